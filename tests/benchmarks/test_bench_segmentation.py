"""Benchmarks of static-interval detection on a 1-hour recording at 100 Hz (360,000 samples; issue #20 asks
for segmentation within 2 s): change-point segmentation (the default) on poses held 8 s, on poses held
10 minutes (PELT's worst case: long stretches without a change, cut into pieces of PIECE_BLOCKS blocks),
with a gyroscope whose stillness it judges too (issue #29), and the variance detector with one threshold for
comparison.

Run with `make bench`; under `make test` each runs once with timing disabled. Samples per second and the
intervals found go to extra_info.
"""

import numpy as np
import pytest

from optcal.core.recording import detect_static, interval_scores, segment_static
from optcal.core.synthetic_recording import poses_recording

N_HOUR = 360_000


@pytest.fixture(scope="module", params=["8 s poses", "10 min poses"])
def hour(request):
    hold = 8.0 if request.param == "8 s poses" else 600.0
    n_poses = 400 if hold == 8.0 else 6
    syn = poses_recording(np.random.default_rng(0), n_poses=n_poses, hold_s=hold, flicker_g=2e-4)
    rec = syn.recording
    rec.N, rec.t, rec.saturated = rec.N[:N_HOUR], rec.t[:N_HOUR], rec.saturated[:N_HOUR]
    rests = np.minimum(syn.rests[syn.rests[:, 0] < N_HOUR], N_HOUR)
    return request.param, syn, rests


def test_bench_segmentation_hour(benchmark, hour):
    import ruptures  # noqa: F401  (imported once, outside the timing: segment imports it on first use)

    name, syn, rests = hour
    rec = syn.recording
    det = benchmark(segment_static, rec)
    sc = interval_scores(det.intervals, rests, len(rec), 30)
    assert len(rec) == N_HOUR and sc["precision"] == 1.0 and sc["recall"] >= 0.99
    seconds = benchmark.stats.stats.min if benchmark.stats is not None else None
    benchmark.extra_info.update({"recording": name, "samples": len(rec), "seconds": seconds,
                                 "samples_per_s": None if seconds is None else len(rec) / seconds,
                                 "intervals": det.n_intervals, "precision": sc["precision"],
                                 "recall": sc["recall"]})


def _gyro(syn, rng):
    """A gyroscope's rates (rad/s) for the simulated recording: the turn of the gravity direction between
    consecutive samples (a rate orthogonal to it, which is all the accelerometer can tell) plus 0.01 rad/s of
    white noise."""
    A = syn.recording.N
    return np.vstack([np.zeros((1, 3)), np.cross(A[:-1], A[1:]) * syn.recording.rate]) + 0.01 * rng.standard_normal(
        A.shape)


def test_bench_segmentation_hour_with_gyroscope(benchmark, hour):
    import ruptures  # noqa: F401

    name, syn, rests = hour
    rec = syn.recording
    W = _gyro(syn, np.random.default_rng(1))
    det = benchmark(segment_static, rec, gyro=W)
    sc = interval_scores(det.intervals, rests, len(rec), 30)
    assert sc["precision"] == 1.0 and sc["recall"] >= 0.99
    seconds = benchmark.stats.stats.min if benchmark.stats is not None else None
    benchmark.extra_info.update({"recording": name + ", with gyroscope", "samples": len(rec), "seconds": seconds,
                                 "samples_per_s": None if seconds is None else len(rec) / seconds,
                                 "intervals": det.n_intervals, "precision": sc["precision"],
                                 "recall": sc["recall"]})


def test_bench_variance_detector_hour(benchmark, hour):
    name, syn, rests = hour
    rec = syn.recording
    det = benchmark(detect_static, rec, 4.0)
    assert det.n_intervals >= 1
    seconds = benchmark.stats.stats.min if benchmark.stats is not None else None
    benchmark.extra_info.update({"recording": name, "samples": len(rec), "seconds": seconds,
                                 "samples_per_s": None if seconds is None else len(rec) / seconds,
                                 "intervals": det.n_intervals})
