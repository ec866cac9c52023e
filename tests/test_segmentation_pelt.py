"""optcal.core.recording.pelt against ruptures' compiled PELT (KernelCPD, linear kernel, min_size 1, jump 1): the same
change points on random piecewise-constant series with noise, at many penalties, and on the block series that
segmentation builds from raw recordings of the real corpus (tests/corpus.py; docs/segmentation.md)."""

import numpy as np
import pytest
import ruptures

import optcal.core.recording.segment as segment
from optcal.core.recording.pelt import RUPTURES_FROM_BLOCKS, VECTOR_FROM, pelt_l2, pelt_l2_many
from optcal.core.recording.reading import read_recording


def _ruptures(Z, pen):
    return ruptures.KernelCPD(kernel="linear", min_size=1, jump=1).fit(Z).predict(pen=pen)


def test_same_change_points_as_ruptures_on_random_series():
    rng = np.random.default_rng(7)
    for _ in range(300):
        lens = rng.integers(1, 120, size=rng.integers(1, 14))
        Z = np.concatenate([rng.normal(rng.normal(0, 3, 3), 1, (n, 3)) for n in lens])
        pen = float(rng.uniform(1, 60))
        assert pelt_l2(Z, pen) == _ruptures(Z, pen)


def test_series_in_lockstep_give_what_each_gives_alone():
    """pelt_l2_many (segmentation's pieces side by side) against pelt_l2 series by series: 100 batches of 2-5
    series of different lengths, a long rest among them, and an empty and a one-block series."""
    rng = np.random.default_rng(11)
    for _ in range(100):
        batch = []
        for _ in range(rng.integers(2, 6)):
            lens = rng.integers(1, 120, size=rng.integers(1, 14))
            batch.append(np.concatenate([rng.normal(rng.normal(0, 3, 3), 1, (n, 3)) for n in lens]))
        pen = float(rng.uniform(1, 60))
        assert pelt_l2_many(batch, pen) == [pelt_l2(Z, pen) for Z in batch]
    rest = np.concatenate([rng.normal(0, 1, (6 * VECTOR_FROM, 3)), rng.normal(5, 1, (40, 3))])
    batch = [rest, np.zeros((0, 3)), rng.normal(0, 1, (1, 3)), rest[::-1]]
    assert pelt_l2_many(batch, 123.0) == [pelt_l2(Z, 123.0) for Z in batch]


def test_long_rest_takes_the_vector_pass_and_agrees():
    """A rest long enough that PELT keeps more than VECTOR_FROM candidates (the NumPy pass), then a step."""
    rng = np.random.default_rng(3)
    Z = np.concatenate([rng.normal(0, 1, (6 * VECTOR_FROM, 3)), rng.normal(5, 1, (40, 3))])
    assert pelt_l2(Z, 123.0) == _ruptures(Z, 123.0) == [6 * VECTOR_FROM, len(Z)]


@pytest.mark.parametrize("path, units, rate", [
    ("imu_tk/xsens_acc.mat.gz", "counts", None), ("mpu6050/example_data_calibration.csv", "counts", None),
    ("imucal/annotated_session.csv", "counts", 204.8), ("imucal/example_ferraris_session.csv", "m/s2", 102.4)])
def test_segmentation_of_real_recordings_is_the_same_with_either(path, units, rate, monkeypatch, corpus):
    rec = read_recording(corpus / path, units=units, rate=rate)
    ours = segment.segment_static(rec).intervals
    assert len(ours) >= 6
    monkeypatch.setattr(segment, "RUPTURES_FROM_BLOCKS", 0)  # every series through ruptures
    theirs = segment.segment_static(rec).intervals
    np.testing.assert_array_equal(ours, theirs)
    assert RUPTURES_FROM_BLOCKS > 10_000  # the corpus' recordings are below it: pelt_l2 served them above


def test_shape_is_checked():
    with pytest.raises(ValueError, match="an \\(n, 3\\) series"):
        pelt_l2(np.zeros((10, 2)), 1.0)
