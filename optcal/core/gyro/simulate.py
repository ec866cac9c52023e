"""Simulated IMU recordings with known truth: rests in the poses of a scheme, rotations between them.

The body's attitude C (body to world) in pose k puts the scheme's direction u_k (the specific force in
the body frame, docs/design.md, "Position schemes") on the world's vertical, with a heading drawn uniformly. Between two
poses the body turns about the fixed body axis of the relative rotation C_kᵀ·C_{k+1} (axis a, angle θ)
along a rotation profile s(τ), the share of θ turned at the motion's time fraction τ (:data:`PROFILES`):
``smooth``, s(τ) = τ − sin(2πτ)/(2π), a raised-cosine rate that starts and ends at zero; or
``trapezoid``, a constant angular acceleration over the first quarter, a constant rate, and a constant
deceleration over the last quarter (a motion turned at a steady rate, as by hand or a rate table), its
corners on sample times: the calibration integrates the rate as linear between samples, and a corner
between two samples would put an error of about (angular acceleration)·dt²/8 into the truth (2e-5 rad per
corner for a 2 rad turn in 2 s at 100 Hz) that no calibration could remove. The
true body rate is a·θ·ṡ and the attitude is known in closed form at every sample (no integration error in
the truth). The gyroscope outputs the model of :mod:`optcal.core.gyro.model` at the true rate and specific
force, plus white noise and a bias random walk (bias instability: Brownian motion of the rate bias, the
rate random walk term of IEEE Std 952's gyroscope noise model); the accelerometer's specific force
(already calibrated, g) carries white noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.data import GyroData
from optcal.core.gyro.model import GyroModel
from optcal.core.schemes import scheme

# Navigation-grade MEMS truth spreads (1 SD): scale 1 %, misalignment 5 mrad, bias 5 mrad/s (0.3 °/s),
# g-sensitivity 1 mrad/s per g (0.06 °/s/g).
TRUTH_SPREAD = {"K": 0.01, "T": 5e-3, "b": 5e-3, "G": 1e-3}


def draw_truth(model: GyroModel, rng: np.random.Generator, scale: float) -> np.ndarray:
    """A truth vector: scale ``scale``·(1 + 1 % noise) output units per rad/s, the rest of TRUTH_SPREAD."""
    x = np.empty(model.n_params)
    for k, n in enumerate(model.names):
        v = TRUTH_SPREAD[n[0]] * rng.standard_normal()
        x[k] = scale * (1.0 + v) if n[0] == "K" else v
    return x


@dataclass
class SimulatedIMU:
    data: GyroData
    truth: np.ndarray
    model: GyroModel
    attitudes: np.ndarray  # (poses, 3, 3) body to world


# The ramp of the trapezoid profile: the share of the motion's duration spent accelerating (and as much
# decelerating), before it is rounded to a whole number of sample steps.
RAMP = 0.25


def _smooth(tau: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """s(τ) = τ − sin(2πτ)/(2π) and ds/dτ = 1 − cos(2πτ)."""
    return tau - np.sin(2 * np.pi * tau) / (2 * np.pi), 1.0 - np.cos(2 * np.pi * tau)


def _trapezoid(tau: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """The trapezoid's s(τ) and ds/dτ: the rate rises linearly to v = 1/(1 − r) over [0, r], holds, and falls
    linearly to zero over [1 − r, 1] (so that s(1) = 1), with r the RAMP rounded to a whole number of the
    motion's ``steps`` sample steps (at least one), so that its corners fall on samples."""
    r = max(1, round(RAMP * steps)) / steps
    v = 1.0 / (1.0 - r)
    rise, fall = tau < r, tau > 1.0 - r
    s = np.where(rise, v * tau**2 / (2 * r), v * (tau - r / 2))
    s = np.where(fall, 1.0 - v * (1.0 - tau) ** 2 / (2 * r), s)
    ds = np.where(rise, v * tau / r, np.where(fall, v * (1.0 - tau) / r, v))
    return s, ds


# The rotation profiles between poses: the share s(τ) of the turn made at the motion's time fraction τ, and
# its derivative ds/dτ, for a motion of ``steps`` sample steps.
PROFILES = {"smooth": _smooth, "trapezoid": _trapezoid}


def _attitudes(u: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Body-to-world rotations putting each body direction u_k on the world's z axis, random heading."""
    from scipy.spatial.transform import Rotation

    out = []
    z = np.array([0.0, 0.0, 1.0])
    for v in u:
        align, _ = Rotation.align_vectors([z], [v])  # maps v onto z
        heading = Rotation.from_rotvec(z * rng.uniform(-np.pi, np.pi))
        out.append((heading * align).as_matrix())
    return np.array(out)


def simulate_imu(model: GyroModel, truth, *, poses=24, rate_hz: float = 100.0, rest_s: float = 3.0,
                 motion_s: float = 2.0, noise_rate: float = 1e-3, bias_walk: float = 0.0,
                 noise_acc_g: float = 1e-3, attitudes: np.ndarray | None = None, profile: str = "smooth",
                 rng: np.random.Generator) -> SimulatedIMU:
    """A recording of ``poses`` (a scheme: 24, 36, ...) with rests of ``rest_s`` s and motions of
    ``motion_s`` s between them along the rotation ``profile`` (:data:`PROFILES`), at ``rate_hz``. Noise:
    ``noise_rate`` rad/s (SD per sample, white) on each gyroscope axis, a bias random walk of ``bias_walk``
    rad/s/√s (the SD of the bias's change over one second; rad/s²/√Hz, Kalibr's ``gyroscope_random_walk``,
    is the same number), ``noise_acc_g`` g on each accelerometer axis. ``truth``: a parameter vector of
    ``model``. ``attitudes`` (k, 3, 3), body to world, replace the poses (to rotate about chosen axes
    only). Every draw from ``rng``."""
    if not isinstance(rng, np.random.Generator):
        raise InputError("simulate_imu needs a numpy.random.Generator (seeded from the user's seed)")
    if profile not in PROFILES:
        raise InputError(f"unknown rotation profile {profile!r}; use one of {', '.join(PROFILES)}")
    truth = np.asarray(truth, float)
    if truth.shape != (model.n_params,):
        raise InputError(f"the truth has {truth.size} values; model {model.name} has {model.n_params}")
    from scipy.spatial.transform import Rotation  # imported at first use, as optcal's commands expect

    C = _attitudes(scheme(poses, rng), rng) if attitudes is None else np.asarray(attitudes, float)
    n_rest, n_move = int(round(rest_s * rate_hz)), int(round(motion_s * rate_hz))
    dt = 1.0 / rate_hz
    omega, att, rests = [], [], []
    i = 0
    for k in range(len(C)):
        rests.append((i, i + n_rest))
        omega.append(np.zeros((n_rest, 3)))
        att.append(np.repeat(C[k][None], n_rest, axis=0))
        i += n_rest
        if k + 1 == len(C):
            break
        rel = Rotation.from_matrix(C[k].T @ C[k + 1]).as_rotvec()  # body-frame rotation vector
        tau = (np.arange(1, n_move + 1)) / (n_move + 1)
        s, ds = PROFILES[profile](tau, n_move + 1)
        sdot = ds / ((n_move + 1) * dt)
        omega.append(sdot[:, None] * rel[None])
        att.append(C[k] @ Rotation.from_rotvec(s[:, None] * rel[None]).as_matrix())
        i += n_move
    omega, att = np.concatenate(omega), np.concatenate(att)
    t = np.arange(len(omega)) * dt
    f = att[:, 2, :]  # body-frame specific force: Cᵀ·e_z, 1 g upward (the turns are about the sensor's origin)
    W = model.forward(truth, omega, f)
    K = truth[:3]
    noise = noise_rate * rng.standard_normal(W.shape)
    if bias_walk > 0:
        noise += np.cumsum(bias_walk * np.sqrt(dt) * rng.standard_normal(W.shape), axis=0)
    W = W + K * noise
    F = f + noise_acc_g * rng.standard_normal(f.shape)
    return SimulatedIMU(GyroData(t, W, F, np.array(rests), units="counts"), truth, model, C)
