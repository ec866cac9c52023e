"""Change-point segmentation of raw recordings (optcal.core.recording.segment; docs/segmentation.md, issue #20):
poses with and without motion between them are found, a recording without rest is refused, intervals stay
inside the rests, the noise comes from the recording, and the detector is chosen as documented."""

import json

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.workflows.recording import detection_method, positions_from_raw
from optcal.core.errors import InputError
from optcal.core.recording import Recording, interval_scores, segment_static
from optcal.core.recording.segment import segment_diagnosis
from optcal.core.synthetic_recording import arc, poses_recording, random_directions, tumble_recording

RATE = 100.0
TOL = 30  # samples (0.3 s at 100 Hz): how far a found interval may reach beyond its true rest


def _write(path, rec):
    np.savetxt(path, np.column_stack([rec.t, rec.N]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.7f")
    return str(path)


@pytest.mark.parametrize("motion", ["rotate", "step"])
@pytest.mark.parametrize("hold_s", [0.5, 1.0, 3.0])
def test_poses_are_found_with_and_without_motion_between_them(motion, hold_s):
    """12 random poses held 0.5, 1 or 3 s, joined by 90 °/s turns or by steps (no motion at all): every
    interval found lies in one pose (precision 1), and nearly every pose is found. Measured over seeds 0-4:
    recall 1 everywhere but 0.5 s poses after turns (0.92-1: a pose of 50 samples that PELT places a block
    late is shorter than 0.5 s)."""
    for seed in range(5):
        syn = poses_recording(np.random.default_rng(seed), hold_s=hold_s, motion=motion)
        det = segment_static(syn.recording)
        sc = interval_scores(det.intervals, syn.rests, len(syn.recording), TOL)
        assert sc["precision"] == 1.0, (seed, sc)
        assert sc["recall"] >= (0.9 if hold_s == 0.5 and motion == "rotate" else 1.0), (seed, sc)


def test_one_second_poses_back_to_back_and_steps_calibrate(tmp_path, capsys):
    """Issue #20 (a) and (c): 1 s poses separated by steps only (a sensor re-seated with logging paused) are
    all found, and the calibration recovers the simulated scale factors."""
    syn = poses_recording(np.random.default_rng(11), n_poses=15, hold_s=1.0, motion="step")
    det = segment_static(syn.recording)
    sc = interval_scores(det.intervals, syn.rests, len(syn.recording), TOL)
    assert sc["n_found"] == 15 and sc["precision"] == sc["recall"] == 1.0
    path = _write(tmp_path / "steps.csv", syn.recording)
    assert main(["calibrate", path, "--raw", "--model", "diag6", "--min-static", "0.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    K = np.array([out["parameters"][f"K_{a}"] for a in "xyz"])
    np.testing.assert_allclose(K, [1.012, 0.991, 1.004], rtol=2e-3)  # optcal.core.synthetic_recording.SCALE
    assert out["n_positions"] == 15


@pytest.mark.parametrize("rate_dps", [0.5, 1.0, 2.0, 5.0, 10.0, 20.0])
def test_slow_tumbles_without_rest_are_refused(rate_dps, tmp_path, capsys):
    """Issue #20 (b): a continuous turn at 0.5-20 °/s has no rest; nothing in it is taken for one (three
    seeds each, 60 s at 100 Hz, 2 mg white and 0.5 mg flicker noise), and the CLI refuses it in one line
    that names the reason and the way out."""
    for seed in range(3):
        syn = tumble_recording(np.random.default_rng(seed), turn_rate_dps=rate_dps, flicker_g=5e-4)
        det = segment_static(syn.recording)
        assert det.n_intervals == 0, (seed, det.intervals)
        counts, advice = segment_diagnosis(det, 6)
        assert advice.startswith("no part of the recording is at rest")
    path = _write(tmp_path / "tumble.csv", syn.recording)
    assert main(["calibrate", path, "--raw", "--model", "diag6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "found 0 static interval(s)" in err[0]
    assert "no part of the recording is at rest" in err[0] and "--intervals" in err[0]


@pytest.mark.parametrize("rate_dps", [1.0, 5.0, 20.0])
def test_pauses_in_a_tumble_are_the_only_intervals(rate_dps):
    """A tumble with three 2 s pauses: every interval found lies in a pause (within 0.3 s at its ends), and
    at 5 and 20 °/s every pause is found. At 1 °/s the start of the turn is within the noise for a while
    (0.1° in 0.1 s, 1.7 mg against 2 mg per sample), so an end may be cut short but never extended."""
    for seed in range(3):
        syn = tumble_recording(np.random.default_rng(seed), turn_rate_dps=rate_dps, pauses=3)
        det = segment_static(syn.recording)
        sc = interval_scores(det.intervals, syn.rests, len(syn.recording), TOL)
        assert sc["precision"] == 1.0, (seed, det.intervals, syn.rests)
        if rate_dps >= 5:
            assert sc["recall"] == 1.0, (seed, sc)


def test_noise_comes_from_the_recording_and_long_poses_stay_whole():
    """The white noise SD per sample is estimated from the recording's quiet second differences (2 mg ×
    the simulated scale factors, within 5 %); 3-minute poses, cut into PELT's pieces of 2048 blocks, come
    back whole or in a few intervals, all inside their pose."""
    syn = poses_recording(np.random.default_rng(4), n_poses=3, hold_s=180.0, flicker_g=2e-4)
    det = segment_static(syn.recording)
    np.testing.assert_allclose(det.noise, 2e-3 * np.array([1.012, 0.991, 1.004]), rtol=0.05)
    sc = interval_scores(det.intervals, syn.rests, len(syn.recording), TOL)
    assert 3 <= det.n_intervals <= 6 and sc["precision"] == sc["recall"] == 1.0 and sc["iou"] > 0.98


def test_saturated_and_missing_samples_are_never_inside_an_interval():
    syn = poses_recording(np.random.default_rng(6), n_poses=10, hold_s=4.0, clip_g=0.95, drop_fraction=0.002)
    rec = syn.recording
    det = segment_static(rec)
    bad = rec.saturated | ~np.isfinite(rec.N).all(axis=1)
    assert bad.any() and det.n_intervals >= 3
    for s, e in det.intervals:
        assert not bad[s:e].any()
    sc = interval_scores(det.intervals, syn.rests, len(rec), TOL)
    assert sc["precision"] == 1.0
    assert any("set aside" in n for n in det.notes)


def test_without_a_rate_the_settings_are_in_samples():
    """Without a rate (time = sample index) the defaults are in samples (a pose of at least 50); a setting in
    seconds cannot be converted and is refused."""
    syn = poses_recording(np.random.default_rng(8), n_poses=8, hold_s=3.0)
    r = syn.recording
    rec = Recording(np.arange(len(r)).astype(float), r.N, None, "g", float("nan"), r.saturated, "norate")
    det = segment_static(rec)
    sc = interval_scores(det.intervals, syn.rests, len(rec), TOL)
    assert det.min_samples == 50 and sc["precision"] == sc["recall"] == 1.0
    with pytest.raises(InputError, match="no rate.*`rate`"):
        segment_static(rec, min_static_s=1.0)


def test_bad_settings_and_tiny_or_constant_recordings():
    syn = poses_recording(np.random.default_rng(9), n_poses=3, hold_s=2.0)
    rec = syn.recording
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="`min_static_s` must be a positive number of seconds"):
            segment_static(rec, min_static_s=bad)
    with pytest.raises(InputError, match="`window_s` must be"):
        segment_static(rec, window_s=0.0)
    short = Recording(rec.t[:40], rec.N[:40], None, "g", RATE, rec.saturated[:40], "short")
    with pytest.raises(InputError, match="too few"):
        segment_static(short)
    const = Recording(rec.t, np.tile(rec.N[:1], (len(rec), 1)), None, "g", RATE, rec.saturated, "const")
    with pytest.raises(InputError, match="never change"):
        segment_static(const)


def test_detector_choice_and_options_of_the_variance_detector(tmp_path):
    """Segmentation by default; the variance detector when asked (``method``) or when one of its own
    settings is given; its settings with method="segment" are refused in one line."""
    assert detection_method(None, None, None) == "segment"
    assert detection_method(None, "2:10", None) == "segment"  # the CLI's default search
    assert detection_method(None, 4, None) == "variance" and detection_method(None, None, 2.0) == "variance"
    assert detection_method("variance", None, None) == "variance"
    with pytest.raises(InputError, match="^`threshold_k` set the variance detector's threshold.*`method`"):
        detection_method("segment", 4, None)
    with pytest.raises(InputError, match="`method` 'kmeans': use segment"):
        detection_method("kmeans", None, None)
    syn = poses_recording(np.random.default_rng(10), n_poses=10, hold_s=3.0)
    path = _write(tmp_path / "ten.csv", syn.recording)
    seg = positions_from_raw(path, model="linear9")
    var = positions_from_raw(path, model="linear9", threshold_k=4)
    assert seg.extra["detection"].method == "segment" and var.extra["detection"].method == "variance"
    assert len(seg) == len(var) == 10
    # the two detectors' positions agree to the noise of a mean (2 mg / √n, n ≥ 100)
    np.testing.assert_allclose(seg.N, var.N, atol=1e-3)


def test_interval_scores_by_hand():
    truth = np.array([[0, 100], [200, 300]])
    found = np.array([[10, 90], [190, 260], [120, 180], [205, 330]])
    sc = interval_scores(found, truth, 400, tol=10)
    # [10, 90) inside; [190, 260) reaches 10 before its rest: inside within tol; [120, 180) in no rest;
    # [205, 330) overlaps its rest by 95 of 125 samples but ends 30 after it: beyond tol
    assert sc["precision"] == 0.5 and sc["recall"] == 1.0 and sc["n_false"] == 2
    # static samples: found 80 + 60 + 140 = 280, true 200, shared 80 + 100 = 180, union 300
    assert sc["iou"] == pytest.approx(180 / 300)


def test_arc_and_directions():
    rng = np.random.default_rng(0)
    d = random_directions(rng, 20, 30.0)
    ang = np.degrees(np.arccos(np.sum(d[1:] * d[:-1], axis=1)))
    assert np.all(ang >= 30.0) and np.allclose(np.linalg.norm(d, axis=1), 1.0)
    a, b = np.array([0.0, 0, 1]), np.array([0.0, 0, -1])  # antipodal: through a perpendicular
    v = arc(a, b, 50)
    assert v.shape == (50, 3) and np.allclose(np.linalg.norm(v, axis=1), 1.0)
    assert np.all(np.diff(v[:, 2]) < 0)


def test_a_recording_of_too_few_poses_is_told_so(tmp_path, capsys):
    """Three held poses joined by turns (a lab's 3-pose file outside the corpus was told to try another detector):
    all three are found, and the refusal says the recording holds just those, with no detector to try."""
    from optcal.core.synthetic_recording import poses_recording

    syn = poses_recording(np.random.default_rng(0), n_poses=3, hold_s=20.0)
    det = segment_static(syn.recording)
    assert det.n_intervals == 3
    counts, advice = segment_diagnosis(det, 6)
    assert advice.startswith("the recording holds rests in just 3 orientation(s); record at least 6")
    path = _write(tmp_path / "three.csv", syn.recording)
    assert main(["calibrate", path, "--raw", "--model", "diag6"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds rests in just 3 orientation(s)" in err[0] and "variance" not in err[0]
    # the counts name the rests kept, and diag6's number is the fit's own (6 parameters, 3 residual dof)
    assert "needs at least 9 (segments: 3 rest, " in err[0] and "record at least 9" in err[0]


def test_short_rests_in_one_orientation_are_not_advised_a_shorter_pose():
    """A file of one face (a lab's +X file of a six-file set): a long rest and ten short ones, all within 2° of +x.
    The refusal said "lower min_static_s to 0.2 s", which then found five rests of the same face and refused
    again; it says the recording holds rests in one orientation. Short rests in other orientations are still
    advised a shorter pose."""
    ang = np.radians([0] + [2, -2] * 5)
    dirs = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    syn = poses_recording(np.random.default_rng(0), dirs, hold_s=[5.0] + [0.35] * 10, motion="step", noise_g=1e-3)
    counts, advice = segment_diagnosis(segment_static(syn.recording), 9)
    assert advice.startswith("the recording holds rests in just 1 orientation(s); record at least 9"), advice
    spread = np.random.default_rng(1).normal(size=(11, 3))
    syn = poses_recording(np.random.default_rng(0), spread, hold_s=[5.0] + [0.35] * 10, motion="step", noise_g=1e-3)
    counts, advice = segment_diagnosis(segment_static(syn.recording), 9)
    assert advice.startswith("lower `min_static_s` to 0.3 s"), advice


def test_outputs_on_a_decimal_grid_are_not_taken_for_noiseless():
    """Outputs printed to 0.01 m/s² (a logger of another lab): where consecutive samples repeat, their differences
    are 1e-17, not 0, and were read as the noise level (z's SD taken for 0.0029 m/s², its quantisation floor,
    against 0.014), which cut six flat faces into slivers. The noise is measured within 20 % and every pose of
    the six found whole."""
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    syn = poses_recording(np.random.default_rng(4), dirs, hold_s=20.0, rate=RATE, motion="step", noise_g=1.4e-3)
    r = syn.recording
    N = np.round(r.N * 9.80665, 2)  # m/s², two decimals
    rec = Recording(r.t, N, None, "m/s2", r.rate, r.saturated, "decimal.csv")
    det = segment_static(rec)
    true_sd = np.array([np.std(np.diff(N[s:e], axis=0), axis=0) / np.sqrt(2) for s, e in syn.rests]).mean(axis=0)
    assert np.all(np.abs(det.segmentation.sigma / true_sd - 1) < 0.2), (det.segmentation.sigma, true_sd)
    sc = interval_scores(det.intervals, syn.rests, len(rec), TOL)
    assert sc["recall"] == 1.0 and sc["precision"] == 1.0 and det.n_intervals == 6, sc


def test_a_coarse_gyroscope_s_flicker_is_no_turn():
    """Six faces logged apart with a gyroscope at 0.01 per count that reads 0 on 98 % of its samples and flickers
    by a count or two on the others, in bursts (a six-face log of another lab): no turn was recorded, and no face
    is cut at a flicker (without the rule, 13 intervals for the 6 faces); a rate of 30 counts for 1 s inside a face
    is still a turn."""
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    syn = poses_recording(np.random.default_rng(5), dirs, hold_s=12.0, rate=RATE, motion="step", noise_g=2e-3)
    rng = np.random.default_rng(6)
    n = len(syn.recording)
    W = np.zeros((n, 3))
    for k in rng.choice(n - 40, 40, replace=False):  # bursts of flicker, 0.2-0.4 s long
        m = rng.integers(20, 40)
        W[k:k + m, rng.integers(3)] = rng.choice([-0.02, -0.01, 0.01, 0.02], m) * (rng.random(m) < 0.5)
    det = segment_static(syn.recording, gyro=W)
    sc = interval_scores(det.intervals, syn.rests, n, TOL)
    assert det.n_intervals == 6 and sc["recall"] == 1.0 and sc["precision"] == 1.0, (det.n_intervals, sc)
    turn = W.copy()
    a, b = syn.rests[2][0] + 300, syn.rests[2][0] + 400
    turn[a:b, 0] = 0.3  # 30 counts for a second inside the third face: a turn
    det = segment_static(syn.recording, gyro=turn)
    assert not any(s < b and e > a for s, e in det.intervals)


def test_a_gyroscope_at_its_level_through_poses_logged_apart():
    """Six faces logged apart, the gyroscope printed to 0.01 °/s and reading 0.02 or 0.03 throughout (a lab's
    MPU-6050 files joined): its flickers are no turns (the quantum a turn must exceed is 0.01, not a rounding
    residue of 1e-17), and the joins, which its rates never saw, bound no scale (a flicker counted as turning gave
    0.04 output units per rad/s, and the attitude rule then flagged 69 % of the samples: on the lab's files 17
    intervals over 4 poses before, 7 over the 6 faces now)."""
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    syn = poses_recording(np.random.default_rng(8), dirs, hold_s=30.0, rate=62.5, motion="step", noise_g=1e-3)
    rng = np.random.default_rng(9)
    n = len(syn.recording)
    W = np.round(np.column_stack([np.where(rng.random(n) < 0.5, 0.02, 0.03), rng.choice([-0.01, 0.0, 0.01, 0.02], n),
                                  np.where(rng.random(n) < 0.9, 0.01, 0.02)]), 2)
    for k in rng.choice(n - 30, 8, replace=False):  # a few bursts at 0.04-0.05 for half a second: "turns"
        W[k:k + 30, 1] = rng.choice([0.04, 0.05], 30)
    det = segment_static(syn.recording, gyro=W)
    sc = interval_scores(det.intervals, syn.rests, n, TOL)
    # the bursts of 2-3 counts cut their faces (14 intervals), the faces are otherwise whole; without the noise-path
    # rule the attitude rule flags nearly everything (recall 0.83, 2 % of the faces' samples kept)
    assert sc["recall"] == 1.0 and sc["precision"] == 1.0 and sc["iou"] > 0.9, (det.n_intervals, sc)


def test_a_fast_gyroscope_s_correlated_noise_is_no_turn(monkeypatch):
    """A 1-kHz IMU behind its low-pass filter (a rocket club's MicroStrain log of one face held still): its rate
    noise is correlated over tens of samples, so second differences understate what a 0.25-s average scatters,
    and the pose "turned" throughout (0 rests). From 400 Hz the average is judged by its own scatter: the pose is
    one rest; judged on white noise alone (the rule switched off), none."""
    import optcal.core.recording.segment as seg
    from optcal.core.recording.reading import Recording

    rng = np.random.default_rng(3)
    n, rate = 12000, 1000.0
    A = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 1e-3, (n, 3))
    e = np.vstack([np.zeros((1, 3)), np.cumsum(rng.normal(0, 1, (n + 49, 3)), axis=0)])
    W = (e[50:] - e[:-50]) / np.sqrt(50) * 0.005  # rad/s, a moving sum of 50 samples
    rec = Recording(np.arange(n) / rate, A, None, "g", rate, np.zeros(n, bool))
    assert segment_static(rec, gyro=W).intervals.tolist() == [[0, n]]
    monkeypatch.setattr(seg, "CORRELATED_RATE", np.inf)
    assert segment_static(rec, gyro=W).n_intervals == 0
