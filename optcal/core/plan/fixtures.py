"""Where a sensor can be put: the candidate directions of a fixture, and each direction said as a person
places it (which face is down, two tilt angles), in an order that needs little handling.

Faces and tilts (docs/planning.md, "For a person: fixtures, faces and tilts, order, files, figure"): the face down is
the side of the case whose outward axis points at the
table, −s·k for the specific force's largest component A_k of sign s (A points up, away from the table).
With (k, i, j) cyclic (z, x, y / x, y, z / y, z, x), the two tilts α, β satisfy
A_i = sin β, A_j = cos β · sin α, s·A_k = cos β · cos α: tilt by α about the i axis, then by β about the
(tilted) j axis; both lie within ±45° since A_k is the largest component.
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.sphere import fibonacci_sphere, rotation_groups

FIXTURES = ("free", "faces", "faces:STEP", "head:STEP")
_CYCLIC = {0: (1, 2), 1: (2, 0), 2: (0, 1)}  # k -> (i, j)


def _step(spec: str) -> float:
    try:
        step = float(spec.split(":", 1)[1])
    except ValueError:
        step = 0.0
    if not (np.isfinite(step) and 0 < step <= 90 and abs(90 / step - round(90 / step)) < 1e-9):
        raise InputError(f"fixture {spec!r}: the tilt step must divide 90°, e.g. {spec.split(':')[0]}:15")
    return step


def from_faces(face_axis: np.ndarray, sign: np.ndarray, alpha_deg: np.ndarray, beta_deg: np.ndarray) -> np.ndarray:
    """Directions (n, 3) from faces (axis k, sign s of the up axis) and tilts α, β in degrees."""
    a, b = np.deg2rad(alpha_deg), np.deg2rad(beta_deg)
    out = np.zeros((len(face_axis), 3))
    for k, (i, j) in _CYCLIC.items():
        m = face_axis == k
        out[m, i] = np.sin(b[m])
        out[m, j] = np.cos(b[m]) * np.sin(a[m])
        out[m, k] = sign[m] * np.cos(b[m]) * np.cos(a[m])
    return out


def to_faces(directions: np.ndarray) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Face down (e.g. '-z'), α and β (degrees) of each direction (the inverse of :func:`from_faces`)."""
    d = np.asarray(directions, float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    k = np.argmax(np.abs(d), axis=1)
    s = np.sign(d[np.arange(len(d)), k])
    alpha, beta = np.zeros(len(d)), np.zeros(len(d))
    for kk, (i, j) in _CYCLIC.items():
        m = k == kk
        beta[m] = np.rad2deg(np.arcsin(np.clip(d[m, i], -1, 1)))
        alpha[m] = np.rad2deg(np.arctan2(d[m, j], s[m] * d[m, kk]))
    faces = [("-" if sv > 0 else "+") + "xyz"[kk] for kk, sv in zip(k, s)]
    return faces, alpha, beta


def unique_directions(d: np.ndarray) -> np.ndarray:
    _, keep = np.unique(np.round(d, 9), axis=0, return_index=True)
    return d[np.sort(keep)]


def candidates(fixture: str, grid: int = 1000) -> tuple[np.ndarray, bool]:
    """The fixture's candidate directions and whether directions may vary continuously between them.

    ``free``: hand-held, any orientation (a golden-spiral grid of ``grid`` points, refined continuously);
    ``faces``: the six faces of a cube; ``faces:STEP``: a cube on a tilt plate, α and β in multiples of STEP
    degrees; ``head:STEP``: a dividing head turning about each sensor axis in STEP steps (the 24- and
    36-position schemes are head:45 and head:30).
    """
    spec = str(fixture).strip()
    if spec == "free":
        if not (isinstance(grid, int | np.integer) and 12 <= grid <= 100_000):
            raise InputError(f"`grid` = {grid!r}: the candidate grid needs 12 to 100,000 points (e.g. 1000)")
        return fibonacci_sphere(int(grid)), True
    if spec == "faces":
        return np.vstack([np.eye(3), -np.eye(3)]), False
    if spec.startswith("faces:"):
        step = _step(spec)
        t = np.arange(-45.0, 45.0 + 1e-9, step)
        A, B = np.meshgrid(t, t, indexing="ij")
        n = A.size
        faces = np.repeat(np.arange(3), 2 * n)
        signs = np.tile(np.repeat([1.0, -1.0], n), 3)
        d = from_faces(faces, signs, np.tile(A.ravel(), 6), np.tile(B.ravel(), 6))
        return unique_directions(d), False
    if spec.startswith("head:"):
        return unique_directions(rotation_groups(_step(spec))), False
    raise InputError(f"unknown fixture {spec!r}; use free, faces, faces:STEP (e.g. faces:15) or head:STEP "
                     "(e.g. head:30)")


def handling_order(directions: np.ndarray) -> np.ndarray:
    """An order of the positions that keeps the turns between consecutive positions small: nearest neighbour
    from the position closest to 'z up', then 2-opt on the path's total turn angle (the sum of angles between
    consecutive directions). A permutation of range(N); N is tens, so plain loops suffice here."""
    d = np.asarray(directions, float)
    n = len(d)
    if n < 3:
        return np.arange(n)
    ang = np.arccos(np.clip(d @ d.T, -1.0, 1.0))
    order = [int(np.argmax(d[:, 2]))]
    left = set(range(n)) - set(order)
    while left:
        last = order[-1]
        nxt = min(left, key=lambda j: (ang[last, j], j))
        order.append(nxt)
        left.remove(nxt)
    path = np.array(order)
    improved = True
    while improved:
        improved = False
        for a in range(1, n - 1):
            # reversing path[a:b+1] replaces edges (a-1, a) and (b, b+1) with (a-1, b) and (a, b+1)
            b = np.arange(a + 1, n)
            nb = np.append(path[b[:-1] + 1], -1)
            old = ang[path[a - 1], path[a]] + np.where(nb >= 0, ang[path[b], nb], 0.0)
            new = ang[path[a - 1], path[b]] + np.where(nb >= 0, ang[path[a], nb], 0.0)
            gain = old - new
            k = int(np.argmax(gain))
            if gain[k] > 1e-12:
                path[a:b[k] + 1] = path[a:b[k] + 1][::-1]
                improved = True
    return path


def turn_angle_deg(directions: np.ndarray) -> float:
    """Total turn (degrees) along the positions in the given order."""
    d = np.asarray(directions, float)
    return float(np.rad2deg(np.sum(np.arccos(np.clip(np.sum(d[1:] * d[:-1], axis=1), -1, 1)))))
