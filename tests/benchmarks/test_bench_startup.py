"""Benchmarks of start-up: ``optcal --help`` and ``optcal calibrate --help`` as a user runs them, one fresh
process per round (the console script beside the interpreter, or ``python -c`` running optcal.app.cli.main when
there is none). extra_info holds the best time in seconds and the heavy libraries the same help imports
(tests/test_startup.py's list; it should be empty), found in a separate process so that the timed one does
nothing but start. No timed assertions.

``test_bench_raw_calibration_process`` times the whole ``optcal calibrate --raw`` on imu_tk's Xsens recording. With
``OPTCAL_IMU_TK`` naming an executable of imu_tk's own ``test_imu_calib`` (built outside this repository:
docs/gyroscope.md, "imu_tk's Xsens recording, against imu_tk"), it and optcal also run in turn on the same files,
:data:`PAIRED_ROUNDS` paired rounds (:func:`paired_with_imu_tk`, shared with test_bench_gyro.py), and
``imu_tk_paired_median_ratio`` is the median of the rounds' ratios. Unset, nothing more runs.
"""

from __future__ import annotations

import gzip
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

HEAVY = ("scipy", "matplotlib", "casadi", "cvxpy", "nlopt", "dask", "distributed", "numba", "pandas", "pyarrow",
         "tqdm")


def _command() -> list[str]:
    script = Path(sys.executable).parent / "optcal"
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from optcal.app.cli import main; sys.exit(main())"]


def _env(cache: Path) -> dict[str, str]:
    """The environment with Python's bytecode cache on, in ``cache``: an installed program runs from its
    cached bytecode (pip compiles it at install), and a shell with PYTHONDONTWRITEBYTECODE set would time
    the compilation of every module instead. The warm-up round fills the cache."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(cache)
    return env


def _run(argv: list[str], env: dict | None = None) -> float:
    """Seconds for one fresh ``optcal ARGV``, which must exit 0 and print its usage."""
    t = time.perf_counter()
    proc = subprocess.run([*_command(), *argv], capture_output=True, text=True, timeout=120, env=env)
    seconds = time.perf_counter() - t
    assert proc.returncode == 0 and proc.stdout.startswith("usage: optcal"), proc.stderr
    return seconds


def _heavy_imported(argv: list[str]) -> list[str]:
    code = ("import contextlib, io, json, sys\n"
            "from optcal.app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try:\n"
            f"        main({argv!r})\n"
            "    except SystemExit:\n"
            "        pass\n"
            "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules} & set(sys.argv[1:]))))\n")
    proc = subprocess.run([sys.executable, "-c", code, *HEAVY], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv", [["--help"], ["calibrate", "--help"]], ids=["help", "calibrate-help"])
def test_bench_cli_help(benchmark, argv, tmp_path):
    seconds = benchmark.pedantic(_run, args=(argv, _env(tmp_path / "pycache")), rounds=5, iterations=1,
                                 warmup_rounds=1)
    if benchmark.stats is not None:
        seconds = benchmark.stats.stats.min
    benchmark.extra_info.update({"command": " ".join(["optcal", *argv]), "seconds": seconds,
                                 "heavy_modules": _heavy_imported(argv)})


def xsens_pair(corpus: Path, folder: Path) -> tuple[Path, Path]:
    """imu_tk's Xsens pair (accelerometer, gyroscope) from the real corpus, decompressed into ``folder``."""
    acc, gyr = folder / "xsens_acc.mat", folder / "xsens_gyro.mat"
    for f in (acc, gyr):
        f.write_bytes(gzip.decompress((corpus / "imu_tk" / f"{f.name}.gz").read_bytes()))
    return acc, gyr


PAIRED_ROUNDS = 11  # odd: the median ratio is one round's


def paired_with_imu_tk(ours, acc: Path, gyr: Path, cwd: Path) -> dict:
    """With ``OPTCAL_IMU_TK`` set: imu_tk's ``test_imu_calib`` on ``acc`` and ``gyr`` and ``ours`` (a callable
    timing one fresh optcal process, bytecode cache warm) in turn, :data:`PAIRED_ROUNDS` rounds with the order
    alternating, so that each round's two see the same load; the whole-process medians of each and the median of
    the per-round ratios optcal / imu_tk, for extra_info. Empty when the variable is unset."""
    peer = os.environ.get("OPTCAL_IMU_TK")
    if not peer:
        return {}
    if not os.access(peer, os.X_OK):
        pytest.fail(f"OPTCAL_IMU_TK={peer} is not an executable (imu_tk's test_imu_calib: "
                    "docs/gyroscope.md, 'imu_tk's Xsens recording, against imu_tk')")

    def run_peer() -> float:
        t = time.perf_counter()
        # in ``cwd``: test_imu_calib writes its two .calib files where it runs
        proc = subprocess.run([peer, str(acc), str(gyr)], capture_output=True, text=True, timeout=300, cwd=cwd)
        assert proc.returncode == 0, proc.stderr
        return time.perf_counter() - t

    run_peer()  # its warm-up (the files in the page cache); optcal's was the benchmark's
    load = os.getloadavg()[0]
    pairs = []
    for r in range(PAIRED_ROUNDS):
        if r % 2 == 0:
            peer_s = run_peer()
            pairs.append((peer_s, ours()))
        else:
            ours_s = ours()
            pairs.append((run_peer(), ours_s))
    return {"imu_tk_paired_rounds": PAIRED_ROUNDS, "imu_tk_paired_s": statistics.median(p for p, _ in pairs),
            "optcal_paired_s": statistics.median(o for _, o in pairs),
            "imu_tk_paired_median_ratio": statistics.median(o / p for p, o in pairs),
            "imu_tk_paired_ratios": [round(o / p, 4) for p, o in pairs], "load_before_pairs": load}


# imu_tk (C++/Ceres) calibrates the accelerometer and the gyroscope of its own Xsens recording in 0.52 s of
# whole-process time (issue #20's measurement, its own test_imu_calib timed beside optcal on the same files)
IMU_TK_SECONDS = 0.52


def test_bench_raw_calibration_process(benchmark, tmp_path, corpus):
    """The whole ``optcal calibrate --raw`` process on imu_tk's Xsens recording (51,175 samples, from the real
    corpus: tests/corpus.py; the default command: units only), a fresh process per round; extra_info: the best
    time and its ratio to imu_tk's, and with ``OPTCAL_IMU_TK`` the paired rounds' medians
    (:func:`paired_with_imu_tk`: imu_tk calibrating both sensors, optcal the accelerometer)."""
    path, gyr = xsens_pair(corpus, tmp_path)
    argv = [*_command(), "calibrate", str(path), "--raw", "--units", "counts"]
    env = _env(tmp_path / "pycache")

    def run() -> float:
        t = time.perf_counter()
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=300, env=env)
        assert proc.returncode == 0 and "model " in proc.stdout, proc.stderr  # the default model (or its fallback)
        return time.perf_counter() - t

    seconds = benchmark.pedantic(run, rounds=5, iterations=1, warmup_rounds=1)
    if benchmark.stats is not None:
        seconds = benchmark.stats.stats.min
    benchmark.extra_info.update({"command": "optcal calibrate xsens_acc.mat --raw --units counts",
                                 "seconds": seconds, "imu_tk_acc_and_gyro_seconds": IMU_TK_SECONDS,
                                 "ratio_to_imu_tk": seconds / IMU_TK_SECONDS})
    benchmark.extra_info.update(paired_with_imu_tk(run, path, gyr, tmp_path))
