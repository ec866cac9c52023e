"""Simulated hand-held IMU recordings with known rests, for measuring rest detection (issue #29, item 8):
an accelerometer and a gyroscope sampled at the same times, following one attitude trajectory, with the hard
cases of hand-held logs:

- **turns** about a body axis (mostly tilting gravity) at a peak rate of 60-180 °/s, with a smooth rate
  profile (raised cosine) or a **slow start** (the rate ramps up from 0 over 0.5-1 s, the start of a motion
  that a change-point segment may share with the rest before it);
- **settling** at the start of a pose: a decaying oscillation of a fraction of a degree (0.2-0.8° at its
  peak, 1.5-4 Hz) over 0.3-1 s;
- **tremor** during holds: 8-12 Hz, a rotation at up to about 1 °/s (a few hundredths of a degree) and a
  linear acceleration of a couple of milli-g, at a level drawn per pose, none where the sensor was set down;
- **re-seats**: short rests back to back, the attitude stepping by 5-30° either by a short fast motion
  (0.05-0.15 s) or with no motion at all (the attitude jumps between two samples: the gyroscope sees
  nothing, as when logging pauses while the sensor is re-seated);
- poses held 1-5 s.

The accelerometer measures gravity in the body frame (+1 g up when still), the centripetal and tangential
acceleration of a lever arm (:data:`LEVER_M`) during turns and the tremor's linear acceleration; the gyroscope
measures the body rate of the same attitude trajectory. Each sensor is diagonal (a scale and an offset per
axis) with white noise; the gyroscope's bias drifts linearly through the recording. Every draw comes from the
``rng`` given.

**Truth.** A sample is at rest when the sensor, tremor aside, is not rotating: its attitude is within
:data:`TRUE_REST_DEG` (0.1°, under any accelerometer's noise) of its pose's. Every sample of a hold is at
rest (its rate is zero but for the tremor, whose angle stays within a few hundredths of a degree); a turn or a
re-seat is moving from the sample where it has turned by more than that to the one where it is within that
of its end; a settling is moving while the envelope of its angle, which rises once and falls once, is above
that. The true rests are the runs of samples at rest that hold a hold, [start, end) samples; two holds joined
by a re-seat without motion are two rests.

A top-level core module like :mod:`optcal.core.synthetic_recording`; it returns two
:class:`~optcal.core.recording.reading.Recording` objects (the gyroscope's ``N`` holds its rates in °/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.recording.reading import Recording

TRUE_REST_DEG = 0.1  # °: a sample is at rest within this of its pose's attitude (tremor stays within it)
SETTLE_DECAY = 1 / 3  # a settling's decay time, as a fraction of its length
# the largest value of e^(−x/SETTLE_DECAY)·sin²(πx) on [0, 1] (at tan(πx) = 2π·SETTLE_DECAY): a settling's
# angle is scaled by its inverse so that its envelope peaks at the amplitude drawn
_X = np.arctan(2 * np.pi * SETTLE_DECAY) / np.pi
SETTLE_PEAK = float(np.exp(-_X / SETTLE_DECAY) * np.sin(np.pi * _X) ** 2)
LEVER_M = 0.02  # m: the sensor's distance from the centre of the hand's turns (centripetal, tangential)
G0 = 9.80665  # m/s² per g


@dataclass
class SyntheticIMU:
    """A simulated IMU recording and its truth."""

    acc: Recording  # outputs in g (diagonal scale and offset applied)
    gyro: Recording  # rates in °/s (diagonal scale and offset applied), same times
    still: np.ndarray  # (n,) bool: at rest (module docstring, "Truth")
    rests: np.ndarray  # (k, 2) int [start, end): the true rests, one per hold (back-to-back holds stay apart)
    rate_dps: np.ndarray  # (n, 3) true body rate, °/s
    gravity: np.ndarray  # (n, 3) true gravity direction in the body frame (unit vectors; tremor included)
    steps: np.ndarray  # (s,) int: samples at which the attitude jumps with no motion (a re-seat, logging paused)
    acc_scale: np.ndarray  # (3,) accelerometer output per g
    acc_offset: np.ndarray  # (3,) g
    gyro_scale: np.ndarray  # (3,) gyroscope output per °/s
    gyro_bias: np.ndarray  # (n, 3) °/s of output (the offset, drifting linearly)
    kinds: list  # the phases in order: (kind, start, end) with kind hold, turn, ramp, reseat, settle


def _rodrigues(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices (m, 3, 3) by ``angle`` (m,) rad about unit ``axis`` (m, 3)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    C = 1.0 - c
    return np.stack([
        np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
        np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
        np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1)], -2)


def _exp(v: np.ndarray) -> np.ndarray:
    """Rotation matrices (m, 3, 3) of rotation vectors ``v`` (m, 3) rad."""
    th = np.linalg.norm(v, axis=1)
    safe = np.where(th > 0, th, 1.0)
    return _rodrigues(np.where(th[:, None] > 0, v / safe[:, None], [1.0, 0.0, 0.0]), th)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = _unit(rng.standard_normal(4))
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _tilt_axis(rng: np.random.Generator, g_body: np.ndarray, yaw: float) -> np.ndarray:
    """A body axis mostly perpendicular to gravity (a turn that tilts it), with a share ``yaw`` along it."""
    a = _unit(np.cross(g_body, rng.standard_normal(3)))
    return _unit(a + yaw * rng.standard_normal() * g_body)


def _profiles(kind, tau, T, Ta, peak, amp, freq, decay):
    """Angle (rad) and rate (rad/s) of each sample's phase at time ``tau`` into it (all arrays, per sample).
    turn: raised cosine up for Ta, down for T − Ta; ramp: linear up for Ta, raised cosine down; settle: a
    decaying oscillation of amplitude scale ``amp`` in a sin² window, angle and rate zero at both ends."""
    up = tau < Ta
    Td = np.maximum(T - Ta, 1e-12)
    Ta_ = np.maximum(Ta, 1e-12)
    # rising half (turn: raised cosine; ramp: linear)
    ang_up_turn = peak * (tau / 2 - Ta_ / (2 * np.pi) * np.sin(np.pi * tau / Ta_))
    rate_up_turn = peak * np.sin(np.pi * tau / (2 * Ta_)) ** 2
    ang_up_ramp = peak * tau ** 2 / (2 * Ta_)
    rate_up_ramp = peak * tau / Ta_
    u = tau - Ta
    ang_down = peak * Ta / 2 + peak * (u / 2 + Td / (2 * np.pi) * np.sin(np.pi * u / Td))
    rate_down = peak * np.cos(np.pi * u / (2 * Td)) ** 2
    ramp = kind == 2
    ang = np.where(up, np.where(ramp, ang_up_ramp, ang_up_turn), ang_down)
    rate = np.where(up, np.where(ramp, rate_up_ramp, rate_up_turn), rate_down)
    # settling: amp·e^(−τ/decay)·sin(2πfτ)·sin²(πτ/T): angle and rate 0 at both ends
    Ts = np.maximum(T, 1e-12)
    e = np.exp(-tau / np.maximum(decay, 1e-12))
    s, c = np.sin(2 * np.pi * freq * tau), np.cos(2 * np.pi * freq * tau)
    w = np.sin(np.pi * tau / Ts) ** 2
    dw = np.pi / Ts * np.sin(2 * np.pi * tau / Ts)
    ang_s = amp * e * s * w
    rate_s = amp * e * (-s * w / np.maximum(decay, 1e-12) + 2 * np.pi * freq * c * w + s * dw)
    settle = kind == 4
    ang = np.where(settle, ang_s, ang)
    rate = np.where(settle, rate_s, rate)
    hold = kind == 0
    return np.where(hold, 0.0, ang), np.where(hold, 0.0, rate)


def handheld_imu(rng: np.random.Generator, *, n_poses: int = 20, rate: float = 100.0,
                 hold_s=(1.0, 5.0), first_hold_s: float = 5.0, turn_dps=(60.0, 180.0),
                 turn_deg=(40.0, 150.0), p_ramp: float = 0.3, ramp_s=(0.5, 1.0), p_reseat: float = 0.25,
                 p_reseat_still: float = 0.5, reseat_deg=(5.0, 30.0), reseat_s=(0.05, 0.15),
                 p_settle: float = 0.7, settle_s=(0.3, 1.0), settle_deg=(0.2, 0.8), settle_hz=(1.5, 4.0),
                 tremor_hz=(8.0, 12.0), tremor_g: float = 2e-3, tremor_dps: float = 1.0, p_table: float = 0.3,
                 acc_noise_g: float = 3e-3, gyro_noise_dps: float = 0.1, gyro_drift_dps: float = 0.05,
                 lever_m: float = LEVER_M, yaw: float = 0.3) -> SyntheticIMU:
    """A hand-held recording of ``n_poses`` poses (module docstring). Ranges are (low, high) and drawn
    uniformly per pose: ``hold_s`` the true rest of each pose after the first (``first_hold_s``);
    ``turn_dps`` peak rate and ``turn_deg`` angle of a turn, with probability ``p_ramp`` a slow start
    (``ramp_s`` long); with probability ``p_reseat`` a pose is reached by a re-seat (``reseat_deg``) instead of a
    turn, without any motion with probability ``p_reseat_still``, else in ``reseat_s``; with probability
    ``p_settle`` a turned-to pose starts with a settling (``settle_s`` long, ``settle_deg`` amplitude,
    ``settle_hz``). Tremor: ``tremor_hz``, ``tremor_g`` linear (g), ``tremor_dps`` largest rate (°/s), at a
    level drawn per pose from 0.3-1 of these, none with probability ``p_table`` (set down). White noise SD per
    sample: ``acc_noise_g`` (g), ``gyro_noise_dps`` (°/s); the gyroscope's bias drifts by ``gyro_drift_dps``
    (°/s) from start to end. ``lever_m``: the sensor's distance from the centre of the turns. ``yaw``: the
    share of a turn's axis along gravity (0: pure tilts)."""
    if not (rate > 0 and n_poses >= 1):
        raise InputError("`rate` must be positive and `n_poses` at least 1")
    dt = 1.0 / rate
    R0 = _random_rotation(rng)
    up = np.array([0.0, 0.0, 1.0])
    # phases: (kind, samples, axis, peak rad/s, Ta s, amplitude rad, freq Hz, decay s); kinds: 0 hold,
    # 1 turn, 2 ramp, 3 re-seat in motion, 4 settle; a re-seat without motion is a step between two samples
    phases, starts, steps_at = [], [], []
    R = R0.copy()
    pos = 0

    def samples(seconds):
        return max(2, int(round(seconds * rate)))

    def add(kind, m, axis=None, peak=0.0, Ta=0.0, amp=0.0, freq=0.0, decay=1.0, angle=0.0):
        nonlocal pos, R
        axis = np.zeros(3) if axis is None else axis
        phases.append((kind, m, axis, peak, Ta, amp, freq, decay))
        starts.append(R.copy())  # the attitude at the phase's start (after any step before it)
        pos += m
        if kind in (1, 2, 3):  # the attitude at the phase's end
            R = R @ _rodrigues(axis[None], np.array([angle]))[0]

    add(0, samples(first_hold_s))
    for _ in range(1, n_poses):
        g_body = R.T @ up
        settle = False
        if rng.random() < p_reseat:
            axis = _tilt_axis(rng, g_body, 0.0)
            ang = np.radians(rng.uniform(*reseat_deg))
            if rng.random() < p_reseat_still:
                R = R @ _rodrigues(axis[None], np.array([ang]))[0]
                steps_at.append(pos)
            else:
                m = samples(rng.uniform(*reseat_s))
                add(3, m, axis, 2 * ang / (m * dt), m * dt / 2, angle=ang)
        else:
            axis = _tilt_axis(rng, g_body, yaw)
            peak = np.radians(rng.uniform(*turn_dps))
            ang = np.radians(rng.uniform(*turn_deg))
            if rng.random() < p_ramp:
                Ta = rng.uniform(*ramp_s)
                m = samples(max(2 * ang / peak, Ta + 0.2))
                T = m * dt
                add(2, m, axis, 2 * ang / T, Ta, angle=ang)
            else:
                m = samples(2 * ang / peak)
                T = m * dt
                add(1, m, axis, 2 * ang / T, T / 2, angle=ang)
            settle = rng.random() < p_settle
        if settle:
            m = samples(rng.uniform(*settle_s))
            add(4, m, _unit(rng.standard_normal(3)), amp=np.radians(rng.uniform(*settle_deg)) / SETTLE_PEAK,
                freq=rng.uniform(*settle_hz), decay=m * dt * SETTLE_DECAY)
        add(0, samples(rng.uniform(*hold_s)))
    n = pos
    kind = np.array([p[0] for p in phases])
    length = np.array([p[1] for p in phases])
    start = np.concatenate([[0], np.cumsum(length)[:-1]])
    idx = np.repeat(np.arange(len(phases)), length)
    tau = (np.arange(n) - start[idx]) * dt
    axes = np.array([p[2] for p in phases])
    peak, Ta, amp, freq, decay = (np.array([p[i] for p in phases], float) for i in range(3, 8))
    T = length * dt
    k = kind[idx]
    ang, rate_rad = _profiles(k, tau, T[idx], Ta[idx], peak[idx], amp[idx], freq[idx], decay[idx])
    Rs = np.array(starts)
    Rt = Rs[idx] @ _rodrigues(axes[idx], ang)
    w_traj = axes[idx] * rate_rad[:, None]  # body rate of a rotation about a body-fixed axis
    # tremor: three sinusoids per component (rotation vector and linear acceleration), 8-12 Hz
    t = np.arange(n) * dt
    # a hand's tremor, at a level drawn per pose (the hold and the motion into it); none where the sensor
    # was set down on a table
    pose = np.cumsum(kind == 0) - (kind == 0)
    level = np.where(rng.random(n_poses) < p_table, 0.0, rng.uniform(0.3, 1.0, n_poses))[pose][idx]
    f_rot = rng.uniform(*tremor_hz, size=(3, 3))
    ph_rot = rng.uniform(0, 2 * np.pi, size=(3, 3))
    a_rot = np.radians(tremor_dps) / (3 * np.sqrt(3) * 2 * np.pi * f_rot)  # |δ'| ≤ tremor_dps
    arg = 2 * np.pi * f_rot[None] * t[:, None, None] + ph_rot[None]
    delta = level[:, None] * np.sum(a_rot[None] * np.sin(arg), axis=2)  # (n, 3) rad
    ddelta = level[:, None] * np.sum(a_rot[None] * 2 * np.pi * f_rot[None] * np.cos(arg), axis=2)
    f_lin = rng.uniform(*tremor_hz, size=(3, 3))
    ph_lin = rng.uniform(0, 2 * np.pi, size=(3, 3))
    lin = level[:, None] * np.sum(tremor_g / 3 * np.sin(2 * np.pi * f_lin[None] * t[:, None, None] + ph_lin[None]),
                                  axis=2)
    E = _exp(delta)
    Rtot = Rt @ E
    w = np.einsum("nji,nj->ni", E, w_traj) + ddelta  # Exp(δ)ᵀ ω_traj + δ' (δ tiny)
    g_body = np.einsum("nji,j->ni", Rtot, up)
    # lever arm: the sensor at r from the centre of the turn, r along a fixed body direction
    r = _unit(rng.standard_normal(3)) * lever_m
    alpha = np.gradient(w, dt, axis=0)
    lever = (np.cross(w, np.cross(w, r)) + np.cross(alpha, r)) / G0
    f = g_body + lever + lin
    # sensors
    acc_scale = 1 + rng.uniform(-0.02, 0.02, 3)
    acc_offset = rng.uniform(-0.05, 0.05, 3)
    gyro_scale = 1 + rng.uniform(-0.03, 0.03, 3)
    b0 = rng.uniform(-2.0, 2.0, 3)
    drift = _unit(rng.standard_normal(3)) * gyro_drift_dps
    gyro_bias = b0 + np.outer(t / max(t[-1], dt), drift)
    w_dps = np.degrees(w)
    N_acc = acc_scale * (f + acc_noise_g * rng.standard_normal((n, 3))) + acc_offset
    N_gyro = gyro_scale * (w_dps + gyro_noise_dps * rng.standard_normal((n, 3))) + gyro_bias
    sat = np.zeros(n, bool)
    acc = Recording(t.copy(), N_acc, None, "g", float(rate), sat, "simulated hand-held IMU (accelerometer)")
    gyro = Recording(t.copy(), N_gyro, None, "deg/s", float(rate), sat.copy(),
                     "simulated hand-held IMU (gyroscope)")
    # truth: the attitude (tremor aside) within TRUE_REST_DEG of the nearer pose's; a settling by the bound
    # amp·e^(−τ/decay)·sin²(πτ/T) of its angle, which rises once and falls once
    full = (peak * T / 2)[idx]  # a turn's angle
    dist = np.where(k == 4, amp[idx] * np.exp(-tau / decay[idx]) * np.sin(np.pi * tau / T[idx]) ** 2,
                    np.minimum(np.abs(ang), np.abs(full - ang)))
    still = np.degrees(np.where(k == 0, 0.0, dist)) <= TRUE_REST_DEG
    # the true rests: runs at rest that hold a hold, cut where the attitude steps
    m = np.concatenate([[False], still, [False]])
    edges = np.flatnonzero(m[1:] != m[:-1])
    steps = np.asarray(steps_at, np.int64)
    bounds = np.unique(np.concatenate([edges, steps]))
    cut = np.column_stack([bounds[:-1], bounds[1:]])
    c = np.concatenate([[0], np.cumsum(k == 0)])
    rests = cut[still[np.minimum(cut[:, 0], n - 1)] & (c[cut[:, 1]] > c[cut[:, 0]])].astype(np.int64)
    kinds = [(("hold", "turn", "ramp", "reseat", "settle")[kd], int(s), int(s + m))
             for kd, s, m in zip(kind, start, length)]
    return SyntheticIMU(acc, gyro, still, rests, w_dps, g_body, steps, acc_scale,
                        acc_offset, gyro_scale, gyro_bias, kinds)
