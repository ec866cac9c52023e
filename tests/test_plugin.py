"""Third-party solvers and the listing of solvers.

The example plugin (examples/random_search_plugin, its own pyproject.toml with an ``optcal.solvers`` entry
point) is built and installed with pip into a temporary directory (offline: no index, no build isolation,
no dependencies), never into the running environment; a subprocess with that directory on its path then
finds it in the registry (``optcal solvers --json``) and calibrates with it (``optcal calibrate --solver
random-search``). Nothing is left behind: the directory is pytest's temporary one.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from optcal import solvers
from optcal.app.cli import main
from optcal.core.presets import draw_truth, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate
from optcal.solvers.base import Solver

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "random_search_plugin"


def _run(args, env=None, timeout=180):
    proc = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def _can_build_offline() -> bool:
    """Building a wheel without build isolation needs ``wheel`` or setuptools >= 70.1 (bdist_wheel built in)."""
    import importlib.util

    import setuptools

    major, minor = (int(v) for v in setuptools.__version__.split(".")[:2])
    return importlib.util.find_spec("wheel") is not None or (major, minor) >= (70, 1)


def test_plugin_installs_registers_and_solves(tmp_path):
    assert _can_build_offline(), "install the test extra (it brings `wheel`): pip install -e '.[test]'"
    src, site = tmp_path / "src", tmp_path / "site"
    # Build from a copy, so the build's by-products (build/, *.egg-info) stay out of the repository.
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    _run(["-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--no-index",
          "--target", str(site), str(src)])
    assert (site / "optcal_random_search" / "__init__.py").is_file()
    (dist,) = site.glob("optcal_random_search-*.dist-info")
    assert "optcal.solvers" in (dist / "entry_points.txt").read_text()

    rng = np.random.default_rng(8)
    truth = draw_truth("nonlinear12", rng)
    sim = simulate("nonlinear12", truth, rng, scheme="24", noise_g=10e-6)
    presets = manufacturer_presets(truth, rng)
    sim.data.to_csv(tmp_path / "pos.csv")
    (tmp_path / "presets.json").write_text(presets.to_json())
    # One interpreter with the target directory on its path runs both commands (start-up is the slow part).
    script = (
        "from optcal.app.cli import main\n"
        "main(['solvers', '--json'])\nprint('\\f')\n"
        f"main(['calibrate', {str(tmp_path / 'pos.csv')!r}, '--solver', 'random-search', '--presets', "
        f"{str(tmp_path / 'presets.json')!r}, '--budget', '4001', '--seed', '3', '--option', 'm=40', '--json'])\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")])))
    listing_text, calibrate_text = _run(["-c", script], env=env).split("\f")
    found = {s["name"]: s for s in json.loads(listing_text)["solvers"]}
    assert "random-search" in found
    rs = found["random-search"]
    assert rs["module"] == "optcal_random_search" and rs["family"] == "metaheuristic" and rs["available"]
    assert rs["options"]["m"]["default"] == 20 and rs["options"]["sigma_init"]["default"] == 0.1
    assert set(found) > set(solvers.names())  # the built-in ones are all still there

    out = json.loads(calibrate_text)
    p = CalibrationProblem("nonlinear12", sim.data, presets=presets)
    ref = solvers.get("scipy-lm").solve(p, rng=0)
    start = p.cost(p.x0)
    print(f"random-search plugin: cost {out['cost']:.3e} from {start:.3e} at the presets (optimum {ref.fun:.3e}), "
          f"{out['nfev']} evaluations")
    assert out["solver"] == "random-search" and out["success"] and out["nfev"] == 4001
    assert out["cost"] < 0.2 * start and out["cost"] <= 1.5 * ref.fun  # within the conformance's 0.5 gap

    # The running interpreter never saw it: nothing was installed into this environment.
    assert "random-search" not in solvers.names()


# -- optcal solvers ---------------------------------------------------------------------------------------
def test_solvers_command_lists_every_solver_with_its_options_and_defaults(capsys):
    assert main(["solvers", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [s["name"] for s in info["solvers"]] == solvers.names()
    for s in info["solvers"]:
        cls, fixed = solvers.registry.solver_class(s["name"])
        assert s["family"] == cls.family and s["available"] == cls.is_available()
        assert list(s["options"]) == list(cls.options)
        for k, o in cls.options.items():
            assert s["options"][k]["default"] == json.loads(json.dumps(fixed.get(k, o.default)))
            assert s["options"][k]["doc"] == o.doc
            assert s["options"][k].get("fixed", False) == (k in fixed)
    wrappers = {w["prefix"]: w for w in info["wrappers"]}
    assert set(wrappers) >= {"staged", "mcs"}
    assert wrappers["staged"]["usage"] == "staged:<solver>"
    assert wrappers["staged"]["options"]["max_cycles"]["default"] == 5
    assert wrappers["mcs"]["options"]["runs"]["default"] == 100

    assert main(["solvers"]) == 0
    text = capsys.readouterr().out
    heads = [line.split()[0] for line in text.splitlines() if line and not line.startswith(" ")]
    assert set(solvers.names()) <= set(heads)
    assert "    runs = 100" in text and "staged:<solver>" in text and "inner.KEY=VALUE" in text
    assert "    ftol    = 1e-15" in text  # scipy-lm's options, aligned, with defaults

    assert main(["solvers", "scipy-lm"]) == 0
    one = capsys.readouterr().out
    assert one.startswith("scipy-lm  [local]  available") and "scipy-trf" not in one


def test_solvers_command_reports_unavailable_solvers_and_unknown_names(monkeypatch, capsys):
    class NeedsMissing(Solver):
        name, family, requires = "needs-missing", "local", ("no_such_package_optcal",)

    monkeypatch.setitem(solvers.registry._SOLVERS, "needs-missing", (NeedsMissing, {}))
    assert main(["solvers", "needs-missing"]) == 0
    out = capsys.readouterr().out
    assert "UNAVAILABLE: solver needs-missing needs the package(s) no_such_package_optcal" in out
    assert main(["solvers", "--json", "needs-missing"]) == 0
    (entry,) = json.loads(capsys.readouterr().out)["solvers"]
    assert entry["available"] is False and "no_such_package_optcal" in entry["message"]
    assert main(["solvers", "no-such-solver"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown solver(s) no-such-solver" in err[0]


def test_registry_refuses_duplicates_and_loads_entry_points_once():
    with pytest.raises(ValueError, match="already registered"):
        solvers.register(type(solvers.get("scipy-lm")))
    with pytest.raises(ValueError, match="already registered"):
        solvers.register_wrapper("staged", lambda inner: inner)
    assert solvers.registry.load_entry_points() == []  # already loaded by names(); never twice
