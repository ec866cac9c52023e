"""optcal.core.recording.attitude: the gyroscope's scale bounded by the accelerometer's turns, and the slow motions
inside still runs that the detection leaves out of its rests (issue #29; docs/segmentation.md)."""

import numpy as np
import pytest

import optcal.core.recording.attitude as attitude
import optcal.core.recording.segment as segment
from optcal.core.recording import segment_static
from optcal.core.recording.reading import Recording
from optcal.core.synthetic_imu import handheld_imu

RATE = 100.0
HOLD, TURN = 500, 100  # samples
SAG_START = 2 * (HOLD + TURN) + 200  # 2 s into the third hold


def _sag_recording(rng, sag_dps, sag_s=1.5):
    """Six holds of 5 s about x, 90° turns of 1 s between them (raised-cosine rate, 141 °/s at the peak); in the
    third hold the sensor sags at ``sag_dps`` for ``sag_s`` (below the turn threshold, about 0.7 °/s here). The
    accelerometer in g (1 mg noise), the gyroscope in °/s (0.05 °/s noise, a bias); the true attitude (°)."""
    rates = []
    for k in range(6):
        r = np.zeros(HOLD)
        if k == 2:
            r[200:200 + int(sag_s * RATE)] = sag_dps
        rates.append(r)
        if k < 5:
            x = (np.arange(TURN) + 0.5) / TURN
            rates.append(90.0 * RATE / TURN * (1 - np.cos(2 * np.pi * x)))
    w = np.concatenate(rates)
    theta = np.cumsum(w) / RATE
    n = len(w)
    th = np.radians(theta)
    A = np.column_stack([np.zeros(n), np.sin(th), np.cos(th)]) + 1e-3 * rng.standard_normal((n, 3))
    W = np.column_stack([w, np.zeros(n), np.zeros(n)]) + 0.05 * rng.standard_normal((n, 3)) + [0.3, -0.2, 0.1]
    return Recording(np.arange(n) / RATE, A, None, "g", RATE, np.zeros(n, bool)), W, theta


def _spans(intervals, theta):
    """The true attitude's range (°) over each kept interval."""
    return np.array([np.ptp(theta[a:b]) for a, b in intervals])


def test_a_slow_sag_is_left_out_of_the_rest(monkeypatch):
    """A 0.6° sag at 0.4 °/s inside a hold, under the gyroscope's turn threshold: no kept interval spans more than
    a quarter of SLOW_DEG of attitude (0.04° measured: the sag's first and last samples), and the hold's still
    parts on either side are kept. Without the rule (SLOW_DEG out of reach) a kept interval holds 0.24° of the
    sag (the accelerometer and the rate threshold see the rest of it)."""
    acc, W, theta = _sag_recording(np.random.default_rng(0), 0.4)
    det = segment_static(acc, gyro=W)
    assert _spans(det.intervals, theta).max() < attitude.SLOW_DEG / 4
    inside = det.intervals[(det.intervals[:, 0] >= SAG_START - 200) & (det.intervals[:, 1] <= SAG_START + 350)]
    assert len(inside) == 2  # before and after the sag
    slow = attitude.SLOW_DEG
    monkeypatch.setattr(attitude, "SLOW_DEG", 1e9)
    assert _spans(segment_static(acc, gyro=W).intervals, theta).max() > slow


def test_a_wobble_within_a_tenth_of_a_degree_stays_a_rest():
    """A sag of 0.1° (0.1 °/s for 1 s) is a hand's wobble: the hold stays one rest."""
    acc, W, theta = _sag_recording(np.random.default_rng(1), 0.1, sag_s=1.0)
    det = segment_static(acc, gyro=W)
    assert len(det.intervals) == 6
    assert np.all(_spans(det.intervals, theta)[[0, 1, 3, 4, 5]] < 0.01)
    assert _spans(det.intervals, theta)[2] == pytest.approx(0.1, abs=0.005)


def _shaking_third_hold(seed, acc_g, on):
    """The sag recording without a sag, its third hold shaken (white vibration of ``acc_g`` on the accelerometer
    and 0.5 °/s on the gyroscope, where ``on`` (HOLD, 1) is 1): the recording, the rates, and a function giving a
    detection's intervals that reach into that hold."""
    rng = np.random.default_rng(seed)
    acc, W, _ = _sag_recording(rng, 0.0)
    third = slice(2 * (HOLD + TURN), 2 * (HOLD + TURN) + HOLD)
    A = acc.N.copy()
    A[third] += acc_g * rng.standard_normal((HOLD, 3)) * on
    W[third] += 0.5 * rng.standard_normal((HOLD, 3)) * on

    def inside(det):
        iv = det.intervals
        return iv[(iv[:, 1] > third.start) & (iv[:, 0] < third.stop)]

    return Recording(acc.t, A, None, "g", RATE, acc.saturated), W, inside


@pytest.mark.parametrize("seed", range(4))
def test_a_shaking_hold_the_gyroscope_sees_still_is_a_rest(seed, monkeypatch):
    """The third hold shakes (6 mg of white vibration on the accelerometer, six times its noise; 0.5 °/s on the
    gyroscope, which averages out over its 0.25-s window): step 4a calls its segments shaking, and the
    accelerometer alone keeps nothing of it. With the gyroscope, a shaking segment it sees still throughout and
    lasting two shortest poses is a rest: one interval of at least 1 s inside the hold (1.3-3.8 s measured),
    none without that rule."""
    shaking, W, inside = _shaking_third_hold(seed, 0.006, np.ones((HOLD, 1)))
    kept = inside(segment_static(shaking, gyro=W))
    assert len(kept) == 1 and kept[0, 1] - kept[0, 0] >= RATE
    assert len(inside(segment_static(shaking, gyro=False))) == 0
    monkeypatch.setattr(segment, "SHAKING_HOLD_POSES", 10**6)
    assert len(inside(segment_static(shaking, gyro=W))) == 0


@pytest.mark.parametrize("seed", range(4))
def test_a_hold_that_vibrates_in_bursts_is_a_rest(seed, monkeypatch):
    """The third hold vibrates in bursts (8 mg and 0.5 °/s, 0.3 s on, 0.3 s off): step 7 cuts it into loud pieces
    and quiet ones, each shorter than a pose. The gyroscope sees them still throughout: together, lasting two
    shortest poses, they are one rest (1.3-3.1 s of the 5-s hold measured); without that rule none is kept."""
    burst = (np.floor(np.arange(HOLD) / RATE / 0.3) % 2 == 0)[:, None]
    shaking, W, inside = _shaking_third_hold(seed, 0.008, burst)
    kept = inside(segment_static(shaking, gyro=W))
    assert len(kept) == 1 and kept[0, 1] - kept[0, 0] >= RATE
    monkeypatch.setattr(segment, "_vibrating_holds", lambda seg, reason, still: (seg, reason))
    assert len(inside(segment_static(shaking, gyro=W))) == 0


@pytest.mark.parametrize("seed", range(8))
def test_scale_bound_is_the_gyroscopes_scale_within_a_few_percent(seed):
    """On simulated hand-held recordings (turns of 60-180 °/s about body axes, tremor, settling; each sensor's axes
    2-4 % apart in scale), the bound from the true rests lies within the gyroscope's axes' scales (output units per
    rad/s) widened by the accelerometer's own scale errors: 0.97 × the least to 1.05 × the largest."""
    s = handheld_imu(np.random.default_rng(seed), p_reseat=0.0)
    X = s.gyro.N - s.gyro_bias
    A = np.array([s.acc.N[a:b].mean(axis=0) - s.acc_offset for a, b in s.rests])
    K = attitude.scale_bound(X, A, s.rests, ~s.still, s.acc.rate)
    scale = s.gyro_scale * 180.0 / np.pi
    assert 0.97 * scale.min() <= K <= 1.05 * scale.max(), (K, scale)


@pytest.mark.parametrize("seed", range(8))
def test_gyro_scale_is_the_gyroscopes_scale_within_its_axes_spread(seed):
    """The fitted scale (the one K under which the motions carry each rest's gravity onto the next's) lies within
    the gyroscope's axes' scales widened by 1 % (the accelerometer's scale errors tilt the gravity directions),
    inside the bound's wider 0.97-1.05."""
    s = handheld_imu(np.random.default_rng(seed), p_reseat=0.0)
    X = s.gyro.N - s.gyro_bias
    A = np.array([s.acc.N[a:b].mean(axis=0) - s.acc_offset for a, b in s.rests])
    K = attitude.gyro_scale(X, X, A, s.rests, ~s.still, s.acc.rate)
    scale = s.gyro_scale * 180.0 / np.pi
    assert 0.99 * scale.min() <= K <= 1.01 * scale.max(), (K, scale)


def _tilted_turns(rng, tilt_deg):
    """Rests joined by 90° turns about axes ``tilt_deg`` from gravity (in the body frame, gravity's direction at
    the rest leaning by the tilt toward a perpendicular that alternates): gravity's direction turns by
    2·asin(sin(tilt)·sin(45°)), far less than the sensor, so the bound ∫|W| dt / θ lies well above K. Rates in
    output units of 100 per rad/s."""
    hold, turn = 100, 100
    R = np.eye(3)
    W, rests, A, t0 = [], [], [], 0
    for k in range(8):
        rests.append([t0, t0 + hold])
        A.append(R.T @ np.array([0.0, 0.0, 1.0]))
        W.append(np.zeros((hold, 3)))
        t0 += hold
        lean = np.radians(tilt_deg)
        u = A[-1]
        p = np.cross(u, [1.0, 0.0, 0.0] if k % 2 else [0.0, 1.0, 0.0])
        axis = np.cos(lean) * u + np.sin(lean) * p / np.linalg.norm(p)
        w = np.outer(np.full(turn, (np.pi / 2) * RATE / turn), axis)  # rad/s, body frame
        for wi in w:  # the body turns by wi/RATE about its own axis
            v = wi / RATE
            a = np.linalg.norm(v)
            Kx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / a
            R = R @ (np.eye(3) + np.sin(a) * Kx + (1 - np.cos(a)) * Kx @ Kx)
        W.append(100.0 * w + 0.01 * rng.standard_normal((turn, 3)))
        t0 += turn
    rests.append([t0, t0 + hold])
    A.append(R.T @ np.array([0.0, 0.0, 1.0]))
    W.append(np.zeros((hold, 3)))
    X = np.vstack(W)
    turning = np.linalg.norm(X, axis=1) > 1.0
    return X, np.array(A), np.array(rests), turning


def test_gyro_scale_where_the_turns_are_not_across_gravity():
    """Turns of 90° about axes 50° from gravity turn gravity by 65.6°: the bound is 1.37 times K, the fit K
    within 0.5 %."""
    X, A, rests, turning = _tilted_turns(np.random.default_rng(3), 50.0)
    bound = attitude.scale_bound(X, A, rests, turning, RATE)
    assert bound == pytest.approx(100.0 * 90.0 / 65.6, rel=0.01)
    assert attitude.gyro_scale(X, X, A, rests, turning, RATE) == pytest.approx(100.0, rel=5e-3)


def test_gyro_scale_falls_back_to_the_bound_when_the_rotations_do_not_carry_gravity():
    """A gyroscope whose rates are not the rotations the accelerometer saw (its axes swapped: the turns about x
    read about z, which does not move gravity) is not fitted: the scale is the bound."""
    X, A, rests, turning = _tilted_turns(np.random.default_rng(4), 50.0)
    X = X[:, [2, 0, 1]]
    assert attitude.gyro_scale(X, X, A, rests, turning, RATE) == attitude.scale_bound(X, A, rests, turning, RATE)


def test_scale_bound_leaves_out_joins_the_gyroscope_did_not_see():
    """Rests joined without a motion (the gravity direction jumps, no turning sample between them) bound nothing;
    without any turn it is NaN."""
    X = np.zeros((400, 3))
    A = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    rests = np.array([[0, 100], [100, 200], [200, 400]])
    assert np.isnan(attitude.scale_bound(X, A, rests, np.zeros(400, bool), RATE))
    X[150:250, 0] = 90.0  # a turn of 90° at 90 units per ... between the second and the third rest's middles
    turning = np.zeros(400, bool)
    turning[150:250] = True
    K = attitude.scale_bound(X, A, rests, turning, RATE)
    assert K == pytest.approx(90.0 / (np.pi / 2))
