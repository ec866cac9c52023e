"""optcal.core.recording.pelt against ruptures' compiled PELT (KernelCPD, linear kernel, min_size 1, jump 1): the same
change points on random piecewise-constant series with noise, at many penalties, and on the block series that
segmentation builds from raw recordings of the real corpus (tests/corpus.py; docs/segmentation.md); and the compiled
kernel that segmentation takes from ruptures' extension file without importing the package."""

import subprocess
import sys

import numpy as np
import pytest
import ruptures

import optcal.core.recording.pelt as pelt
import optcal.core.recording.segment as segment
from optcal.core.recording.pelt import VECTOR_FROM, compiled_pelt_l2, pelt_ends, pelt_l2, pelt_l2_many
from optcal.core.recording.reading import read_recording


def _ruptures(Z, pen):
    return ruptures.KernelCPD(kernel="linear", min_size=1, jump=1).fit(Z).predict(pen=pen)


def _random_series(rng):
    """A piecewise-constant (n, 3) series with unit noise: 1-13 levels of 1-119 blocks each."""
    lens = rng.integers(1, 120, size=rng.integers(1, 14))
    return np.concatenate([rng.normal(rng.normal(0, 3, 3), 1, (n, 3)) for n in lens])


def test_same_change_points_as_ruptures_on_random_series():
    rng = np.random.default_rng(7)
    for _ in range(300):
        Z = _random_series(rng)
        pen = float(rng.uniform(1, 60))
        assert pelt_l2(Z, pen) == _ruptures(Z, pen)


def _agrees_series_by_series(batched, rng, smallest):
    """``batched`` (several series in one call) gives pelt_l2's change points series by series on 100 batches of
    ``smallest``-5 random series."""
    for _ in range(100):
        batch = [_random_series(rng) for _ in range(rng.integers(smallest, 6))]
        pen = float(rng.uniform(1, 60))
        assert batched(batch, pen) == [pelt_l2(Z, pen) for Z in batch]


def _long_rest(rng):
    """A rest long enough that PELT keeps more than VECTOR_FROM candidates (the NumPy pass), then a step."""
    return np.concatenate([rng.normal(0, 1, (6 * VECTOR_FROM, 3)), rng.normal(5, 1, (40, 3))])


def test_series_in_lockstep_give_what_each_gives_alone():
    """pelt_l2_many (segmentation's pieces side by side) against pelt_l2 series by series: 100 batches of 2-5
    series of different lengths, a long rest among them, and an empty and a one-block series."""
    rng = np.random.default_rng(11)
    _agrees_series_by_series(pelt_l2_many, rng, smallest=2)
    rest = _long_rest(rng)
    batch = [rest, np.zeros((0, 3)), rng.normal(0, 1, (1, 3)), rest[::-1]]
    assert pelt_l2_many(batch, 123.0) == [pelt_l2(Z, 123.0) for Z in batch]


def test_long_rest_takes_the_vector_pass_and_agrees():
    """A rest long enough that PELT keeps more than VECTOR_FROM candidates (the NumPy pass), then a step."""
    Z = _long_rest(np.random.default_rng(3))
    assert pelt_l2(Z, 123.0) == _ruptures(Z, 123.0) == [6 * VECTOR_FROM, len(Z)]


@pytest.mark.parametrize("path, units, rate", [
    ("imu_tk/xsens_acc.mat.gz", "counts", None), ("mpu6050/example_data_calibration.csv", "counts", None),
    ("imucal/annotated_session.csv", "counts", 204.8), ("imucal/example_ferraris_session.csv", "m/s2", 102.4)])
def test_segmentation_of_real_recordings_is_the_same_with_either(path, units, rate, monkeypatch, corpus):
    """The compiled kernel (the default), the NumPy PELT, and ruptures' public API give the same intervals."""
    rec = read_recording(corpus / path, units=units, rate=rate)
    compiled = segment.segment_static(rec).intervals
    assert len(compiled) >= 6
    monkeypatch.setattr(pelt, "compiled_pelt_l2", lambda: None)  # as where ruptures lays its files out otherwise
    ours = segment.segment_static(rec).intervals
    monkeypatch.setattr(pelt, "RUPTURES_FROM_BLOCKS", 0)  # every series through ruptures' public API
    theirs = segment.segment_static(rec).intervals
    np.testing.assert_array_equal(ours, compiled)
    np.testing.assert_array_equal(ours, theirs)


def test_compiled_kernel_gives_pelt_l2s_change_points():
    """pelt_ends (ruptures' compiled kernel, loaded from its file) against the NumPy PELT: 100 batches of 1-5
    random piecewise-constant series, a long rest among them, a one-block series."""
    assert compiled_pelt_l2() is not None  # the installed ruptures (pyproject.toml) has it where it is looked for
    rng = np.random.default_rng(5)
    _agrees_series_by_series(pelt_ends, rng, smallest=1)
    rest = _long_rest(rng)
    assert pelt_ends([rest, rng.normal(0, 1, (1, 3))], 123.0) == [[6 * VECTOR_FROM, len(rest)], [1]]


def test_the_compiled_kernel_loads_without_ruptures_or_scipy():
    """In a fresh process, loading the kernel and segmenting a recording import neither the ruptures package nor
    scipy (their import is what the compiled kernel is taken on its own to avoid); a later ``import ruptures``
    still works and gives the same change points."""
    code = (
        "import sys, numpy as np\n"
        "from optcal.core.recording.pelt import compiled_pelt_l2, pelt_ends\n"
        "assert compiled_pelt_l2() is not None\n"
        "Z = np.random.default_rng(0).normal(0, 1, (300, 3)); Z[100:200] += 4\n"
        "ends = pelt_ends([Z], 60.0)[0]\n"
        "print(ends, 'ruptures' in sys.modules, any(m == 'scipy' or m.startswith('scipy.') for m in sys.modules))\n"
        "import ruptures\n"
        "print(ruptures.KernelCPD(kernel='linear', min_size=1, jump=1).fit(Z).predict(pen=60.0) == ends)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "[100, 200, 300] False False", out
    assert out[1] == "True", out


def test_shape_is_checked():
    with pytest.raises(ValueError, match="an \\(n, 3\\) series"):
        pelt_l2(np.zeros((10, 2)), 1.0)
