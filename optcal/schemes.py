"""Static position schemes (docs/design.md §4): unit gravity directions in the body frame.

Group x turns about the horizontal x axis: A = (0, sin θ, cos θ); group y: A = (cos θ, 0, sin θ);
group z: A = (sin θ, cos θ, 0). The 24-position scheme uses 45° steps (2020 paper §3.3, 2015 paper §7.1),
the 36-position scheme 30° steps (2020 paper §5.1). Each returns unit vectors of shape (n, 3); multiply by
g_local (in g) for specific force.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError


def rotation_groups(step_deg: float) -> np.ndarray:
    theta = np.deg2rad(np.arange(0.0, 360.0, step_deg))
    s, c, z = np.sin(theta), np.cos(theta), np.zeros_like(theta)
    return np.concatenate([np.stack([z, s, c], 1), np.stack([c, z, s], 1), np.stack([s, c, z], 1)])


def six_position() -> np.ndarray:
    return np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def random_orientations(n: int, rng: np.random.Generator) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def tilt(directions: np.ndarray, sigma_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Imperfect placement: rotate each direction by a small random rotation (σ per axis, degrees)."""
    if sigma_deg <= 0:
        return directions
    phi = np.deg2rad(sigma_deg) * rng.standard_normal(directions.shape)
    # Rodrigues' formula, vectorised over positions
    angle = np.linalg.norm(phi, axis=1, keepdims=True)
    k = np.divide(phi, angle, out=np.zeros_like(phi), where=angle > 0)
    v = directions
    return (v * np.cos(angle) + np.cross(k, v) * np.sin(angle)
            + k * np.sum(k * v, axis=1, keepdims=True) * (1 - np.cos(angle)))


# A calibration uses tens of positions; a million already takes 100 MB per array of outputs and samples.
MAX_RANDOM_POSITIONS = 1_000_000


def scheme(spec: str | int, rng: np.random.Generator | None = None) -> np.ndarray:
    """Directions for a scheme given as ``6``, ``24``, ``36`` or ``random:N``."""
    spec = str(spec).strip()
    if spec == "6":
        return six_position()
    if spec == "24":
        return rotation_groups(45.0)
    if spec == "36":
        return rotation_groups(30.0)
    if spec.startswith("random:"):
        try:
            n = int(spec.split(":", 1)[1])
        except ValueError:
            n = 0
        if n < 1:
            raise InputError(f"scheme {spec!r}: give the number of orientations, e.g. random:30")
        if n > MAX_RANDOM_POSITIONS:
            raise InputError(f"scheme {spec!r}: {n:,} orientations is more than optcal handles "
                             f"({MAX_RANDOM_POSITIONS:,}); a calibration needs tens, e.g. random:30")
        return random_orientations(n, rng if rng is not None else np.random.default_rng(0))
    raise InputError(f"unknown scheme {spec!r}; use 6, 24, 36 or random:N")
