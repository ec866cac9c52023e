"""Property-based tests of change-point segmentation (optcal.core.recording.segment, issue #20): random numbers of
poses held 0.5 s to 2 minutes, joined by turns or steps, at random noise levels, with saturation and dropped
(NaN) samples. Whatever the recording, segmentation returns intervals or raises InputError, never anything
else; its intervals never hold a saturated or missing sample; and on clean recordings every interval lies in
one pose (within 0.3 s) and most poses are found."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optcal.core.errors import InputError
from optcal.core.recording import interval_scores, segment_static
from optcal.core.synthetic_recording import poses_recording

TOL = 30  # samples at 100 Hz (0.3 s)
SETTINGS = settings(max_examples=40, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])

holds = st.lists(st.one_of(st.floats(0.5, 3.0), st.floats(3.0, 120.0)), min_size=2, max_size=10)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), hold=holds, motion=st.sampled_from(["rotate", "step"]),
       turn=st.floats(20.0, 180.0), noise=st.floats(1e-4, 2e-2), flicker=st.floats(0.0, 5e-4),
       clip=st.one_of(st.none(), st.floats(0.5, 1.2)), drop=st.sampled_from([0.0, 1e-4, 1e-3, 1e-2]))
def test_anything_goes_in_and_only_input_errors_come_out(seed, hold, motion, turn, noise, flicker, clip, drop):
    syn = poses_recording(np.random.default_rng(seed), n_poses=len(hold), hold_s=hold, motion=motion,
                          turn_rate_dps=turn, noise_g=noise, flicker_g=flicker, clip_g=clip, drop_fraction=drop)
    rec = syn.recording
    try:
        det = segment_static(rec)
    except InputError:
        return
    iv = det.intervals
    assert iv.dtype.kind == "i" and iv.ndim == 2 and iv.shape[1] == 2
    assert np.all(iv[:, 0] >= 0) and np.all(iv[:, 1] <= len(rec)) and np.all(iv[:, 1] > iv[:, 0])
    assert np.all(iv[1:, 0] >= iv[:-1, 1])  # in order, not overlapping
    bad = rec.saturated | ~np.isfinite(rec.N).all(axis=1)
    c = np.concatenate([[0], np.cumsum(bad)])
    assert np.all(c[iv[:, 1]] == c[iv[:, 0]])  # no saturated or missing sample inside an interval


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), hold=holds, motion=st.sampled_from(["rotate", "step"]),
       turn=st.floats(30.0, 180.0), noise=st.floats(5e-4, 5e-3))
def test_clean_recordings_give_back_their_poses(seed, hold, motion, turn, noise):
    """Clean recordings (white noise 0.5-5 mg, no saturation or drops): precision 1 (every interval in
    one pose) and recall at least 0.8 (poses of 0.5 s that PELT places a block late may fall short)."""
    syn = poses_recording(np.random.default_rng(seed), n_poses=len(hold), hold_s=hold, motion=motion,
                          turn_rate_dps=turn, noise_g=noise)
    det = segment_static(syn.recording)
    sc = interval_scores(det.intervals, syn.rests, len(syn.recording), TOL)
    assert sc["precision"] == 1.0, sc
    assert sc["recall"] >= 0.8, sc
