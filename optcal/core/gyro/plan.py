"""Planning the rotations between rests for the gyroscope (docs/planning.md, "Planning the rotations"): the
models, the stated noise and timing, the motions a pair of poses allows, the criteria and a plan.

The gyroscope's parameters are determined by the motions between rests (Tedaldi, Pretto and Menegatti, ICRA
2014, §IV-B): each motion's two residuals say how far the first rest's gravity direction, carried by the
integrated calibrated rate, lands from the second's (:mod:`optcal.core.gyro.problem`). A motion from pose a
(gravity direction u_a in the sensor frame) to pose b is a rotation Q of the body with Q·u_b = u_a; such
rotations form a one-parameter family, Q(φ) = Rot(u_a, φ)·Q_s, Q_s the shortest one and φ a turn about the
vertical (the "heading"). Each is one turn about a fixed sensor axis (its rotation vector: axis and angle).

The residual sees the motion's attitude error only across the gravity direction at its end: an error of the
rotation about that direction moves the carried gravity direction nowhere, so a turn about the vertical
says nothing about the rate sensed along the vertical (its axis's scale factor). Rotations about one axis
leave the other axes' scale factors and four misalignments undetermined.

The candidates and their information are built in :mod:`.gyro_candidates`, the order and the rotations are
searched in :mod:`.gyro_search`, and plan files and recordings that follow a plan are in :mod:`.gyro_follow`.
Information adds over motions and rests.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gauge import RTOL

# name -> (g-sensitivity, bias mode of GyroProblem)
GYRO_MODELS = {"gyro9": (False, "rests"), "gyro12": (False, "fit"), "gyro21": (True, "fit")}
CRITERIA = ("D", "A", "E", "worst")
# A rotation vector is ambiguous at 180° (+a and −a reach the same attitude along different paths): one motion
# turns at most this much, so opposite poses are never consecutive.
MAX_ANGLE_DEG = 179.0
MIN_REST_S = 0.1  # ten samples at 100 Hz, the rate at which a plan's recording is simulated
DEG_PER_H = 180.0 / np.pi * 3600.0
# What a user reads: (scale to multiply the natural unit by, unit)
DISPLAY = {"K": (1e6, "ppm"), "T": (1e6, "µrad"), "b": (DEG_PER_H, "°/h"), "G": (DEG_PER_H, "(°/h)/g")}


def model_spec(name: str) -> tuple[bool, str]:
    if name not in GYRO_MODELS:
        raise InputError(f"unknown gyroscope model {name!r}; use {', '.join(GYRO_MODELS)} (scale and misalignment; "
                         "with the bias; with the bias and g-sensitivity)")
    return GYRO_MODELS[name]


@dataclass(frozen=True)
class GyroNoise:
    """The stated noise: ``density`` the rate noise density (rad/s/√Hz, white: the angle random walk),
    ``direction`` the SD of a rest's mean gravity direction per tangent component (rad: the SD of a rest's mean
    specific force per axis in g, over 1 g), ``rest_s`` the time of each rest (s)."""

    density: float = 1e-4
    direction: float = 10e-6
    rest_s: float = 3.0

    def __post_init__(self):
        for name, v in (("gyroscope noise density", self.density), ("rest direction noise", self.direction),
                        ("rest time", self.rest_s)):
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"the {name} must be a positive number, got {v!r}")
        if self.rest_s < MIN_REST_S:
            raise InputError(f"rests of {self.rest_s:g} s are too short to take a mean of: give at least "
                             f"{MIN_REST_S:g} s (3 s is usual)")

    def motion_sd(self, window_s: np.ndarray) -> np.ndarray:
        return np.sqrt(2.0 * self.direction**2 + self.density**2 * np.asarray(window_s, float))

    def rest_sd(self) -> float:
        return self.density / np.sqrt(self.rest_s)


@dataclass(frozen=True)
class Timing:
    """A motion's duration: the smooth profile of the simulator, whose peak rate is 2θ/T, at ``rate_limit_dps``
    (°/s), at least ``min_s`` (s), rounded up to ``step_s``."""

    rate_limit_dps: float = 90.0
    min_s: float = 0.5
    step_s: float = 0.05

    def __post_init__(self):
        if not (np.isfinite(self.rate_limit_dps) and self.rate_limit_dps > 0):
            raise InputError(f"the rate limit must be a positive number of °/s, got {self.rate_limit_dps!r}")

    def duration(self, angle_rad: np.ndarray) -> np.ndarray:
        t = np.maximum(2.0 * np.rad2deg(np.asarray(angle_rad, float)) / self.rate_limit_dps, self.min_s)
        return np.ceil(t / self.step_s - 1e-9) * self.step_s


def perpendicular(u: np.ndarray) -> np.ndarray:
    h = np.where(np.abs(u[:, [0]]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e = np.cross(u, h)
    return e / np.linalg.norm(e, axis=1, keepdims=True)


def rotation_family(ua: np.ndarray, ub: np.ndarray, headings: int) -> np.ndarray:
    """Rotation vectors (m, H, 3) of Q(φ) = Rot(u_a, φ)·Q_s for φ = 2πk/H, Q_s the shortest rotation with
    Q_s·u_b = u_a (k = 0: the shortest itself; the identity when u_a = u_b)."""
    from scipy.spatial.transform import Rotation

    n = np.cross(ub, ua)
    s, c = np.linalg.norm(n, axis=1), np.sum(ua * ub, axis=1)
    axis = np.where(s[:, None] > 1e-12, n / np.maximum(s, 1e-300)[:, None], perpendicular(ua))
    Qs = Rotation.from_rotvec(axis * np.arctan2(s, c)[:, None])
    phi = 2.0 * np.pi * np.arange(headings) / headings
    m = len(ua)
    Rh = Rotation.from_rotvec((ua[:, None, :] * phi[None, :, None]).reshape(-1, 3))
    Q = Rh * Qs[np.repeat(np.arange(m), headings)]
    return Q.as_rotvec().reshape(m, headings, 3)


def body_axis_rotations(ua: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """Rotation vectors (m, 6, 3) about ±x, ±y, ±z taking u_b to u_a (both ways round), NaN where the axis
    cannot (the two directions' components along it differ) or for a zero turn."""
    out = np.full((len(ua), 6, 3), np.nan)
    for i in range(3):
        e = np.eye(3)[i]
        pa, pb = ua - ua[:, [i]] * e, ub - ub[:, [i]] * e
        ok = (np.abs(ua[:, i] - ub[:, i]) < 1e-9) & (np.linalg.norm(pa, axis=1) > 1e-9)
        th = np.arctan2(np.cross(pb, pa) @ e, np.sum(pa * pb, axis=1))
        ok &= np.abs(th) > 1e-9
        out[ok, 2 * i] = e * th[ok, None]
        out[ok, 2 * i + 1] = -e * (np.sign(th[ok]) * (2 * np.pi - np.abs(th[ok])))[:, None]
    return out


@dataclass
class Candidates:
    """Every candidate motion between the distinct directions U of the scheme's ``poses`` (N, 3; pose k has
    direction U[vertex[k]]): from U[a] to U[b], rotation vector ``rotvec`` (body frame, rad), ``duration`` (s),
    ``shortest`` (the k = 0 member of its pair's family), its two Jacobian rows ``rows`` (m, 2, p) whitened
    with the stated noise and its information ``info`` (m, p, p) = rowsᵀ·rows, in natural units (relative
    for K, rad, rad/s, (rad/s)/g), and each direction's rest information ``rest_info`` (n, p, p)."""

    model: str
    poses: np.ndarray
    vertex: np.ndarray
    U: np.ndarray
    a: np.ndarray
    b: np.ndarray
    rotvec: np.ndarray
    duration: np.ndarray
    shortest: np.ndarray
    rows: np.ndarray
    rest_info: np.ndarray
    names: tuple
    noise: GyroNoise
    timing: Timing
    options: np.ndarray = field(init=False)  # (n, n, O): candidate ids of each ordered pair, −1 padded
    info: np.ndarray = field(init=False)

    def __post_init__(self):
        self.info = np.einsum("mrp,mrq->mpq", self.rows, self.rows)
        n = len(self.U)
        count = np.zeros((n, n), int)
        np.add.at(count, (self.a, self.b), 1)
        self.options = np.full((n, n, max(1, count.max())), -1)
        pos = np.zeros((n, n), int)
        for c, (i, j) in enumerate(zip(self.a, self.b, strict=True)):
            self.options[i, j, pos[i, j]] = c
            pos[i, j] += 1

    @property
    def angle(self) -> np.ndarray:
        return np.linalg.norm(self.rotvec, axis=1)

    @property
    def about_axis(self) -> np.ndarray:
        """True for the turns about one of the sensor's axes."""
        a = np.abs(self.rotvec) / np.maximum(self.angle, 1e-300)[:, None]
        return (np.abs(a.max(axis=1) - 1.0) < 1e-6) & (self.angle > 0)

    def shortest_of(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """The shortest candidate of each pair (U[i] → U[j]); −1 where there is none (opposite directions)."""
        O = self.options[i, j]
        hit = (O >= 0) & self.shortest[np.maximum(O, 0)]
        return np.where(hit.any(axis=-1), np.take_along_axis(O, np.argmax(hit, axis=-1)[..., None], -1)[..., 0], -1)


def level_attitudes(u: np.ndarray) -> np.ndarray:
    """Body-to-world attitudes (m, 3, 3) putting each body direction u on the world's vertical."""
    from scipy.spatial.transform import Rotation

    z = np.array([0.0, 0.0, 1.0])
    n = np.cross(u, z)
    s, c = np.linalg.norm(n, axis=1), u @ z
    axis = np.where(s[:, None] > 1e-12, n / np.maximum(s, 1e-300)[:, None], perpendicular(u))
    return Rotation.from_rotvec(axis * np.arctan2(s, c)[:, None]).as_matrix()


def criterion(F: np.ndarray, kind: str = "D", ridge: float = 0.0) -> np.ndarray:
    """The criterion (S,) of informations F (S, p, p) in natural units (smaller is better): D, the geometric
    mean of the variances along the principal axes, det(F)^(−1/p); A, their mean; E, the largest; worst, the
    largest parameter variance diag(F⁻¹). inf where F is singular (relative eigenvalue below RTOL², the
    observability threshold of :mod:`optcal.core.analysis`); ``ridge`` > 0: of F + ridge·I, with no such test (a
    weak prior that orders plans which do not determine the model yet, as in :mod:`.design`)."""
    if kind not in CRITERIA:
        raise InputError(f"unknown criterion {kind!r} for the gyroscope; use one of {', '.join(CRITERIA)}")
    F = np.asarray(F, float)
    if ridge > 0:
        F = F + ridge * np.eye(F.shape[-1])
        # positive definite: Cholesky and LU are several times faster than an eigen-decomposition
        if kind == "D":
            L = np.linalg.cholesky(F)
            return np.exp(-2.0 * np.mean(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1))
        if kind in ("A", "worst"):
            var = np.diagonal(np.linalg.inv(F), axis1=1, axis2=2)
            return var.mean(axis=1) if kind == "A" else var.max(axis=1)
        return 1.0 / np.linalg.eigvalsh(F)[:, 0]
    lam, V = np.linalg.eigh(F)
    ok = lam[:, 0] > RTOL**2 * np.maximum(lam[:, -1], 1e-300)
    lam = np.where(ok[:, None], lam, 1.0)
    if kind == "D":
        v = np.exp(-np.mean(np.log(lam), axis=1))
    elif kind == "A":
        v = np.mean(1.0 / lam, axis=1)
    elif kind == "E":
        v = 1.0 / lam[:, 0]
    else:
        v = np.max(np.einsum("spr,sr->sp", V * V, 1.0 / lam), axis=1)
    return np.where(ok, v, np.inf)


def sd_of(F: np.ndarray) -> np.ndarray:
    """Cramér-Rao SD (p,) of every parameter in natural units; inf where F is singular."""
    lam = np.linalg.eigvalsh(F)
    if not lam[0] > RTOL**2 * max(lam[-1], 1e-300):
        return np.full(len(F), np.inf)
    return np.sqrt(np.diag(np.linalg.inv(F)))


@dataclass
class MotionPlan:
    """The scheme's poses in ``order`` (indices into the scheme) and the motion between each pair of
    consecutive poses (``choice``: candidate ids); the information F (natural units), the criterion's value,
    every parameter's Cramér-Rao SD (natural units)."""

    cands: Candidates
    order: np.ndarray
    choice: np.ndarray
    kind: str = "D"
    F: np.ndarray = field(init=False)

    def __post_init__(self):
        self.order, self.choice = np.asarray(self.order, int), np.asarray(self.choice, int)
        self.F = information(self.cands, self.choice[None])[0]

    @property
    def directions(self) -> np.ndarray:
        return self.cands.poses[self.order]

    @property
    def value(self) -> float:
        return float(criterion(self.F[None], self.kind)[0])

    @property
    def sd(self) -> np.ndarray:
        return sd_of(self.F)

    @property
    def rotvec(self) -> np.ndarray:
        return self.cands.rotvec[self.choice]

    @property
    def duration(self) -> np.ndarray:
        return self.cands.duration[self.choice]

    @property
    def angle_deg(self) -> np.ndarray:
        return np.rad2deg(np.linalg.norm(self.rotvec, axis=1))

    @property
    def peak_dps(self) -> np.ndarray:
        """Each motion's peak rate (°/s) on the simulator's smooth profile, 2θ/T."""
        return 2.0 * self.angle_deg / self.duration

    @property
    def motion_s(self) -> float:
        return float(self.duration.sum())

    @property
    def session_s(self) -> float:
        """Rests and motions (s)."""
        return len(self.order) * self.cands.noise.rest_s + self.motion_s

    def family_sd(self) -> dict[str, float]:
        """The largest SD of each parameter family, in the unit a user reads (DISPLAY)."""
        out = {}
        for fam, (k, _) in DISPLAY.items():
            m = [i for i, n in enumerate(self.cands.names) if n[0] == fam]
            if m:
                out[fam] = float(np.max(self.sd[m]) * k)
        return out


def information(cands: Candidates, choices: np.ndarray) -> np.ndarray:
    """F (S, p, p) of S plans of the scheme's poses: their rests (in any order: a rest does not depend on
    it) plus the motions ``choices`` (S, N − 1) (candidate ids)."""
    F_rest = cands.rest_info[cands.vertex].sum(axis=0)
    return F_rest[None] + cands.info[np.asarray(choices)].sum(axis=1)
