"""Benchmarks of the raw-recording path: applying a calibration file to a million samples (the issue asks
for well under a second), reading a raw CSV, and the static-interval statistic.

Run with `make bench`; under `make test` each runs once with timing disabled. Throughput (samples per
second) and the accuracy of the inverse go to extra_info.
"""

import time
from dataclasses import replace

import numpy as np
import pytest

from optcal.app.fit import calibrate
from optcal.core.calfile import read_calibration, write_calibration
from optcal.core.recording import read_recording, variance_statistic
from optcal.core.schemes import random_orientations
from optcal.core.simulate import simulate

TRUTH = {"K_x": 16301.0, "K_y": 16452.0, "K_z": 16690.0, "b_x": 0.021, "b_y": -0.013, "b_z": 0.042,
         "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3, "K2_x": 3.0, "K2_y": -2.0, "K2_z": 4.0}
N_APPLY = 1_000_000


@pytest.fixture(scope="module", params=["linear9", "nonlinear12"])
def calfile(request, tmp_path_factory):
    model = request.param
    truth = {k: v for k, v in TRUTH.items() if not (model == "linear9" and k.startswith("K2"))}
    sim = simulate(model, truth, np.random.default_rng(0), scheme="36", noise_g=20e-6)
    cal = calibrate(replace(sim.data, units="counts"), model)
    path = tmp_path_factory.mktemp("cal") / f"{model}.json"
    write_calibration(cal, path, units_in="g", units_out="counts")
    return read_calibration(path)


def test_bench_apply_million_samples(benchmark, calfile):
    rng = np.random.default_rng(1)
    A = random_orientations(N_APPLY, rng) * rng.uniform(0.5, 1.5, (N_APPLY, 1))
    N = calfile.model.forward(calfile.x, A)[0]
    got = benchmark(calfile.apply, N)
    err = float(np.max(np.abs(got - A)))
    assert got.shape == (N_APPLY, 3) and err < 1e-12
    t = time.perf_counter()
    calfile.apply(N)
    once = time.perf_counter() - t
    benchmark.extra_info.update({"model": calfile.model.name, "samples": N_APPLY, "max_abs_error_g": err,
                                 "seconds_once": once, "samples_per_s_once": N_APPLY / once})


@pytest.fixture(scope="module")
def raw_csv(tmp_path_factory):
    n = 200_000
    rng = np.random.default_rng(2)
    path = tmp_path_factory.mktemp("raw") / "raw.csv"
    data = np.column_stack([np.arange(n) / 100.0, rng.integers(-2000, 2000, (n, 2)),
                            rng.integers(15000, 17000, n)])
    np.savetxt(path, data, delimiter=",", header="t,ax,ay,az", comments="", fmt=["%.2f", "%d", "%d", "%d"])
    return path, n


def test_bench_read_recording(benchmark, raw_csv):
    path, n = raw_csv
    rec = benchmark(read_recording, path, units="counts")
    assert len(rec) == n and rec.rate == pytest.approx(100.0)
    t = time.perf_counter()
    read_recording(path, units="counts")
    once = time.perf_counter() - t
    benchmark.extra_info.update({"rows": n, "seconds_once": once, "rows_per_s_once": n / once})


def test_bench_variance_statistic(benchmark):
    n = 1_000_000
    N = np.random.default_rng(3).standard_normal((n, 3)) * 30 + [0, 0, 16384]
    s = benchmark(variance_statistic, N, 101)
    assert s.shape == (n,) and np.isnan(s[:50]).all()
    assert np.nanmedian(s) == pytest.approx(np.sqrt(3) * 900, rel=0.05)
    t = time.perf_counter()
    variance_statistic(N, 101)
    benchmark.extra_info.update({"samples": n, "samples_per_s_once": n / (time.perf_counter() - t)})
