"""imu_tk's gyroscope file to and from optcal's gyroscope block (issue #23): exact round trips, the same
rates from both, g-sensitivity refused."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.core.errors import InputError
from optcal.core.exchange.gyro_imu_tk import dumps, gyro_from_imu_tk, gyro_to_imu_tk, loads
from optcal.core.gyro.calfile import read_gyro_block
from optcal.core.gyro.model import get_gyro_model

# imu_tk's own gyroscope calibration of its Xsens pair (test_imu_gyro.calib; docs/scripts/gyro_imu_tk.py)
XSENS = ("1 0.00593634 0.00111101\n0.00808812 1 -0.0535569\n0.0253067 -0.0025513 1\n\n"
         "0.000209295 0 0\n0 0.000209899 0\n0 0 0.000209483\n\n32777.1\n32459.8\n32511.8\n")


def test_imu_tk_file_round_trip_and_same_rates():
    T, K, B = loads(XSENS, "test_imu_gyro.calib")
    block = gyro_from_imu_tk(T, K, B, "counts")
    cal = read_gyro_block({"gyroscope": block}, "x.json")
    assert cal.model.name == "gyro12" and block["units"]["parameters"]["K_x"] == "counts/(rad/s)"
    np.testing.assert_allclose(1 / np.array([block["parameters"][f"K_{a}"] for a in "xyz"]),
                               [0.000209295, 0.000209899, 0.000209483], rtol=3e-3)
    T2, K2, B2 = gyro_to_imu_tk(cal)
    np.testing.assert_allclose(T2, T, atol=1e-15)
    np.testing.assert_allclose(K2, K, rtol=1e-14)
    np.testing.assert_allclose(B2, B, rtol=1e-14)
    W = 32768 + 3000 * np.random.default_rng(0).standard_normal((100, 3))
    np.testing.assert_allclose(cal.apply(W), (T @ K @ (W - B).T).T, rtol=1e-12, atol=1e-15)
    T3, K3, B3 = loads(dumps(T2, K2, B2), "again")
    np.testing.assert_array_equal(T3, T2)
    np.testing.assert_array_equal(B3, B2)


def test_bias_from_the_rests_is_exported_as_the_offset():
    model = get_gyro_model(False, bias=False)
    x = np.array([4780.0, 4770.0, 4775.0, 0.001, -0.002, 0.003, 0.0, 0.01, -0.005])
    block = {"model": model.name, "terms": list(model.terms), "parameters": dict(zip(model.names, x)),
             "units": {"raw": "counts", "calibrated": "rad/s"}, "offset_raw": [32777.2, 32459.9, 32511.9]}
    cal = read_gyro_block({"gyroscope": block}, "x.json")
    T, K, B = gyro_to_imu_tk(cal)
    np.testing.assert_array_equal(B, [32777.2, 32459.9, 32511.9])
    np.testing.assert_allclose(np.diag(T), 1.0)
    W = np.array([[33000.0, 32000.0, 32600.0]])
    np.testing.assert_allclose(cal.apply(W), (T @ K @ (W - B).T).T, rtol=1e-12)


def test_g_sensitivity_cannot_be_exported_to_imu_tk():
    model = get_gyro_model(True)
    x = np.zeros(model.n_params)
    x[:3] = 1000.0
    block = {"model": model.name, "terms": list(model.terms), "parameters": dict(zip(model.names, x)),
             "units": {"raw": "counts", "calibrated": "rad/s"}}
    with pytest.raises(InputError, match="no g-sensitivity"):
        gyro_to_imu_tk(read_gyro_block({"gyroscope": block}, "x.json"))


def test_kalibr_gyroscope_intrinsics_reproduce_the_rates():
    """M·C·ω + A·a equals the calibrated model's output in rad/s (deg/s raw), M lower triangular with a
    positive diagonal, C a rotation; counts and a constant bias are refused."""
    from optcal.core.exchange.gyro_kalibr import gyro_to_kalibr

    model = get_gyro_model(True)
    rng = np.random.default_rng(4)
    x = np.concatenate([180 / np.pi * (1 + 0.01 * rng.standard_normal(3)), 0.01 * rng.standard_normal(6),
                        np.zeros(3), 1e-3 * rng.standard_normal(9)])
    block = {"model": model.name, "terms": list(model.terms), "parameters": dict(zip(model.names, x)),
             "units": {"raw": "deg/s", "calibrated": "rad/s"}}
    cal = read_gyro_block({"gyroscope": block}, "x.json")
    M, A, C = gyro_to_kalibr(cal)
    assert np.allclose(np.triu(M, 1), 0) and np.all(np.diag(M) > 0)
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(C) == pytest.approx(1.0)
    omega, f = rng.standard_normal((50, 3)), rng.standard_normal((50, 3))
    expected = np.deg2rad(model.forward(x, omega, f))
    np.testing.assert_allclose((M @ C @ omega.T).T + (A @ (9.80665 * f).T).T, expected, rtol=1e-12, atol=1e-14)
    with pytest.raises(InputError, match="no constant bias"):
        x2 = x.copy()
        x2[9] = 0.01
        gyro_to_kalibr(read_gyro_block({"gyroscope": {**block, "parameters": dict(zip(model.names, x2))}}, "y"))
    with pytest.raises(InputError, match="no fixed value in rad/s"):
        gyro_to_kalibr(read_gyro_block({"gyroscope": {**block, "units": {"raw": "counts",
                                                                         "calibrated": "rad/s"}}}, "z"))


def test_imucal_gyroscope_round_trip_and_same_rates(corpus):
    """imucal's own Ferraris calibration (the real corpus's imucal/example_cal.json, whose K_ga is not zero): read
    as gyro21, written back to the same matrices, and the same rates as imucal's equation."""
    import json

    from optcal.core.exchange.gyro_imucal import gyro_from_imucal, gyro_to_imucal

    path = corpus / "imucal" / "example_cal.json"
    d = json.loads(path.read_text())
    block = gyro_from_imucal(d, "counts", path)
    assert block["model"] == "gyro21"
    cal = read_gyro_block({"gyroscope": block}, path)
    back = gyro_to_imucal(cal)
    Kg, Rg = np.array(d["K_g"]), np.array(d["R_g"])
    # imucal's R_g rows are unit vectors up to its fit's rounding; the product K_g·R_g is what it applies
    np.testing.assert_allclose(np.array(back["K_g"]) @ np.array(back["R_g"]), Kg @ Rg, rtol=1e-12)
    np.testing.assert_allclose(back["K_ga"], d["K_ga"], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back["b_g"], d["b_g"], rtol=1e-12)
    rng = np.random.default_rng(2)
    u, a = 100 * rng.standard_normal((20, 3)), 9.8 * rng.standard_normal((20, 3))
    imucal = (np.linalg.inv(Rg) @ np.linalg.inv(Kg) @ (u - a @ np.array(d["K_ga"]).T - d["b_g"]).T).T
    np.testing.assert_allclose(np.rad2deg(cal.apply(u, a / 9.80665)), imucal, rtol=1e-10, atol=1e-10)
