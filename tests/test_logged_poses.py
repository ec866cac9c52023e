"""Poses logged apart (optcal.core.recording.jumps; docs/segmentation.md, "Poses logged apart"): a file that holds
only the poses, back to back, each a burst of samples logged at a key press (CK-Explorer's logger). Its poses are
bounded by jumps, and a pose that shakes with a hand's tremor is a rest there; the same tremor between turns that
were recorded is not (the accelerometer alone cannot tell it from a motion), and a pose moved beyond the tremor's
bound is not."""

import json

import numpy as np
from corpus import corpus_root

from optcal.app.cli import main
from optcal.core.recording import Recording, interval_scores, segment_static
from optcal.core.recording.jumps import TREMOR_G, jump_bounded, jump_samples
from optcal.core.synthetic_recording import SCALE, poses_recording

RATE = 100.0
TOL = 30  # samples: how far a found interval may reach beyond its true rest


def _tremor(rng, n, amp_g):
    """A hand's tremor (g, (n, 3)): three sines of 3-9 Hz per axis with random phases, RMS ``amp_g`` per axis."""
    t = np.arange(n) / RATE
    f = rng.uniform(3.0, 9.0, (3, 3))
    ph = rng.uniform(0, 2 * np.pi, (3, 3))
    x = np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None]).sum(axis=1)  # (n, 3)
    return x / x.std(axis=0) * amp_g


def _shaken(syn, rng, every, amp_g):
    """The recording with a tremor of RMS ``amp_g`` (g per axis) added to every ``every``-th pose."""
    N = syn.recording.N.copy()
    for s, e in syn.rests[::every]:
        N[s:e] += _tremor(rng, e - s, amp_g) * SCALE
    r = syn.recording
    return Recording(r.t, N, None, r.units, r.rate, r.saturated, r.path), syn.rests[::every]


def test_a_logger_s_shaking_poses_are_rests():
    """20 poses of 1 s back to back (no motion logged), every second one shaking at 6 mg RMS per axis (3-9 Hz,
    about CK-Explorer's 4-9 mg): every pose found, each interval inside one pose. Seeds 0-4."""
    for seed in range(5):
        rng = np.random.default_rng(seed)
        syn = poses_recording(rng, n_poses=20, hold_s=1.0, motion="step", noise_g=1.5e-3)
        rec, shaken = _shaken(syn, rng, 2, 6e-3)
        sc = interval_scores(segment_static(rec).intervals, syn.rests, len(rec), TOL)
        assert sc["precision"] == 1.0 and sc["recall"] == 1.0, (seed, sc)


def test_the_same_tremor_between_recorded_turns_is_refused():
    """Poses shaking at 8 mg RMS per axis, joined by 90 °/s turns that were recorded: no jump bounds a pose,
    and without a gyroscope the tremor is not told from a motion: the shaking poses are refused (recall of them
    0), the quiet ones found; logged apart, the same poses are found (recall ≥ 0.9: at 14 mg in all, some
    blocks scatter beyond TREMOR_G). The rule is for what the file shows, not for what a tremor is."""
    for seed in range(3):
        rng = np.random.default_rng(seed)
        syn = poses_recording(rng, n_poses=20, hold_s=1.0, motion="step", noise_g=1.5e-3)
        rec, shaken = _shaken(syn, rng, 2, 8e-3)
        assert interval_scores(segment_static(rec).intervals, shaken, len(rec), TOL)["recall"] >= 0.9, seed
        rng = np.random.default_rng(seed)
        syn = poses_recording(rng, n_poses=20, hold_s=1.0, motion="rotate", noise_g=1.5e-3)
        rec, shaken = _shaken(syn, rng, 2, 8e-3)
        found = segment_static(rec).intervals
        assert interval_scores(found, shaken, len(rec), TOL)["recall"] == 0.0, seed
        quiet = syn.rests[1::2]
        assert interval_scores(found, quiet, len(rec), TOL)["recall"] >= 0.9, seed


def test_a_pose_moved_beyond_the_tremor_bound_is_refused():
    """Between jumps, a pose whose block means scatter by 5 % of gravity (three times TREMOR_G) is not held
    but moved: refused; the quiet poses around it found."""
    rng = np.random.default_rng(7)
    syn = poses_recording(rng, n_poses=12, hold_s=1.0, motion="step", noise_g=1.5e-3)
    rec, shaken = _shaken(syn, rng, 3, 0.05 / np.sqrt(3))
    assert 0.05 > 2 * TREMOR_G
    found = segment_static(rec).intervals
    assert interval_scores(found, shaken, len(rec), TOL)["recall"] == 0.0
    quiet = np.delete(syn.rests, np.arange(0, 12, 3), axis=0)
    assert interval_scores(found, quiet, len(rec), TOL)["recall"] == 1.0


def test_jumps_are_single_sample_steps_not_recorded_turns_or_tremor():
    """A step of 100 mg in one sample is a jump; a turn recorded at 200 °/s (35 mg on each of its samples), a
    knock's spike out and back (each of its two steps is beside the other: no jump, and nothing bounded) and
    noise are told apart by the steps beside them."""
    n = 400
    N = np.tile([0.0, 0.0, 1.0], (n, 1)) + np.random.default_rng(0).normal(0, 2e-3, (n, 3))
    N[100:] += [0.1, 0.0, 0.0]  # the step
    ang = np.radians(np.arange(0, 60) * 2.0)  # 200 °/s at 100 Hz: 2° per sample, from sample 200 to 259
    N[200:260] = np.column_stack([np.sin(ang), np.zeros(60), np.cos(ang)])
    N[260:] = [np.sin(ang[-1]), 0.0, np.cos(ang[-1])]
    N[330] += [0.0, 0.2, 0.0]  # a knock: one sample out
    j = jump_samples(N, np.zeros(n, bool), 1.0)
    assert j.tolist() == [100]
    # bounded: a segment whose both ends sit at jumps, in blocks of 6 samples (the jump inside the block on
    # either side of its boundary)
    nb = n // 6
    seg = np.array([[100 // 6, 200 // 6], [0, 100 // 6], [100 // 6 + 2, 200 // 6], [200 // 6, nb], [0, nb]])
    assert jump_bounded(seg, j, 6, nb).tolist() == [False, True, False, False, False]
    seg2 = np.array([[100 // 6, 330 // 6]])
    assert jump_bounded(seg2, np.array([100, 330]), 6, nb).tolist() == [True]


def test_ck_explorer_every_logged_pose_and_the_count_the_fit_used(capsys):
    """CK-Explorer's logger (no gyroscope, 160 poses of 100 samples back to back, 4-9 mg of tremor in a quarter of
    them): every pose found and fitted. Position 19, whose force drifts by 1.1 mg while held, is an outlier of the
    fit, re-examined: its drift is within the recording's own slow noise (the floor's flicker, which the tremor
    poses raise), so it is kept and named, not dropped; the text's count is the calibration file's."""
    path = corpus_root() / "ck_explorer" / "acc_log.csv"
    assert main(["calibrate", str(path), "--raw", "--units", "g", "--rate", "100"]) == 0
    out = capsys.readouterr().out
    assert "160 static interval(s)" in out
    assert "model nonlinear12, 160 positions, outputs in g" in out
    assert "position 19 is -849 µg off the fit of the other positions, 5.08 σ" in out
    assert "moved while held" not in out
    assert main(["calibrate", str(path), "--raw", "--units", "g", "--rate", "100", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_positions"] == 160
    assert [row["position"] for row in out["positions"]] == list(range(160))


def test_the_recording_figure_draws_a_bar_for_each_position_fitted(tmp_path, monkeypatch):
    """calibrate --raw --plot draws the residual of each fitted position over its interval: when the recheck drops a
    pose the figure takes the fitted positions' intervals (it had drawn no bar at all: 159 residuals against 160
    intervals). The pose: an interval given 1.5 s into the turn after it, an outlier of the fit; the recheck's
    drift bound set to 0 so that it is dropped rather than trimmed (the plumbing under test is the figure's)."""
    import optcal.core.plots.recording as plots

    seen = {}
    real = plots.recording_figure

    def spy(recording, detection, residuals_g):
        fig = real(recording, detection, residuals_g)
        seen["bars"] = sum(len(c) for c in fig.axes[-1].containers)
        seen["residuals"] = len(residuals_g)
        return fig

    monkeypatch.setattr(plots, "recording_figure", spy)
    import optcal.core.recording.positions as positions

    monkeypatch.setattr(positions, "DRIFT_SIGMAS", 0.0)
    syn = poses_recording(np.random.default_rng(4), n_poses=16, hold_s=3.0, turn_rate_dps=30.0, noise_g=1e-3)
    rests = syn.rests.copy()
    rests[5, 1] += 150  # 1.5 s into the turn that follows pose 5
    rec = syn.recording
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.column_stack([rec.t, rec.N]), delimiter=",", header="t,ax,ay,az", comments="", fmt="%.7f")
    (tmp_path / "iv.json").write_text(json.dumps(rests.tolist()))
    assert main(["calibrate", str(path), "--raw", "--units", "g", "--intervals", str(tmp_path / "iv.json"),
                 "--model", "diag6", "--plot", str(tmp_path / "fig.png")]) == 0
    assert seen == {"bars": 15, "residuals": 15} and (tmp_path / "fig.png").stat().st_size > 0
