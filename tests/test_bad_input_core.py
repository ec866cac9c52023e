"""Inputs that used to end in a traceback, a hang or a silent wrong answer give one clear error."""

import numpy as np
import pytest

from optcal import CalibrationProblem, PositionsData, get_model, simulate
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.presets import PAPER_TRUTH
from optcal.core.schemes import MAX_RANDOM_POSITIONS, scheme


@pytest.fixture(scope="module")
def sim():
    m = get_model("nonlinear12")
    return simulate(m, {k: v for k, v in PAPER_TRUTH.items() if k in m.names}, np.random.default_rng(1),
                    scheme="24", noise_g=10e-6)


def test_a_wildly_wrong_position_is_named(sim):
    N = sim.data.N.copy()
    N[3, 0] = 1e300  # used to end in LinAlgError inside the linear start
    with pytest.raises(InputError, match=r"position\(s\) 3 .* more than 4x away"):
        CalibrationProblem("nonlinear12", PositionsData(N=N))
    N[3, 0] = 40.0  # a unit mix-up in one row
    with pytest.raises(InputError, match=r"position\(s\) 3 "):
        CalibrationProblem("nonlinear12", PositionsData(N=N))


def test_non_finite_rows_are_named():
    N = np.ones((10, 3))
    N[[2, 7], 1] = np.nan
    with pytest.raises(InputError, match=r"row\(s\) 3, 8 have a missing or non-finite output"):
        PositionsData(N=N)


def test_zero_sample_sds_and_a_non_positive_noise_are_refused(sim):
    n = len(sim.data)
    zero = PositionsData(N=sim.data.N, n_samples=np.full(n, 100.0), std=np.zeros((n, 3)))
    with pytest.raises(InputError, match="sample SDs .* all zero"):  # used to be ZeroDivisionError later
        CalibrationProblem("nonlinear12", zero)
    for bad in (0.0, -1e-5, float("nan")):
        with pytest.raises(InputError, match="noise SD must be a positive number"):
            CalibrationProblem("nonlinear12", sim.data, noise_g=bad)


def test_a_huge_random_scheme_is_refused_before_allocating():
    with pytest.raises(InputError, match="more than optcal handles"):
        scheme(f"random:{MAX_RANDOM_POSITIONS + 1}")
    assert scheme("random:5", np.random.default_rng(0)).shape == (5, 3)


def test_cli_exits_2_with_one_line(sim, tmp_path, capsys):
    csv = tmp_path / "p.csv"
    data = PositionsData(N=sim.data.N.copy())
    data.N[5, 2] = 1e300
    csv.write_text(data.to_csv())
    assert main(["calibrate", str(csv), "--model", "nonlinear12"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "position(s) 5" in err[0]
    assert main(["simulate", "--scheme", "random:100000000", "-o", str(tmp_path / "x.csv")]) == 2
    assert not (tmp_path / "x.csv").exists()
