"""`optcal simulate --raw`: a hand-held IMU recording to try the raw path on (the README's first calibration).
It is optcal.core.synthetic_imu's recording (re-seats with a motion), written as a CSV with a header; calibrate,
imu and apply read it without naming a column."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import run_cli

from optcal.core.synthetic_imu import handheld_imu


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("raw") / "rec.csv"
    from optcal.app.cli import main

    assert main(["simulate", "--raw", "--seed", "1", "-o", str(path)]) == 0
    return path


def test_the_recording_is_the_simulators(recording):
    """Header t,ax,ay,az,gx,gy,gz; the samples of handheld_imu(seed 1, 24 poses, re-seats with a motion) to 7
    significant digits."""
    sim = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    assert recording.read_text().splitlines()[0] == "t,ax,ay,az,gx,gy,gz"
    table = np.loadtxt(recording, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table, np.column_stack([sim.acc.t, sim.acc.N, sim.gyro.N]), rtol=1e-6, atol=1e-6)


def test_calibrate_finds_the_simulated_sensor(recording, capsys):
    """The default command finds the 24 poses and gives the accelerometer's scale factors and offsets within
    3 standard errors of the simulator's (a diagonal sensor)."""
    code, out, err = run_cli(["calibrate", recording, "--raw", "--units", "g", "--model", "linear9", "--json"], capsys)
    assert code == 0, err
    res = json.loads(out)
    sim = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    assert res["n_positions"] == 24
    P, se = res["parameters"], res["stderr"]
    for i, ax in enumerate("xyz"):
        assert abs(P[f"K_{ax}"] - sim.acc_scale[i]) < 3 * se[f"K_{ax}"]
        assert abs(P[f"b_{ax}"] - sim.acc_offset[i]) < 3 * se[f"b_{ax}"]


def test_imu_takes_the_gyroscope_the_header_names(recording, capsys):
    """optcal imu on the recording without --gyro-columns (its header names gx, gy, gz): both sensors fitted, the
    gyroscope's scale factors within 4 standard errors of the simulator's (°/s of output per °/s, ×180/π per
    rad/s); without --gyro-units, one line naming them."""
    code, out, err = run_cli(["imu", recording, "--units", "g", "--gyro-units", "deg/s", "--model", "linear9",
                              "--json"], capsys)
    assert code == 0, err
    g = json.loads(out)["gyroscope"]
    sim = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    for i, ax in enumerate("xyz"):
        assert abs(g["parameters"][f"K_{ax}"] - sim.gyro_scale[i] * 180 / np.pi) < 4 * g["stderr"][f"K_{ax}"]
    code, out, err = run_cli(["imu", recording, "--units", "g"], capsys)
    assert code == 2 and err.strip().splitlines() == [
        "optcal imu: error: give the gyroscope's units with --gyro-units counts, deg/s, rad/s or volts (the names of "
        f"its columns in {recording} give none)"]


@pytest.mark.parametrize("argv,words", [
    (["--raw", "--noise-ug", "5"], "--noise-ug is for positions"),
    (["--raw", "--poses", "3"], "--poses 3: give 6 to 1000 poses"),
    (["--poses", "12"], "--poses is the number of poses of a --raw recording"),
])
def test_raw_options_refused_in_one_line(argv, words, tmp_path, capsys):
    code, out, err = run_cli(["simulate", *argv, "-o", tmp_path / "x.csv"], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and words in lines[0]
    assert not (tmp_path / "x.csv").exists()
