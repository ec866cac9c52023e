"""Directions on the unit sphere that both the named schemes (:mod:`optcal.core.schemes`, which re-exports them)
and the planner use: the rotation groups of the 24- and 36-position schemes, the six faces, random and
golden-spiral spreads, and the placement error of a hand (docs/design.md, "Position schemes"). Here, below both, so that
:mod:`optcal.core.schemes` can resolve planned scheme names without an import cycle.
"""

from __future__ import annotations

import numpy as np


def rotation_groups(step_deg: float) -> np.ndarray:
    """Group x turns about the horizontal x axis: A = (0, sin θ, cos θ); group y: A = (cos θ, 0, sin θ);
    group z: A = (sin θ, cos θ, 0), θ in steps of ``step_deg`` (2020 paper §3.3 and §5.1)."""
    theta = np.deg2rad(np.arange(0.0, 360.0, step_deg))
    s, c, z = np.sin(theta), np.cos(theta), np.zeros_like(theta)
    return np.concatenate([np.stack([z, s, c], 1), np.stack([c, z, s], 1), np.stack([s, c, z], 1)])


def six_position() -> np.ndarray:
    return np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def random_orientations(n: int, rng: np.random.Generator) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def fibonacci_sphere(n: int) -> np.ndarray:
    """n nearly evenly spread unit vectors (the golden-angle spiral, equal area per point)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


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
