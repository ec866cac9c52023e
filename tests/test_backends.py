"""The problem's two evaluations (CalibrationProblem's ``backend``): NumPy, which one-off least-squares
calibrations use, and the compiled kernel, which the studies and the search methods use, give the same
calibration; and the command that calibrates a raw recording loads none of the libraries whose import costs
more than its fit (numba, scipy.stats, ruptures, cvxpy: docs/performance.md)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from optcal.app.fit import calibrate
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate


@pytest.mark.parametrize("model, scheme", [("diag6", "24"), ("linear9", "36"), ("nonlinear12", "24"),
                                           ("seed15", "24")])
def test_numpy_and_kernel_give_the_same_calibration(model, scheme):
    m = get_model(model)
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    sim = simulate(m, truth, np.random.default_rng(11), scheme=scheme, noise_g=10e-6)
    a = calibrate(sim.data, m, backend="numpy")
    b = calibrate(sim.data, m, backend="kernel")
    assert a.problem.backend == "numpy" and b.problem.backend == "kernel"
    # the same estimate to a millionth of its standard error (the two differ by rounding, ~1e-13 at most)
    # (seed15's unobservable directions have no standard error: held at the gauge, they agree to 1e-12)
    se = np.where(np.isfinite(b.stderr), b.stderr, 1e-6)
    assert np.all(np.abs(a.x - b.x) <= 1e-6 * se)
    np.testing.assert_allclose(a.stderr, b.stderr, rtol=1e-6)
    assert a.fit.cost == pytest.approx(b.fit.cost, rel=1e-8)


def test_least_squares_chooses_numpy_and_search_methods_the_kernel():
    m = get_model("linear9")
    sim = simulate(m, {k: v for k, v in PAPER_TRUTH.items() if k in m.names}, np.random.default_rng(2),
                   scheme="24", noise_g=10e-6)
    assert calibrate(sim.data, m).problem.backend == "numpy"  # scipy-lm
    assert calibrate(sim.data, m, solver="pso", budget=2000).problem.backend == "kernel"


def test_unknown_backend_is_one_line():
    from optcal.core.errors import InputError

    m = get_model("diag6")
    sim = simulate(m, {k: v for k, v in PAPER_TRUTH.items() if k in m.names}, np.random.default_rng(0), scheme="24",
                   noise_g=10e-6)
    with pytest.raises(InputError, match="`backend` 'gpu': use one of kernel, numpy"):
        CalibrationProblem(m, sim.data, backend="gpu")


def test_raw_calibration_loads_no_heavy_library(tmp_path, corpus):
    """optcal calibrate --raw on imu_tk's Xsens recording (51,175 samples), in a fresh interpreter."""
    import gzip

    path = tmp_path / "xsens_acc.mat"
    path.write_bytes(gzip.decompress((corpus / "imu_tk" / "xsens_acc.mat.gz").read_bytes()))
    code = ("import contextlib, io, json, sys\n"
            "from optcal.app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    rc = main(['calibrate', {str(path)!r}, '--raw', '--units', 'counts'])\n"
            "heavy = ('numba', 'scipy.stats', 'ruptures', 'cvxpy', 'matplotlib', 'pandas')\n"
            "print(json.dumps([rc, sorted(m for m in heavy if m in sys.modules)]))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    rc, loaded = json.loads(proc.stdout.strip().splitlines()[-1])
    assert rc == 0 and loaded == []
