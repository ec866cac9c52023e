"""A headerless IMU table of seven columns is read by position as t, ax, ay, az, gx, gy, gz; a lab that writes
t, gx, gy, gz, ax, ay, az (a new user's float dump of a 16-IMU array) had its gyroscope calibrated as the
accelerometer and a refusal about observability that named neither. The two triples are told apart by what
they read: an accelerometer turned between poses a magnitude near g throughout, a gyroscope near 0 at rest."""

from __future__ import annotations

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.core.recording import read_recording
from optcal.core.synthetic_imu import handheld_imu


def _write(path, t, first, second):
    np.savetxt(path, np.column_stack([t, first, second]), delimiter=",", fmt="%.6f")
    return str(path)


@pytest.fixture(scope="module")
def imu():
    s = handheld_imu(np.random.default_rng(3))
    A, W = np.asarray(s.acc.N), np.asarray(s.gyro.N)
    return np.arange(len(A)) / s.acc.rate, A, W


def test_gyroscope_first_is_refused_naming_the_columns(tmp_path, imu, capsys):
    t, A, W = imu
    path = _write(tmp_path / "gyro_first.csv", t, W, A)
    assert main(["calibrate", path, "--raw", "--units", "g"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and len(err) <= 300, err
    assert "columns 1, 2, 3 vary as a gyroscope's rates do" in err
    assert "t=0,ax=4,ay=5,az=6,gx=1,gy=2,gz=3" in err
    # named as the message says, it reads: the accelerometer's magnitude is 1 g
    rec = read_recording(path, columns="t=0,ax=4,ay=5,az=6,gx=1,gy=2,gz=3", units="g")
    assert np.median(np.linalg.norm(rec.N, axis=1)) == pytest.approx(1.0, abs=0.02)


def test_the_usual_order_reads_without_a_word(tmp_path, imu):
    t, A, W = imu
    rec = read_recording(_write(tmp_path / "usual.csv", t, A, W), units="g")
    np.testing.assert_allclose(rec.N, A, atol=1e-6)
    np.testing.assert_allclose(rec.W, W, atol=1e-6)
