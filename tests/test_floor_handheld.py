"""The noise floor of a position on poses turned and held by hand (issue #29; optcal/core/recording/floor.py,
docs/noise.md "The floor on hand-held logs", docs/scripts/floor_mikov.py): the fit of the flicker level no
longer swings to a confident level its points do not hold; on stationary noise the floor predicts the scatter
of the means; on Mikov et al.'s five MPU-9150 recordings (the real corpus's mikov/, MIT) it predicts the
leave-one-out scatter of the positions within the price docs/noise.md states; and a pose that turns while held,
which the per-axis Allan variance counts as flicker, is said in a note."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.app.workflows.recording import positions_from_raw
from optcal.core.analysis import position_sigma
from optcal.core.noise.colored import colored_noise
from optcal.core.problem import CalibrationProblem
from optcal.core.recording import floor as floor_module
from optcal.core.recording import given_intervals, positions_from_recording, read_recording
from optcal.core.recording.floor import fit_white_flicker, noise_floor
from optcal.core.synthetic_recording import OFFSET, SCALE, poses_recording

G0 = 9.80665


# -- the fit of the flicker level --------------------------------------------------------------------------------
# The pooled Allan variance of imu1.log's x axis (mikov/, 23 intervals; mg², from τ = 0.02 s, where the fit starts)
# and its independent pairs: the curve dips below the white line at 0.3-0.6 s and rises at the last two points
TAU = np.array([0.02, 0.04, 0.08, 0.16, 0.32, 0.64, 1.28, 2.56])
AVAR = np.array([18.97, 10.45, 4.918, 1.907, 0.8257, 0.4278, 0.3315, 0.3005])
NU = np.array([6473.0, 3213.5, 1583.8, 768.9, 361.5, 158.8, 57.5, 8.5])


def test_the_flicker_fit_converges_to_a_level_its_points_hold(monkeypatch):
    """Re-weighted with the curve a/τ + b itself, a b < 0 that brings it near 0 at 2.56 s gave that one point
    (8.5 pairs) an unbounded weight: the passes swung between b < 0 and b = 0.156 mg² with a standard error of
    0.002 mg² (70 SE; the floor of imu1 was then 1.8 times σ/√n, χ²/dof 0.105, p = 0.9995). Weighted with a
    negative level taken as none, the fit converges (the same after 6, 7 or 20 passes) and b is −2.0 SE: no
    flicker. It passes the points better: Σ((σ² − curve)/(σ²·√(2/ν)))² is 68 against the swung fit's 157."""
    coef, se = fit_white_flicker(TAU, AVAR, NU)
    print(f"a = {coef[0]:.4g} mg²·s, b = {coef[1]:.3g} ± {se:.2g} mg²")
    assert se > 0.01 and -3.0 < coef[1] / se < 0.0
    for passes in (7, 20):
        monkeypatch.setattr(floor_module, "FIT_PASSES", passes)
        again, se_again = fit_white_flicker(TAU, AVAR, NU)
        np.testing.assert_allclose(again, coef, rtol=1e-3, atol=1e-4)
        assert se_again == pytest.approx(se, rel=1e-3)

    def misfit(a, b):
        return float(np.sum(((AVAR - a / TAU - b) / (AVAR * np.sqrt(2.0 / NU))) ** 2))

    assert misfit(*coef) < 0.5 * misfit(0.370, 0.1555)  # the swung fit's coefficients


# -- stationary noise: the floor is the scatter of the means ----------------------------------------------------
def _scatter(seeds, noise_g, flicker_g, poses=23, hold_s=5.5):
    """RMS over seeds, poses and axes of the floor, and of the means' actual scatter about their average (the
    floor's definition, times p/(p − 1)), for poses_recording's random poses held ``hold_s`` s."""
    floor2 = actual2 = 0.0
    for seed in range(seeds):
        syn = poses_recording(np.random.default_rng(seed), n_poses=poses, hold_s=hold_s, noise_g=noise_g,
                              flicker_g=flicker_g, turn_rate_dps=60.0)
        rec, rests = syn.recording, syn.rests
        f = noise_floor(rec.N, rests, rec.t[rests[:, 0]], rec.rate, "g")
        e = np.array([rec.N[s:t].mean(0) for s, t in rests]) - (syn.directions * SCALE + OFFSET)
        floor2 += np.mean(f.sem**2)
        actual2 += np.mean((e - e.mean(0)) ** 2) * poses / (poses - 1)
    return np.sqrt(floor2 / actual2)


def test_on_stationary_noise_at_mikovs_levels_the_floor_is_the_scatter_of_the_means():
    """Mikov's MPU-9150s: 6.7 mg per sample at 100 Hz, 23 poses of about 5.5 s. With flicker B = 0.3 mg (the
    level fitted on imu0-imu2) the floor is the scatter of the means within [0.8, 1.25] over 100 recordings
    (measured 1.06; on Mikov's own poses 1.04-1.06, docs/noise.md); with white noise alone it is the price
    docs/noise.md states for an estimated flicker level, 1.0-1.35 (measured 1.24; 1.13-1.22 on Mikov's poses)."""
    with_flicker = _scatter(100, 6.7e-3, 0.3e-3)
    white = _scatter(100, 6.7e-3, 0.0)
    print(f"floor / actual scatter: white + flicker {with_flicker:.3f}, white {white:.3f}")
    assert 0.8 <= with_flicker <= 1.25
    assert 1.0 <= white <= 1.35


# -- a pose that turns while held ------------------------------------------------------------------------------
def _turning(seed, turn_rad, noise_g=2e-3):
    """24 random poses of 5 s, white noise ``noise_g`` per sample, and the pose turning while held: flicker
    wander of B = ``turn_rad`` about each axis (the output moves by θ × the force, across the force)."""
    rng = np.random.default_rng(seed)
    syn = poses_recording(rng, n_poses=24, hold_s=5.0, noise_g=noise_g, turn_rate_dps=60.0)
    rec, rests = syn.recording, syn.rests
    theta = colored_noise(len(rec.N), rec.rate, rng, flicker=turn_rad)
    N = rec.N.copy()
    for (s, e), d in zip(rests, syn.directions):
        N[s:e] += np.cross(theta[s:e], d) * SCALE
    return replace(rec, N=N), rests


def test_a_pose_that_turns_is_said_and_its_floor_taken_along_the_force(monkeypatch):
    """The issue's six IMUs on one bar (floor 6-14 times σ/√n, χ²/dof 0.5-2.4 while 2-3.7 mg residuals remain),
    reproduced: a turning pose (1 mrad of flicker wander, 2 mg white noise) made the per-axis floor 8-9 times
    σ/√n while the residuals, which see each mean along its force only, stay at the white noise (χ² 1.1 % of its
    expectation under that floor, over 10 recordings): a misfit many times the noise would pass. The check says
    it on every axis of every recording (12-26 standard errors apart; the flicker read along the force at most
    0.32 of the per-axis one), in a note and in describe(), and the floor takes the along-force level there: 1.0-
    1.8 times σ/√n, Σχ² / ΣE 0.51 (asserted ≥ 0.3; with the per-axis floor, below 0.1)."""
    def run(checked=True):
        chi2, expected = [], []
        for seed in range(10):
            rec, rests = _turning(seed, 1e-3)
            data = positions_from_recording(rec, given_intervals(rec, rests))
            f = data.extra["noise_floor"]
            if checked:
                assert np.all(f.turned) and np.all(f.turn_z > 10.0), f.turn_z
                assert np.all(f.along_bias_instability < 0.4 * f.axis_bias_instability)  # measured ≤ 0.32
                assert any(n.startswith("the poses turned while held (x/y/z") for n in f.notes)
                assert "the poses turned while held" in f.describe()
            cal = calibrate(data, "diag6", recheck=False)
            chi2.append(cal.fit.chi2)
            expected.append(cal.fit.expected_chi2)
            yield f.ratio
        run.chi2 = sum(chi2) / sum(expected)

    ratios = list(run())
    print(f"turning poses: floor / σ√n {min(ratios):.2f}-{max(ratios):.2f}, Σχ² / ΣE = {run.chi2:.3f}")
    assert max(ratios) < 2.5 and run.chi2 > 0.3
    # the per-axis floor the turn inflates: what the floor was
    monkeypatch.setattr(floor_module, "TURN_Z", np.inf)
    ratios = list(run(checked=False))
    assert min(ratios) > 5.0 and run.chi2 < 0.1


def test_on_stationary_noise_the_turn_check_rarely_speaks():
    """No turn: 60 recordings of white + flicker noise (MEMS-like, 100 µg/√Hz and B = 150 µg) and 60 of white
    noise: the per-axis and the along-force flicker levels differ by more than 3 standard errors on at most 3 of
    the 360 axes (measured 2; on 900 axes of test_noise_floor.py's MEMS recordings 0.7 %), where the floor then
    takes the along-force level."""
    flagged = 0
    for seed in range(60):
        for noise_g, flicker_g in ((100e-6 * 10, 150e-6), (2e-3, 0.0)):
            syn = poses_recording(np.random.default_rng(seed), n_poses=24, hold_s=5.0, noise_g=noise_g,
                                  flicker_g=flicker_g, turn_rate_dps=60.0)
            rec, rests = syn.recording, syn.rests
            f = noise_floor(rec.N, rests, rec.t[rests[:, 0]], rec.rate, "g")
            flagged += int(np.sum(f.turned))
    print(f"turn check: {flagged} of 360 axes flagged")
    assert flagged <= 3


# -- the real recordings -------------------------------------------------------------------------------------------
MIKOV_ARGS = ["--raw", "--units", "m/s2", "--gravity-ms2", "9.81", "--rate", "100", "--columns", "ax=0,ay=1,az=2",
              "--json"]


def _mikov(corpus, capsys):
    """Per recording: the command's JSON, the recording and the positions of the command's intervals."""
    return list(_each_mikov(corpus, capsys))


def _each_mikov(corpus, capsys):
    for i in range(5):
        path = corpus / "mikov" / f"imu{i}.log.gz"
        assert main(["calibrate", str(path), *MIKOV_ARGS]) == 0
        out = json.loads(capsys.readouterr().out)
        rec = read_recording(path, columns="ax=0,ay=1,az=2", rate=100.0, units="m/s2")
        yield out, rec, positions_from_recording(rec, given_intervals(rec, np.array(out["recording"]["intervals"])))


def test_mikov_floor_predicts_the_leave_one_out_scatter_within_its_price(corpus, capsys):
    """Each position's prediction error from the fit of the others (the command's model, on its intervals), times
    √(1 − h): the floor's ratio to its RMS, pooled over the 115 positions of the five recordings, is 1.32
    (asserted 0.9-1.5; before the flicker fit converged, 1.40, and 1.85-3.0 on imu1 and imu2). The floor is an
    estimate: at these levels the price of an estimated flicker level is 1.13-1.22 on stationary noise
    (docs/scripts/floor_mikov.py's simulation), and the hand adds 7 % of motion across the force to σ; the
    pooled ratio's own SE is ±0.09. The component along the force alone, σ/√n of the samples projected on it,
    predicts the scatter to 1.10 (asserted 0.85-1.25): the means' noise is white along the force, as the
    floor finds where it finds no flicker. Per recording the floor is 1.0-1.43 times σ/√n, mean 1.21 (asserted
    ≤ 1.4; 1.49 before, docs/noise.md's white-noise price is 1.27), and no axis's per-axis flicker exceeds the
    along-force one by 3 standard errors (the poses held still enough)."""
    z_floor, z_along, ratios = [], [], []
    for out, rec, data in _mikov(corpus, capsys):
        f = data.extra["noise_floor"]
        assert not np.any(f.turned), f.turn_z
        ratios.append(out["goodness_of_fit"]["noise_g"] / out["goodness_of_fit"]["white_noise_g"])
        cal = calibrate(data, out["model"], g_local=9.81 / G0, recheck=False)
        full = CalibrationProblem(cal.model, data, g_local=9.81 / G0, check=False)
        err = np.empty(len(data))
        for j in range(len(data)):
            others = calibrate(data.subset(np.delete(np.arange(len(data)), j)), cal.model, g_local=9.81 / G0,
                               recheck=False, force_weak=True)
            err[j] = full.position_residuals(others.x)[j]
        err *= np.sqrt(1.0 - cal.diagnostics.leverage)
        A = cal.problem.specific_force(cal.x)
        u = A / np.linalg.norm(A, axis=1, keepdims=True)
        along = np.array([np.std((rec.N[s:e] / cal.problem._K0) @ w, ddof=1) / np.sqrt(e - s)
                          for (s, e), w in zip(data.extra["detection"].intervals, u)])
        z_floor.append(err / position_sigma(cal.problem, cal.x))
        z_along.append(err / along)
    floor_ratio = 1.0 / np.sqrt(np.mean(np.concatenate(z_floor) ** 2))
    along_ratio = 1.0 / np.sqrt(np.mean(np.concatenate(z_along) ** 2))
    print(f"floor / LOO scatter {floor_ratio:.3f}, along-force σ/√n / LOO scatter {along_ratio:.3f}, "
          f"floor / (σ/√n) per recording {np.round(ratios, 2)}")
    assert 0.9 <= floor_ratio <= 1.5
    assert 0.85 <= along_ratio <= 1.25
    assert np.mean(ratios) <= 1.4


def test_mikov_calibrations_agree_with_the_source_in_standard_errors(corpus, capsys):
    """The source's table against the command's default fit: every scale factor, offset and angle cosine within
    2.5 of optcal's standard errors (measured at most 1.7: imu3's offset and angles); the floor that gives those
    errors is not too small to compare by."""
    from test_corpus_wild import _mikov_ref, _ours  # the source's table and the comparison, written once there

    for i, (out, _, _) in enumerate(_mikov(corpus, capsys)):
        p, se = out["parameters"], out["stderr"]
        ref_scale, ref_offset, ref_cos = _mikov_ref(i)
        scale, offset, cos = _ours(p)
        K = np.array([p["K_x"], p["K_y"], p["K_z"]])
        dev = np.concatenate([
            (scale - ref_scale) / [se["K_x"], se["K_y"], se["K_z"]],
            (offset - ref_offset) / (K * [se["b_x"], se["b_y"], se["b_z"]]),
            (cos - ref_cos) / [se["S_yz"], se["S_zy"], se["S_zx"]]])
        print(f"imu{i}: |Δ|/SE ≤ {np.max(np.abs(dev)):.2f}")
        assert np.all(np.abs(dev) < 2.5), (i, np.round(dev, 2))


def test_the_hand_held_phone_is_said_to_turn(corpus):
    """Hassan & Bao's phone, held in the hand (the real corpus's hassan_bao/): its z axis shows flicker B = 2 mg
    per axis and none along the force, many standard errors apart: the note says so, and its floor takes the
    along-force level on z (still above σ/√n: x's flicker is the axis's own)."""
    data = positions_from_raw(corpus / "hassan_bao" / "MobileAccData30orientationRawSample01.mat", rate=50.0,
                              units="m/s2", model="linear9")
    f = data.extra["noise_floor"]
    print(f.describe(), f.turn_z)
    assert f.turned[2] and f.turn_z[2] > 5.0
    assert f.axis_bias_instability[2] > 0.01 and f.along_bias_instability[2] < 0.5 * f.axis_bias_instability[2]
    assert f.bias_instability[2] == pytest.approx(f.along_bias_instability[2])
    assert f.bias_instability[0] == pytest.approx(f.axis_bias_instability[0])
    assert 1.2 < f.ratio < 2.5 and np.all(f.sem >= f.white)  # measured 2.78 with z's per-axis flicker
