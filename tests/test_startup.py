"""Start-up cost: ``import optcal`` and the CLI's parser (``optcal --help``, ``optcal calibrate --help``)
import no heavy library. SciPy, matplotlib, the optimisation back-ends, Dask, numba, pandas, pyarrow and
tqdm are imported inside the functions that use them; ``optcal/__init__.py`` loads its public names at first
use (PEP 562), and each command module imports only argparse set-up at module level.

Each check runs in a fresh interpreter (``sys.executable -c ...``): this process has long since imported
everything. No wall-clock assertions here; tests/benchmarks/test_bench_startup.py measures the times.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import types

import pytest
from corpus import corpus_root

IMU_TK = corpus_root() / "imu_tk"  # imu_tk's Xsens pair (BSD), gzip-compressed: the real corpus (tests/corpus.py)

# The libraries that must stay out of the start-up path (top-level package names).
HEAVY = ("scipy", "matplotlib", "casadi", "cvxpy", "nlopt", "dask", "distributed", "numba", "pandas", "pyarrow",
         "tqdm")

# Runs the given code, then prints, as the last line of stdout, the sorted top-level names of the imported
# modules that are in the given set.
# ruptures' compiled kernel, loaded from its file without the package (optcal.core.recording.pelt), is not the
# package's import
_REPORT = """
import json as _json, sys as _sys
_alone = {"ruptures.detection._detection.ekcpd"}
print(_json.dumps(sorted({_m.split(".")[0] for _m in _sys.modules if _m not in _alone} & set(_sys.argv[1:]))))
"""

# optcal's own command line, as tests/test_cli_core.py runs it in a subprocess.
CLI = [sys.executable, "-c", "import sys; from optcal.app.cli import main; sys.exit(main())"]

# `optcal --help` and `optcal calibrate --help` in-process, their output swallowed.
_HELP = """
import contextlib, io
from optcal.app.cli import main
for argv in (["--help"], ["calibrate", "--help"]):
    with contextlib.redirect_stdout(io.StringIO()):
        try:
            main(argv)
        except SystemExit as exc:
            assert exc.code == 0, (argv, exc.code)
"""


def imported(code: str, names=HEAVY) -> list[str]:
    """Which of ``names`` a fresh interpreter has imported after running ``code``."""
    script = textwrap.dedent(code) + "\n" + _REPORT
    proc = subprocess.run([sys.executable, "-c", script, *names], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"{code!r} failed:\n{proc.stdout}\n{proc.stderr}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_import_optcal_imports_no_heavy_module():
    found = imported("import optcal")
    assert found == [], f"import optcal imports {found}"


def test_building_the_parser_imports_no_heavy_module():
    found = imported("import optcal.app.cli\noptcal.app.cli.build_parser()")
    assert found == [], f"optcal.app.cli.build_parser() imports {found}"


def test_help_imports_no_heavy_module():
    found = imported(_HELP)
    assert found == [], f"optcal --help / optcal calibrate --help import {found}"


def test_help_path_does_not_import_numpy():
    """NumPy alone costs about as much as the whole of ``optcal --help`` is allowed (0.3 s): the parser
    path (built-in commands and the study plug-in) does without it."""
    found = imported(_HELP, names=("numpy", "solvers"))
    assert found == [], f"optcal --help / optcal calibrate --help import {found}"


def test_study_plug_in_imports_no_heavy_module():
    found = imported("import optcal.app.commands.study, optcal.app.study_cli", names=(*HEAVY, "numpy", "solvers"))
    assert found == [], f"optcal.app.commands.study and optcal.app.study_cli import {found}"


@pytest.mark.parametrize("argv, expected", [
    (["--help"], ["usage: optcal", "calibrate", "discover", "study"]),
    (["calibrate", "--help"], ["usage: optcal calibrate", "--model", "--solver", "--raw", "--latitude"]),
])
def test_help_exits_0_and_prints_usage(argv, expected):
    proc = subprocess.run([*CLI, *argv], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(expected[0]), proc.stdout
    missing = [s for s in expected if s not in proc.stdout]
    assert missing == [], f"{missing} not in:\n{proc.stdout}"
    assert proc.stderr == ""


def test_lazy_public_names():
    """Every name of ``__all__`` resolves and is listed by ``dir()``; ``optcal.simulate`` stays the function
    even when the submodule of the same name is imported after the package."""
    import optcal
    import optcal.core.simulate  # the submodule, which Python records as an attribute of the package
    from optcal import discover
    from optcal import simulate as simulate_from_package
    from optcal.app.workflows.discovery import discover as discover_direct
    from optcal.core.simulate import Simulation, simulate

    assert set(optcal.__all__) <= set(dir(optcal))
    for name in optcal.__all__:
        assert getattr(optcal, name) is not None, name
    assert optcal.simulate is simulate and isinstance(simulate, types.FunctionType)
    assert simulate_from_package is simulate and optcal.Simulation is Simulation
    assert discover is discover_direct
    assert optcal.core.model.TERMS is optcal.TERMS  # submodules reachable as before
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        optcal.no_such_name  # noqa: B018


def test_lazy_simulate_survives_a_fresh_interpreter():
    """The order that matters: the submodule first (as optcal.studies.trial does), then the package's name."""
    code = ("import optcal.core.simulate, optcal, types\n"
            "assert isinstance(optcal.simulate, types.FunctionType), optcal.simulate\n"
            "from optcal import simulate\n"
            "assert isinstance(simulate, types.FunctionType), simulate\n")
    assert imported(code, names=()) == []


def test_discover_help_defaults_are_the_library_defaults():
    """optcal/app/commands/discover.py keeps copies of the defaults (importing optcal.core.discovery would slow
    every --help); they must be the library's."""
    from optcal.app.commands import discover
    from optcal.core import discovery

    assert discover.CANDIDATES == discovery.CANDIDATES
    assert discover.DEFAULT_ALPHA == discovery.DEFAULT_ALPHA
    assert discover.DEFAULT_BIC_THRESHOLD == discovery.DEFAULT_BIC_THRESHOLD


def _write_recording(path):
    path.write_text("t,ax,ay,az\n" + "".join(f"{i / 100:.2f},{i},{-i},{2 * i}\n" for i in range(50)))


def test_arrow_reader_is_loaded_at_first_read(tmp_path, monkeypatch):
    arrow_csv = pytest.importorskip("pyarrow.csv")
    from optcal.core.recording import reading

    _write_recording(tmp_path / "r.csv")
    monkeypatch.setattr(reading, "_arrow_csv", reading._NOT_LOADED)
    rec = reading.read_recording(tmp_path / "r.csv", units="counts")
    assert reading._arrow_csv is arrow_csv
    assert rec.N[-1].tolist() == [49, -49, 98]


def test_without_pyarrow_the_numpy_reader_is_used(tmp_path, monkeypatch):
    from optcal.core.recording import reading

    _write_recording(tmp_path / "r.csv")
    monkeypatch.setattr(reading, "_arrow_csv", reading._NOT_LOADED)
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # `import pyarrow...` raises ImportError
    monkeypatch.setitem(sys.modules, "pyarrow.csv", None)
    rec = reading.read_recording(tmp_path / "r.csv", units="counts")
    assert reading._arrow_csv is None
    assert rec.N[-1].tolist() == [49, -49, 98]


def _command_alone(argv: list[str], command: str, checks: str = "") -> list[str]:
    """Run ``optcal ARGV`` in a fresh interpreter; assert it succeeds and loads no command module but
    ``command``'s, then the extra ``checks`` (its printed output is ``out``). Returns the heavy (and pydantic,
    ruptures) modules it imported."""
    code = f"""
        import contextlib, io, sys
        from optcal.app.cli import main
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main({argv!r}) == 0
        commands = sorted(m for m in sys.modules
                          if m.startswith("optcal.app.commands.") and not m.split(".")[-1].startswith("_"))
        assert commands == [{f"optcal.app.commands.{command}"!r}], commands
    """
    return imported(textwrap.dedent(code) + textwrap.dedent(checks), HEAVY + ("pydantic", "ruptures"))


def test_calibrating_a_raw_recording_imports_no_heavy_module(tmp_path, corpus):
    """The whole ``optcal calibrate RAW --raw --units counts -o cal.json`` on imu_tk's Xsens recording (issue
    #20: the process's time is mostly imports): none of HEAVY, no importlib.metadata (entry points are read
    only for a name that is not built in), no pydantic (the file's schema is for reading), and of the command
    modules only calibrate's. The fit is optcal.solvers.lm's."""
    import gzip

    path = tmp_path / "xsens_acc.mat"
    path.write_bytes(gzip.decompress((IMU_TK / "xsens_acc.mat.gz").read_bytes()))
    out = tmp_path / "cal.json"
    checks = """
        assert "solver lm" in out.getvalue()
        assert "importlib.metadata" not in sys.modules
        assert "ruptures.detection._detection.ekcpd" in sys.modules  # PELT: ruptures' compiled kernel alone
    """
    argv = ["calibrate", str(path), "--raw", "--units", "counts", "-o", str(out)]
    assert _command_alone(argv, "calibrate", checks) == []
    assert out.is_file()


def test_calibrating_an_imu_imports_no_heavy_module(tmp_path, corpus):
    """The whole ``optcal imu`` on imu_tk's Xsens pair (issue #23: the process's time against imu_tk's): the
    gyroscope's least squares integrate in NumPy (optcal.core.motion_integrator), so neither numba nor scipy is
    loaded, and of the command modules only imu's."""
    out = tmp_path / "imu.json"
    argv = ["imu", str(IMU_TK / "xsens_acc.mat.gz"), "--gyro", str(IMU_TK / "xsens_gyro.mat.gz"), "--gyro-units",
            "counts", "--gyro-scale", "6258", "--units", "counts", "--model", "linear9", "--threshold-k", "3",
            "-o", str(out)]
    assert _command_alone(argv, "imu", 'assert "optcal.core.kernels.gyro" not in sys.modules\n') == []
    assert out.is_file()
