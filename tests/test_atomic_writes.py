"""Nothing lost (issue #29, item 7; docs/design.md, "File formats"): every command that writes is killed mid-write,
and the file it was writing is as it was before (an old one byte for byte, a new one absent); what is left is at
most a stray ``.NAME.XXXXXXXX.tmp`` beside it, never a partial file under the output's name.

"Mid-write" is made deterministic by a runner script (test code only: nothing in optcal knows of it) that
runs the command with :func:`optcal.core.atomicfile._temporary` wrapped, so that its Nth ``write`` to any output
writes half its data, flushes it, and sends the process a signal: SIGKILL (no clean-up at all) or SIGINT
(Ctrl-C: the temporary file is removed)."""

from __future__ import annotations

import json
import os
import re
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tomllib
from conftest import run_cli

from optcal.core.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
IMU_ARGS = ["--gyro-columns", "gx,gy,gz", "--gyro-units", "counts", "--gyro-scale", "1000", "--model", "linear9"]
OLD = b"an old file, which must survive\n"

RUNNER = r'''
import os, runpy, signal, sys, time

import optcal.core.atomicfile as af

sig, after, module, *argv = sys.argv[1:]
sig, after = getattr(signal, sig), int(after)
if argv and argv[0] == "--no-figures":  # the study report's figures skipped: only its three text files counted
    argv = argv[1:]
    import optcal.studies.figures

    optcal.studies.figures.Renderer.draw = lambda self, fn, path, *a, **k: path
writes = 0


class Dying:
    """A temporary file's handle whose `after`-th write (counted over every output) is cut in half."""

    def __init__(self, fh):
        self._fh = fh

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def write(self, data):
        global writes
        writes += 1
        if writes < after:
            return self._fh.write(data)
        self._fh.write(data[: len(data) // 2])
        self._fh.flush()
        os.fsync(self._fh.fileno())
        os.kill(os.getpid(), sig)
        time.sleep(10)  # SIGINT: KeyboardInterrupt is raised here
        sys.exit(99)


real = af._temporary


def dying(*args, **kwargs):
    fh, tmp = real(*args, **kwargs)
    return Dying(fh), tmp


af._temporary = dying
sys.argv = [module, *argv]
runpy.run_module(module, run_name="__main__", alter_sys=True)
'''


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Inputs made once, in this process: a positions CSV and its calibration, a simulated IMU recording (as
    tests/test_gyro_imu_command.py's) and its IMU file, a raw recording, and a small study folder."""
    from optcal.core.gyro import draw_truth, get_gyro_model, simulate_imu

    d = tmp_path_factory.mktemp("atomic")
    (d / "runner.py").write_text(RUNNER)
    assert run_cli(["simulate", "-o", d / "pos.csv", "--seed", "1", "--model", "linear9"], _NoCapture())[0] == 0
    assert run_cli(["calibrate", d / "pos.csv", "-o", d / "cal.json", "--model", "linear9"], _NoCapture())[0] == 0
    rng = np.random.default_rng(0)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    sim = simulate_imu(model, x, poses=24, rest_s=3.0, rng=rng).data
    np.savetxt(d / "imu.csv", np.column_stack([sim.t, sim.F, np.round(sim.W)]), delimiter=",",
               header="t,ax,ay,az,gx,gy,gz", comments="", fmt="%.9g")
    assert run_cli(["imu", d / "imu.csv", *IMU_ARGS, "-o", d / "imu.json"], _NoCapture())[0] == 0
    n = 3000
    A = np.tile([0.01, -0.02, 1.0], (n, 1)) + 1e-3 * rng.standard_normal((n, 3))
    np.savetxt(d / "raw.csv", np.column_stack([np.arange(n) / 100.0, A]), delimiter=",", header="t,ax,ay,az",
               comments="", fmt="%.9g")
    from optcal.studies.execute import run_study
    from optcal.studies.spec import parse

    spec = tomllib.loads((ROOT / "optcal" / "studies" / "specs" / "ci.toml").read_text())
    spec.update(runs=2, solvers=[{"name": "scipy-lm"}], navigation={"enabled": False})
    run_study(parse(spec, "ci.toml"), d / "study", progress=False)
    return d


class _NoCapture:
    """run_cli's capsys for a module fixture: the output is not looked at."""

    def readouterr(self):
        return type("Out", (), {"out": "", "err": ""})()


def killed(work: Path, after: int, *argv, sig: str = "SIGKILL", module: str = "optcal.app.cli"):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, str(work / "runner.py"), sig, str(after), module, *map(str, argv)],
                          capture_output=True, text=True, env=env, cwd=work, timeout=120)


def strays(folder: Path, name: str) -> list[Path]:
    """The temporary files of ``name`` left in ``folder``; every other file whose name holds ``name`` fails."""
    out = []
    for p in folder.iterdir():
        if p.name == name or name not in p.name:
            continue
        assert re.fullmatch(rf"\.{re.escape(name)}\.[A-Za-z0-9_]+\.tmp", p.name), p.name
        out.append(p)
    return out


def fresh(folder: Path, *names: str, old: bool = True) -> list[Path]:
    """``folder``/name for each name, holding :data:`OLD` (``old``) or absent."""
    folder.mkdir(exist_ok=True)
    paths = [folder / n for n in names]
    for p in paths:
        p.unlink(missing_ok=True)
        if old:
            p.write_bytes(OLD)
    return paths


def assert_killed_mid_write(r, *paths: Path, old: bool = True, partial: bytes | None = None) -> None:
    """SIGKILL during the write: every path as it was, and the partial data only in a stray temporary file."""
    assert r.returncode == -signal.SIGKILL, (r.returncode, r.stderr)
    for p in paths:
        if old:
            assert p.read_bytes() == OLD
        else:
            assert not p.exists()
    left = [s for p in paths for s in strays(p.parent, p.name)]
    assert left  # the write had begun
    if partial is not None:
        assert any(s.read_bytes().startswith(partial) for s in left)


def test_calibrate_killed_keeps_the_old_calibration_file(work):
    (out,) = fresh(work / "calibrate", "cal.json")
    r = killed(work, 1, "calibrate", work / "pos.csv", "-o", out, "--force")
    assert_killed_mid_write(r, out, partial=b'{\n  "format": "optcal-calibration"')


def test_imu_killed_writes_no_imu_file(work):
    (out,) = fresh(work / "imu", "imu.json", old=False)
    r = killed(work, 1, "imu", work / "imu.csv", *IMU_ARGS, "-o", out)
    assert_killed_mid_write(r, out, old=False, partial=b"{")


def test_apply_killed_leaves_no_partial_csv(work):
    """The issue's case: a killed apply left a CSV of 929,640 of its 2,000,001 lines that looked whole."""
    (out,) = fresh(work / "apply", "out.csv")
    r = killed(work, 3, "apply", work / "cal.json", work / "raw.csv", "-o", out, "--force")
    assert_killed_mid_write(r, out, partial=b"t,ax,ay,az\n")
    (tmp,) = strays(out.parent, out.name)
    assert tmp.read_text().count("\n") == 2  # header, one row, half a row: streamed, killed mid-way
    # a new target: nothing under its name
    (new,) = fresh(work / "apply_new", "out.csv", old=False)
    assert_killed_mid_write(killed(work, 100, "apply", work / "cal.json", work / "raw.csv", "-o", new), new,
                            old=False)


def test_apply_interrupted_cleans_up(work):
    """Ctrl-C mid-write: exit status 130, the old file as it was and no temporary file left."""
    (out,) = fresh(work / "apply_int", "out.csv")
    r = killed(work, 3, "apply", work / "cal.json", work / "raw.csv", "-o", out, "--force", sig="SIGINT")
    assert r.returncode == 130 and "interrupted" in r.stderr, (r.returncode, r.stderr)
    assert out.read_bytes() == OLD and sorted(p.name for p in out.parent.iterdir()) == ["out.csv"]


def test_export_killed_writes_neither_file_of_the_pair(work):
    """imu_tk's pair: killed while writing the second file, the first (complete) is not renamed either."""
    acc, gyr = fresh(work / "export", "acc.calib", "gyro.calib", old=False)
    r = killed(work, 2, "export", work / "imu.json", "--format", "imu_tk", "-o", acc, "--gyro-output", gyr)
    assert_killed_mid_write(r, acc, gyr, old=False)
    assert strays(acc.parent, acc.name) and strays(gyr.parent, gyr.name)  # both temporary, neither renamed
    (m,) = fresh(work / "export", "m.json")
    assert_killed_mid_write(killed(work, 1, "export", work / "cal.json", "--format", "matrix", "-o", m, "--force"),
                            m)


def test_plan_killed_keeps_the_old_scheme(work):
    (out,) = fresh(work / "plan", "plan.csv")
    r = killed(work, 1, "plan", "--n", "8", "--model", "diag6", "--solver", "exchange", "--placement-deg", "0",
               "--fixture", "faces", "-o", out, "--force", "--seed", "1")
    assert_killed_mid_write(r, out, partial=b"# optcal plan")


def test_simulate_killed_writes_neither_file(work):
    """Killed while writing the truth: the positions CSV, written to its temporary file, is not renamed."""
    pos, truth = fresh(work / "simulate", "pos.csv", "truth.json")
    r = killed(work, 2, "simulate", "-o", pos, "--truth-out", truth, "--force")
    assert_killed_mid_write(r, pos, truth)
    assert strays(pos.parent, pos.name) and strays(truth.parent, truth.name)  # both begun, neither renamed


def test_study_report_killed_keeps_the_old_report(work):
    folder = work / "study"
    paths = [folder / n for n in ("report.md", "summary.json", "parameters.md")]
    for p in paths:
        p.write_bytes(OLD)
    r = killed(work, 3, "--no-figures", "study", "report", folder)
    assert_killed_mid_write(r, *paths)
    assert len([s for p in paths for s in strays(folder, p.name)]) == 3  # all three written, none renamed


def test_study_export_killed_writes_no_folder(work):
    out = work / "exported"
    r = killed(work, 1, "study", "export", work / "study", "--format", "github-action-benchmark", "-o", out)
    assert r.returncode == -signal.SIGKILL, r.stderr
    assert not out.exists()
    (left,) = [p for p in work.iterdir() if p.name.startswith(".exported.")]  # the export's temporary folder
    assert left.is_dir() and left.name.endswith(".tmp")


PNG = b"\x89PNG\r\n\x1a\n"


def test_calibrate_plot_killed_keeps_the_old_figure(work):
    """--plot (optcal.core.plots.save_figure, which calibrate, plan and discover share), cut in its first write."""
    (fig,) = fresh(work / "calibrate_plot", "fit.png")
    r = killed(work, 1, "calibrate", work / "pos.csv", "--model", "linear9", "--plot", fig, "--force")
    assert_killed_mid_write(r, fig, partial=PNG[:4])


def test_noise_killed_writes_neither_output(work):
    """Killed while writing the figure: Kalibr's imu.yaml, written to its temporary file first, is not renamed
    either."""
    yml, fig = fresh(work / "noise", "imu.yaml", "allan.png")
    r = killed(work, 2, "noise", work / "raw.csv", "--kalibr-yaml", yml, "--plot", fig, "--force")
    assert_killed_mid_write(r, yml, fig, partial=PNG[:4])
    assert strays(yml.parent, yml.name) and strays(fig.parent, fig.name)  # both begun, neither renamed


def test_nav_plot_killed_keeps_the_old_figure(work):
    (fig,) = fresh(work / "nav", "nav.png")
    r = killed(work, 1, "nav", work / "cal.json", "--truth", work / "cal.json", "--hours", "0.5", "--plot", fig,
               "--force")
    assert_killed_mid_write(r, fig, partial=PNG[:4])


def test_study_figures_killed_keep_the_old_figures(work):
    """A study report killed in its first figure: no figure under its name when new, the old one as it was
    when redrawn (and the report as it was)."""
    figdir, report = work / "study" / "figures", work / "study" / "report.md"
    report.write_bytes(OLD)
    r = killed(work, 1, "study", "report", figdir.parent)
    assert r.returncode == -signal.SIGKILL, (r.returncode, r.stderr)
    (tmp,) = figdir.iterdir()  # the first figure's temporary file, and nothing else
    fig = figdir / re.fullmatch(r"\.(.+\.png)\.[A-Za-z0-9_]+\.tmp", tmp.name).group(1)
    assert tmp.read_bytes() == PNG[:4] and report.read_bytes() == OLD
    tmp.unlink()
    fig.write_bytes(OLD)
    assert_killed_mid_write(killed(work, 1, "study", "report", figdir.parent), fig, report, partial=PNG[:4])


def test_the_helper(tmp_path, monkeypatch):
    """optcal.core.atomicfile directly: the mode of a new file is open()'s, a replaced file keeps its mode, a refused
    or failed write leaves nothing, a symbolic link is kept and its target replaced, and the bytes are
    Path.write_text's."""
    from optcal.core.atomicfile import atomic_write, write_atomic

    new = tmp_path / "new.txt"
    write_atomic(new, "a\nb\n", overwrite=False)
    ref = tmp_path / "ref.txt"
    ref.write_text("a\nb\n")
    assert new.read_bytes() == ref.read_bytes()
    assert stat.S_IMODE(new.stat().st_mode) == stat.S_IMODE(ref.stat().st_mode)
    os.chmod(new, 0o600)
    write_atomic(new, b"\x00\x01", overwrite=True)
    assert new.read_bytes() == b"\x00\x01" and stat.S_IMODE(new.stat().st_mode) == 0o600
    with pytest.raises(InputError, match=r"new.txt exists; pass --force to overwrite it or choose another -o path"):
        write_atomic(new, "x", overwrite=False)
    with pytest.raises(RuntimeError, match="failed mid-way"):
        with atomic_write(new, overwrite=True) as fh:
            fh.write("half")
            raise RuntimeError("failed mid-way")
    assert new.read_bytes() == b"\x00\x01"

    def refuse(tmp):
        assert Path(tmp).read_text() == "checked"
        raise InputError(f"{tmp} is not good")

    with pytest.raises(InputError, match="is not good"):
        write_atomic(new, "checked", overwrite=True, check=refuse)
    assert new.read_bytes() == b"\x00\x01"
    link = tmp_path / "link.txt"
    link.symlink_to(new)
    write_atomic(link, "via the link", overwrite=True)
    assert link.is_symlink() and new.read_text() == "via the link"
    with pytest.raises(InputError, match=r"cannot write .*nowhere/x.txt: No such file or directory"):
        write_atomic(tmp_path / "nowhere" / "x.txt", "x", overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.txt", "new.txt", "ref.txt"]
    # the calibration files' writer refuses an existing file as before, and the JSON is what it was
    from optcal.core.jsonfile import write_json_object

    write_json_object({"a": 1}, tmp_path / "c.json")
    assert (tmp_path / "c.json").read_text() == json.dumps({"a": 1}, indent=2) + "\n"
    with pytest.raises(InputError, match="c.json exists; pass --force"):
        write_json_object({"a": 2}, tmp_path / "c.json")


def test_save_figure(tmp_path):
    """optcal.core.plots.save_figure through the helper: the PNG is savefig(path)'s byte for byte, a name without a
    suffix gets savefig's .png, and a format matplotlib cannot write is one line, with nothing left behind."""
    from matplotlib.figure import Figure

    from optcal.core.plots import save_figure

    fig = Figure()
    fig.subplots().plot([0, 1, 4])
    fig.savefig(tmp_path / "ref.png", dpi=110, bbox_inches="tight")
    (tmp_path / "fig.png").write_bytes(OLD)
    save_figure(fig, tmp_path / "fig.png", bbox_inches="tight")
    assert (tmp_path / "fig.png").read_bytes() == (tmp_path / "ref.png").read_bytes()
    save_figure(fig, tmp_path / "bare")
    assert (tmp_path / "bare.png").read_bytes()[:8] == PNG
    with pytest.raises(InputError, match=r"cannot write the figure .*fig.xyz: Format 'xyz' is not supported"):
        save_figure(fig, tmp_path / "fig.xyz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bare.png", "fig.png", "ref.png"]
