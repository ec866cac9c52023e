"""The calibration object lives in the core and owns its file (issue #30): ``Calibration.write`` writes the
versioned record that ``optcal calibrate -o`` writes, ``Calibration.read`` reads it back as the
CalibrationFile that applies it, and the round trip is exact."""

from __future__ import annotations

import json

import numpy as np

import optcal
from optcal.core.calfile import FORMAT, FORMAT_VERSION, CalibrationFile
from optcal.core.calibration import Calibration


def _fit():
    rng = np.random.default_rng(11)
    sim = optcal.simulate("linear9", None, rng, scheme="36", noise_g=1e-5)
    return optcal.calibrate(sim.data, "linear9")


def test_write_then_read_is_exact_and_applies_as_the_fit(tmp_path):
    cal = _fit()
    assert isinstance(cal, Calibration)
    path = tmp_path / "cal.json"
    cal.write(path, units_out="g", source="simulated")
    record = json.loads(path.read_text())
    assert record["format"] == FORMAT and record["format_version"] == FORMAT_VERSION
    assert record["units"]["raw"] == "g" and record["units"]["calibrated"] == "g"
    assert record["data"]["source"] == "simulated"
    back = Calibration.read(path)
    assert isinstance(back, CalibrationFile)
    np.testing.assert_array_equal(back.x, cal.x)  # repr precision: the round trip is exact
    N = cal.model.forward(cal.x, np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]]))[0]
    np.testing.assert_allclose(back.apply(N), optcal.apply(cal, N), rtol=0, atol=1e-15)
    # the record without a file is the same content but for the time it was made
    mem = cal.file_record(units_out="g", source="simulated")
    assert {k: v for k, v in mem.items() if k != "created"} == {k: v for k, v in record.items() if k != "created"}


def test_write_keeps_an_existing_file_unless_told(tmp_path):
    cal = _fit()
    path = tmp_path / "cal.json"
    path.write_text("mine")
    try:
        cal.write(path)
    except optcal.InputError as exc:
        assert "exists" in str(exc)
    else:
        raise AssertionError("an existing file was overwritten")
    assert path.read_text() == "mine"
    cal.write(path, overwrite=True)
    assert Calibration.read(path).model.name == "linear9"
