"""Simulated raw recordings with known poses, for measuring static-interval detection (docs/segmentation.md):
poses held for given durations, joined by rotations at a given rate (spherical linear interpolation of the
gravity direction) or by instantaneous steps, a diagonal sensor (scale and offset per axis), white and
flicker noise (:func:`optcal.core.noise.colored.colored_noise`), optional clipping at a range and dropped (NaN)
samples; and slow continuous tumbles with no true rest, with or without pauses. Every draw comes from the
``rng`` given. The true rests are returned as [start, end) sample indices; their precision and recall is
:func:`optcal.core.recording.segment.interval_scores`. A top-level core module rather than part of
``optcal.core.recording``: it draws its noise with :mod:`optcal.noise`, which reads recordings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.noise.colored import colored_noise
from optcal.core.recording.reading import Recording

SCALE = np.array([1.012, 0.991, 1.004])  # output per g of the simulated sensor (diagonal)
OFFSET = np.array([0.021, -0.013, 0.034])  # g


@dataclass
class Synthetic:
    """A simulated recording and its truth: the true rests [start, end) and each one's gravity direction."""

    recording: Recording
    rests: np.ndarray  # (k, 2) int, end exclusive
    directions: np.ndarray  # (k, 3) unit vectors in the sensor frame


def arc(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """``n`` unit vectors from ``a`` to ``b`` along the great circle (slerp), ends excluded; an antipodal
    pair turns through a perpendicular."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    c = float(np.clip(a @ b, -1.0, 1.0))
    if c < -1 + 1e-9:
        p = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        p /= np.linalg.norm(p)
        return np.concatenate([arc(a, p, n // 2 + 1)[: n // 2], arc(p, b, n - n // 2)])
    th = np.arccos(c)
    s = (np.arange(1, n + 1) / (n + 1))[:, None]
    if th < 1e-9:
        return np.repeat(a[None], n, 0)
    return (np.sin((1 - s) * th) * a + np.sin(s * th) * b) / np.sin(th)


def random_directions(rng: np.random.Generator, k: int, min_angle_deg: float = 20.0) -> np.ndarray:
    """``k`` random unit vectors, each at least ``min_angle_deg`` from the one before (consecutive poses must
    differ for a step between them to exist)."""
    out = [rng.standard_normal(3)]
    out[0] /= np.linalg.norm(out[0])
    while len(out) < k:
        v = rng.standard_normal(3)
        v /= np.linalg.norm(v)
        if np.degrees(np.arccos(np.clip(v @ out[-1], -1, 1))) >= min_angle_deg:
            out.append(v)
    return np.array(out)


def _sensor(rng, A, rate, noise_g, flicker_g, clip_g, drop_fraction, path):
    """Outputs of the simulated sensor for true specific forces ``A`` (g), and the Recording."""
    n = len(A)
    noise = colored_noise(n, rate, rng, white=noise_g / np.sqrt(rate), flicker=flicker_g)
    N = (A + noise) * SCALE + OFFSET
    sat = np.zeros(n, bool)
    if clip_g is not None:
        sat = (np.abs(N) >= clip_g).any(axis=1)
        N = np.clip(N, -clip_g, clip_g)
    if drop_fraction:
        drop = rng.random(n) < drop_fraction
        N[drop] = np.nan
    return Recording(np.arange(n) / rate, N, None, "g", float(rate), sat, path)


def poses_recording(rng: np.random.Generator, directions=None, *, n_poses: int = 12, hold_s=3.0,
                    rate: float = 100.0, motion: str = "rotate", turn_rate_dps: float = 90.0,
                    noise_g: float = 2e-3, flicker_g: float = 0.0, clip_g: float | None = None,
                    drop_fraction: float = 0.0) -> Synthetic:
    """A recording of poses (``directions``, default ``n_poses`` random ones) held ``hold_s`` s each (one
    number or one per pose), joined by rotations at ``turn_rate_dps`` °/s (``motion="rotate"``) or by
    instantaneous steps (``"step"``). Noise: ``noise_g`` white SD per sample and ``flicker_g`` flicker
    bias instability (g); ``clip_g``: outputs clipped (and flagged saturated) at ±clip_g; ``drop_fraction``:
    samples replaced by NaN at random."""
    if motion not in ("rotate", "step"):
        raise InputError(f"`motion` {motion!r}: use rotate or step")
    if not (rate > 0 and turn_rate_dps > 0):
        raise InputError("`rate` and `turn_rate_dps` must be positive")
    dirs = random_directions(rng, n_poses) if directions is None else np.asarray(directions, float)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    hold = np.broadcast_to(np.asarray(hold_s, float), (len(dirs),))
    parts, rests, pos = [], [], 0
    for i, (d, h) in enumerate(zip(dirs, hold)):
        if i and motion == "rotate":
            th = np.degrees(np.arccos(np.clip(dirs[i - 1] @ d, -1, 1)))
            m = max(1, int(round(th / turn_rate_dps * rate)))
            parts.append(arc(dirs[i - 1], d, m))
            pos += m
        k = max(1, int(round(h * rate)))
        parts.append(np.repeat(d[None], k, 0))
        rests.append((pos, pos + k))
        pos += k
    A = np.concatenate(parts)
    rec = _sensor(rng, A, rate, noise_g, flicker_g, clip_g, drop_fraction, "simulated poses")
    return Synthetic(rec, np.array(rests, np.int64), dirs)


def tumble_recording(rng: np.random.Generator, *, duration_s: float = 60.0, rate: float = 100.0,
                     turn_rate_dps: float = 5.0, pauses: int = 0, pause_s: float = 2.0, noise_g: float = 2e-3,
                     flicker_g: float = 0.0) -> Synthetic:
    """A continuous rotation at ``turn_rate_dps`` °/s about a random axis (tilted so gravity's direction in
    the sensor sweeps a cone, not a single plane) for ``duration_s`` s, with ``pauses`` rests of ``pause_s``
    s evenly spread through it (the only true rests)."""
    if not (rate > 0 and duration_s > 0 and turn_rate_dps > 0):
        raise InputError("`rate`, `duration_s` and `turn_rate_dps` must be positive")
    n_move = int(round(duration_s * rate))
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    g0 = np.cross(axis, rng.standard_normal(3))
    g0 = g0 / np.linalg.norm(g0) * np.sqrt(0.75) + axis * 0.5  # 60° from the axis
    # rotation angle at each moving sample; pauses hold the angle
    ang = np.radians(turn_rate_dps) * np.arange(n_move) / rate
    k = int(round(pause_s * rate))
    at = np.linspace(0, n_move, pauses + 2)[1:-1].astype(int)
    pieces, rests, pos, prev = [], [], 0, 0
    for b in at:
        pieces.append(ang[prev:b])
        pos += b - prev
        pieces.append(np.full(k, ang[b - 1] if b else 0.0))
        rests.append((pos, pos + k))
        pos, prev = pos + k, b
    pieces.append(ang[prev:])
    seq = np.concatenate(pieces)
    rests = np.array(rests, np.int64).reshape(-1, 2)
    # Rodrigues' rotation of g0 about the axis by each angle
    c, s = np.cos(seq)[:, None], np.sin(seq)[:, None]
    A = g0 * c + np.cross(axis, g0) * s + axis * (axis @ g0) * (1 - c)
    rec = _sensor(rng, A, rate, noise_g, flicker_g, None, 0.0, "simulated tumble")
    dirs = A[rests[:, 0]] if len(rests) else np.zeros((0, 3))
    return Synthetic(rec, rests, dirs)
