"""The noise floor of a position (issue #20, item 5; optcal/core/noise/floor.py, docs/noise.md "The noise floor of a
position"): the pooled Allan variance, the covariance of interval means under flicker noise, the floor against
σ/√n, what positions_from_recording and the positions CSV carry, the false-alarm rate of the χ² (F) test on
simulated white + flicker recordings, and the Xsens MTi recording of imu_tk (BSD licence; the real corpus's imu_tk/,
beside the project: tests/corpus.py)."""

from __future__ import annotations

import gzip
import math
from dataclasses import replace

import numpy as np
import pytest
from corpus import corpus_root

from optcal.app.fit import calibrate
from optcal.core.analysis import goodness_of_fit
from optcal.core.data import read_positions
from optcal.core.errors import InputError
from optcal.core.model import get_model
from optcal.core.noise.colored import colored_noise
from optcal.core.noise.fit import FLICKER_FACTOR, SLOPE_TOL
from optcal.core.presets import PAPER_TRUTH
from optcal.core.problem import CalibrationProblem
from optcal.core.recording import floor as floor_module
from optcal.core.recording import given_intervals, positions_from_recording, read_recording
from optcal.core.recording.floor import centred_variance, flicker_covariance, noise_floor, octaves, pooled_avar
from optcal.core.recording.reading import Recording
from optcal.core.schemes import scheme

RATE, DWELL, MOVE = 100.0, 5.0, 3.0  # Hz, s of each pose, s of motion between poses
MODEL = get_model("linear9")
TRUTH = MODEL.from_dict({k: v for k, v in PAPER_TRUTH.items() if k in MODEL.names})
# a MEMS-like accelerometer: white 100 µg/√Hz, flicker B = 150 µg (σ_A floor 100 µg): flicker dominates at τ > 1 s
MEMS = dict(white=100e-6, flicker=150e-6)


# -- the pieces ------------------------------------------------------------------------------------------------
def test_the_floor_spells_the_constants_of_the_noise_fit_alike():
    """optcal.core.recording.floor cannot import optcal.core.noise (which reads recordings); its copies must agree."""
    assert floor_module.FLICKER_FACTOR == FLICKER_FACTOR and floor_module.SLOPE_TOL == SLOPE_TOL


def test_pooled_avar_is_allantools_oadev_on_one_interval_and_pools_the_differences_of_several():
    import allantools

    y = np.random.default_rng(0).standard_normal((3000, 2)) + [5.0, -2.0]
    m = octaves(500)
    one, count = pooled_avar(y, np.array([[0, 3000]]), m)
    ref = np.array([allantools.oadev(y[:, j], rate=1.0, data_type="freq", taus=m.astype(float))[1] ** 2
                    for j in range(2)]).T
    np.testing.assert_allclose(one, ref, rtol=1e-10)
    np.testing.assert_array_equal(count, 3000 - 2 * m + 1)
    # two intervals with a jump between them: only differences inside each count, weighted by their number
    z = y.copy()
    z[1000:] += 100.0
    iv = np.array([[0, 1000], [1200, 3000]])
    both, c2 = pooled_avar(z, iv, m)
    a, ca = pooled_avar(y, iv[:1], m)
    b, cb = pooled_avar(y, iv[1:], m)
    np.testing.assert_array_equal(c2, ca + cb)
    np.testing.assert_allclose(both, (a * ca[:, None] + b * cb[:, None]) / c2[:, None], rtol=1e-10)


@pytest.mark.parametrize("tau", [0.3, 5.0, 60.0])
def test_flicker_covariance_gives_the_allan_floor_and_barnes_bias_function(tau):
    """Two adjacent means of flicker noise (B = 1): half the variance of their difference is the Allan floor
    2 ln 2/π = 0.664²; p contiguous means scatter about their average by Barnes' B₁(p, 0) = p ln p/(2(p−1) ln 2)
    times that (2.392 for p = 24), at any τ."""
    C = flicker_covariance(np.array([0.0, tau]), np.array([tau, tau]))
    assert 0.5 * (C[0, 0] + C[1, 1] - 2 * C[0, 1]) == pytest.approx(FLICKER_FACTOR**2, rel=1e-12)
    p = 24
    v = centred_variance(flicker_covariance(np.arange(p) * tau, np.full(p, tau)))
    assert v.mean() / FLICKER_FACTOR**2 == pytest.approx(p * math.log(p) / (2 * (p - 1) * math.log(2)), rel=1e-9)


def test_flicker_covariance_matches_simulated_flicker_means():
    """24 poses of 5 s with 3 s of motion between: the scatter of the means of colored_noise's flicker about
    their average, over 300 seeds, against the closed form (measured within 3 %; the tolerance 8 % is 2.5 SE)."""
    rng = np.random.default_rng(42)
    ns, ng, p = int(DWELL * RATE), int(MOVE * RATE), 24
    starts = np.arange(p) * (ns + ng)
    y = np.stack([colored_noise(p * (ns + ng), RATE, rng, flicker=1.0, axes=1)[:, 0] for _ in range(300)])
    means = np.add.reduceat(y, np.ravel(np.column_stack([starts, starts + ns])), axis=1)[:, ::2] / ns
    measured = means.var(axis=1, ddof=1).mean()
    expected = centred_variance(flicker_covariance(starts / RATE, np.full(p, DWELL))).mean()
    print(f"scatter of 24 flicker means: simulated {measured:.4f}, closed form {expected:.4f}")
    assert measured == pytest.approx(expected, rel=0.08)


# -- the floor ---------------------------------------------------------------------------------------------------
def _recording(seed, white=0.0, flicker=0.0, poses=24, dwell=DWELL):
    """A simulated recording of the linear9 truth: ``poses`` orientations of scheme 24 held ``dwell`` s each with
    MOVE s between (the true output held there too: the intervals are given), noise of colored_noise added to
    the outputs (input-referred, times the scale factors). Returns the recording and its intervals."""
    rng = np.random.default_rng(seed)
    A = scheme("24", rng)[:poses]
    ns, ng = int(dwell * RATE), int(MOVE * RATE)
    n = poses * (ns + ng)
    K = np.abs(TRUTH[MODEL.groups()["scale"]])
    N = np.repeat(MODEL.forward(TRUTH, A)[0], ns + ng, axis=0)
    N = N + K * colored_noise(n, RATE, rng, white=white, flicker=flicker)
    rec = Recording(t=np.arange(n) / RATE, N=N, temp=None, units="g", rate=RATE, saturated=np.zeros(n, bool))
    start = np.arange(poses) * (ns + ng)
    return rec, np.column_stack([start, start + ns])


def test_the_floor_is_never_below_white_and_is_close_to_it_for_white_noise():
    """White noise, 24 poses of 20 s: the floor is never below σ/√n, N is read within 3 %, and the floor is
    1.30 times σ/√n on average over 20 seeds (1.00-1.84): the flicker level fitted to τ ≤ 5 s is zero ± its
    standard error, a positive estimate raises the floor and a negative one leaves it at σ/√n (docs/noise.md
    states this price of never understating flicker)."""
    ratios = []
    for seed in range(20):
        rec, iv = _recording(seed, white=100e-6, dwell=20.0)
        f = noise_floor(rec.N, iv, rec.t[iv[:, 0]], RATE, "g")
        assert f.estimator == "allan" and np.all(f.sem >= f.white)
        np.testing.assert_allclose(f.density, 100e-6, rtol=0.03)
        ratios.append(f.ratio)
    print("white noise: floor / (σ/√n) per seed", np.round(ratios, 3))
    assert 1.15 < np.mean(ratios) < 1.45 and min(ratios) >= 1.0


def test_the_floor_of_white_plus_flicker_is_the_scatter_of_the_means():
    """MEMS noise (white 100 µg/√Hz, B = 150 µg), 24 poses of 5 s: B is read within 25 % per axis (measured
    127-173 µg) and the floor is 3.91 times σ/√n, where the closed form with the true N and B gives 3.82
    (asserted: within 20 %)."""
    rec, iv = _recording(7, **MEMS)
    f = noise_floor(rec.N, iv, rec.t[iv[:, 0]], RATE, "g")
    print(f.describe())
    np.testing.assert_allclose(f.bias_instability, 150e-6, rtol=0.25)
    g = centred_variance(flicker_covariance(rec.t[iv[:, 0]], np.full(24, DWELL)))
    truth = np.sqrt(1e-8 / DWELL + 150e-6**2 * g)
    white = np.sqrt(1e-8 * RATE / (DWELL * RATE))
    assert math.sqrt(np.mean(truth**2)) / white == pytest.approx(3.82, abs=0.01)
    assert f.ratio == pytest.approx(3.82, rel=0.2)
    assert f.edf > 50  # B is well determined here: the F test is nearly the χ² test


def test_a_floor_like_another_keeps_its_model_for_trimmed_intervals():
    """A pose re-examined and trimmed keeps the recording's noise model (``like``): on the same intervals the
    floor is the full computation's to rounding; with three poses trimmed by 0.3 s it is within 5 % of the full
    computation on the trimmed intervals (the Allan fit over nearly the same samples)."""
    rec, iv = _recording(7, **MEMS)
    full = noise_floor(rec.N, iv, rec.t[iv[:, 0]], RATE, "g")
    same = noise_floor(rec.N, iv, rec.t[iv[:, 0]], RATE, "g", like=full)
    np.testing.assert_allclose(same.sem, full.sem, rtol=1e-12)
    assert same.edf == pytest.approx(full.edf, rel=1e-12)
    cut = iv.copy()
    cut[[2, 9, 17], 1] -= int(0.3 * RATE)
    again = noise_floor(rec.N, cut, rec.t[cut[:, 0]], RATE, "g")
    kept = noise_floor(rec.N, cut, rec.t[cut[:, 0]], RATE, "g", like=full)
    np.testing.assert_allclose(kept.sem, again.sem, rtol=0.05)
    assert kept.sem[2, 0] > full.sem[2, 0] * 0.99  # a shorter pose's mean is no better known


def test_short_or_single_intervals_fall_back_to_white_with_a_note_and_bad_intervals_are_refused():
    rec, iv = _recording(1, white=1e-4)
    f = noise_floor(rec.N, iv[:1], rec.t[iv[:1, 0]], RATE, "g")
    assert f.estimator == "white" and np.array_equal(f.sem, f.white) and "one position" in f.notes[0]
    short = np.column_stack([iv[:, 0], iv[:, 0] + 2])
    f = noise_floor(rec.N, short, rec.t[short[:, 0]], RATE, "g")
    assert f.estimator == "white" and "too few" in f.notes[0]
    with pytest.raises(InputError, match="`intervals`"):
        noise_floor(rec.N, np.array([[10, 10]]), np.zeros(1), RATE, "g")


def test_positions_from_a_recording_carry_the_floor_and_the_csv_its_se_columns(tmp_path):
    rec, iv = _recording(3, **MEMS)
    data = positions_from_recording(rec, given_intervals(rec, iv))
    f = data.extra["noise_floor"]
    assert data.sem is f.sem and np.array_equal(data.noise_of_mean(), f.sem)
    np.testing.assert_allclose(f.white, data.std / np.sqrt(data.n_samples)[:, None], rtol=1e-9)
    path = tmp_path / "p.csv"
    data.to_csv(path)
    assert "se_x,se_y,se_z" in path.read_text().splitlines()[0]
    back = read_positions(path)
    np.testing.assert_allclose(back.sem, data.sem, rtol=1e-15)
    cal = calibrate(data, MODEL)
    assert cal.fit.noise_source == "measured" and cal.fit.estimator == "allan" and cal.fit.floor_dof > 0
    assert cal.fit.noise_g / cal.fit.white_noise_g == pytest.approx(f.ratio, rel=0.1)
    line = cal.fit.describe()
    assert line.startswith(f"noise floor {cal.fit.noise_g * 1e6:.4g} µg RMS (each mean's SD with the sensor's "
                           "correlated noise (Allan model")
    assert f"σ/√n alone {cal.fit.white_noise_g * 1e6:.4g} µg" in line
    assert f"effective dof and the floor's {cal.fit.floor_dof:.3g}: p = {cal.fit.p_value:.2g}" in line
    assert f.describe().startswith(f"noise floor of a position {math.sqrt(np.mean(f.sem**2)):.4g} g RMS (Allan")
    # the file's se columns are the floor too (stated: no degrees of freedom known, the χ² test)
    fb = calibrate(back, MODEL).fit
    assert fb.estimator == "stated" and fb.floor_dof is None and fb.chi2 == pytest.approx(cal.fit.chi2, rel=1e-6)
    d = cal.to_dict()
    assert d["n_positions"] == 24 and f.to_dict()["estimator"] == "allan"


# -- the false-alarm rate ------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_chi2_test_keeps_its_false_alarm_rate_with_the_new_floor_and_not_with_sigma_over_root_n():
    """300 simulated recordings of the true linear9 model (24 poses of 5 s, 3 s of motion between, MEMS white +
    flicker noise), calibrated through positions_from_recording and optcal.app.fit.calibrate: at α = 5 % the test
    against the new floor (χ² judged by its moments under the floor's correlated noise and the floor's degrees
    of freedom) rejects at most 21 of 300 (5 % plus the one-sided 95 % binomial tolerance
    1.645·√(0.05·0.95/300) = 2.1 %; measured 12); against σ/√n (the χ² test) at least 250 of 300 (measured 300)."""
    new, old = [], []
    for seed in range(300):
        rec, iv = _recording(seed, **MEMS)
        data = positions_from_recording(rec, given_intervals(rec, iv))
        cal = calibrate(data, MODEL)
        new.append(cal.fit.p_value)
        old.append(goodness_of_fit(CalibrationProblem(MODEL, replace(data, sem=None)), cal.x).p_value)
    new, old = np.array(new), np.array(old)
    print(f"rejections at 5 %: new floor {int((new < 0.05).sum())}/300, σ/√n {int((old < 0.05).sum())}/300")
    assert (new < 0.05).sum() <= 21
    assert (old < 0.05).sum() >= 250


# -- the Xsens MTi recording of imu_tk -------------------------------------------------------------------------------
XSENS = corpus_root() / "imu_tk" / "xsens_acc.mat.gz"  # the real corpus (tests/corpus.py)


def test_xsens_residual_is_at_its_new_noise_floor(tmp_path, corpus):
    """imu_tk's Xsens MTi (linear9, |g| = 9.81744 m/s²): against σ/√n (33 µg) the residual (99 µg) is 3 times the
    floor and χ² rejects at p ~ 1e-100; the new floor (116 µg: the z axis's σ_A flattens at 0.55 counts from
    τ = 0.6 s) makes residual / floor 0.85 and p = 0.21 (docs/noise.md). Asserted: residual / old floor 2-4,
    residual / new floor 0.6-1.3, the new p-value above 0.01 and the old one below 1e-20."""
    from optcal.app.workflows.recording import choose_threshold

    path = tmp_path / "xsens_acc.mat"
    path.write_bytes(gzip.decompress(XSENS.read_bytes()))
    rec = read_recording(path, units="counts", saturation=65535)
    g = 9.81744 / 9.80665
    data = positions_from_recording(rec, choose_threshold(rec, "linear9", g_local=g))
    cal = calibrate(data, "linear9", g_local=g)
    old = goodness_of_fit(CalibrationProblem("linear9", replace(data, sem=None), g_local=g), cal.x)
    print(f"Xsens: {len(data)} positions, residual {cal.fit.rms_g * 1e6:.1f} µg, floor σ/√n {old.noise_g * 1e6:.1f} µg "
          f"(p = {old.p_value:.2g}), new {cal.fit.noise_g * 1e6:.1f} µg (p = {cal.fit.p_value:.2g}, "
          f"ν = {cal.fit.floor_dof:.3g}); {data.extra['noise_floor'].describe()}")
    assert 2.0 < cal.fit.rms_g / old.noise_g < 4.0
    assert 0.6 < cal.fit.rms_g / cal.fit.noise_g < 1.3
    assert cal.fit.p_value > 0.01 and old.p_value < 1e-20
