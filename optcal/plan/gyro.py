"""Planning the rotations between rests for the gyroscope (docs/planning.md, "Planning the rotations").

The gyroscope's parameters are determined by the motions between rests (Tedaldi, Pretto and Menegatti, ICRA
2014, §IV-B): each motion's two residuals say how far the first rest's gravity direction, carried by the
integrated calibrated rate, lands from the second's (:mod:`optcal.gyro.problem`). A motion from pose a
(gravity direction u_a in the sensor frame) to pose b is a rotation Q of the body with Q·u_b = u_a; such
rotations form a one-parameter family, Q(φ) = Rot(u_a, φ)·Q_s, Q_s the shortest one and φ a turn about the
vertical (the "heading"). Each is one turn about a fixed sensor axis (its rotation vector: axis and angle).

The residual sees the motion's attitude error only across the gravity direction at its end: an error of the
rotation about that direction moves the carried gravity direction nowhere, so a turn about the vertical
says nothing about the rate sensed along the vertical (its axis's scale factor). Rotations about one axis
only leave the other axes' scale factors and four misalignments undetermined.

The information of a candidate motion comes from the gyroscope problem's own Jacobian at nominal parameters
(scale 1, no misalignment, bias or g-sensitivity): every candidate motion of every pair of poses is
simulated once, chained in one recording (:func:`optcal.gyro.simulate.simulate_imu`, noise-free), and
:meth:`optcal.gyro.problem.GyroProblem.jacobian_full` gives all their rows in one compiled call; the rows
are unwhitened and whitened again with the stated noise. A motion of duration T (the time from leaving one
rest to reaching the next) has the scale and misalignment columns of its rows independent of T (the rate
error integrates to the same angle error however fast the turn) and its bias and g-sensitivity columns
proportional to T (they act per second), so one simulation at a reference duration serves every duration.
Its residuals' SD is √(2σ_u² + N²·T) (:meth:`optcal.gyro.data.GyroData.motion_sd`: σ_u a rest's
gravity-direction noise, N the rate noise density), a rest's three rate residuals' SD N/√(rest time)
(:meth:`optcal.gyro.data.GyroData.rest_sd`). Information adds over motions and rests; the search over
orders and rotations is in :mod:`.gyro_search`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..gauge import RTOL
from ..gyro.model import get_gyro_model
from ..gyro.problem import GyroProblem
from ..gyro.simulate import simulate_imu

# name -> (g-sensitivity, bias mode of GyroProblem)
GYRO_MODELS = {"gyro9": (False, "rests"), "gyro12": (False, "fit"), "gyro21": (True, "fit")}
CRITERIA = ("D", "A", "E", "worst")
# A rotation vector is ambiguous at 180° (+a and −a reach the same attitude along different paths): one motion
# turns at most this much, so opposite poses are never consecutive.
MAX_ANGLE_DEG = 179.0
# The candidates' simulation: 100 samples per motion of 1 s, rests of 10 samples (their means only count).
REF_RATE_HZ, REF_MOTION_S, REF_REST_S = 100.0, 1.0, 0.1
SIM_NOISE = 1e-9  # the candidates' recording is noise-free but for this (the problem refuses constant columns)
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


def distinct(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct unit directions U (n, 3) and the index of each pose's direction in U."""
    d = np.asarray(directions, float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    _, first, inverse = np.unique(np.round(d, 9), axis=0, return_index=True, return_inverse=True)
    keep = np.sort(first)
    remap = np.empty(len(first), int)
    remap[np.argsort(first)] = np.arange(len(first))
    return d[keep], remap[np.ravel(inverse)]


def _perpendicular(u: np.ndarray) -> np.ndarray:
    h = np.where(np.abs(u[:, [0]]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e = np.cross(u, h)
    return e / np.linalg.norm(e, axis=1, keepdims=True)


def rotation_family(ua: np.ndarray, ub: np.ndarray, headings: int) -> np.ndarray:
    """Rotation vectors (m, H, 3) of Q(φ) = Rot(u_a, φ)·Q_s for φ = 2πk/H, Q_s the shortest rotation with
    Q_s·u_b = u_a (k = 0: the shortest itself; the identity when u_a = u_b)."""
    from scipy.spatial.transform import Rotation

    n = np.cross(ub, ua)
    s, c = np.linalg.norm(n, axis=1), np.sum(ua * ub, axis=1)
    axis = np.where(s[:, None] > 1e-12, n / np.maximum(s, 1e-300)[:, None], _perpendicular(ua))
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


def tcolumns(names) -> np.ndarray:
    """The columns that act per second of motion (bias, g-sensitivity)."""
    return np.array([n[0] in "bG" for n in names])


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


def candidates(directions: np.ndarray, model: str = "gyro12", *, noise: GyroNoise = GyroNoise(),
               timing: Timing = Timing(), headings: int = 8, rng: np.random.Generator | None = None) -> Candidates:
    """All candidate motions between the distinct directions of ``directions``: for every ordered pair, the
    family's ``headings`` members and the turns about the sensor's axes, each at most MAX_ANGLE_DEG; a pair of
    equal directions only when the poses repeat it (a turn about the vertical)."""
    g_sens, _ = model_spec(model)
    if not (isinstance(headings, int | np.integer) and 1 <= headings <= 72):
        raise InputError(f"headings = {headings!r}: give 1 to 72 turns about the vertical per pair (e.g. 8)")
    U, idx = distinct(directions)
    n = len(U)
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    repeated = np.bincount(idx, minlength=n) > 1
    keep = (ii != jj) | repeated[ii]
    i, j = ii[keep], jj[keep]
    fam = rotation_family(U[i], U[j], headings)
    rv = np.concatenate([fam, body_axis_rotations(U[i], U[j])], axis=1)
    shortest = np.zeros(rv.shape[:2], bool)
    shortest[:, 0] = True
    pair = np.repeat(np.arange(len(i)), rv.shape[1])
    rv, shortest = rv.reshape(-1, 3), shortest.ravel()
    ok = np.all(np.isfinite(rv), axis=1) & (np.linalg.norm(rv, axis=1) <= np.deg2rad(MAX_ANGLE_DEG))
    # the same rotation twice in a pair (a body axis on the heading grid): keep the first
    key = np.column_stack([pair, np.round(np.where(np.isfinite(rv), rv, 0.0), 9)])
    _, first = np.unique(key[ok], axis=0, return_index=True)
    sel = np.flatnonzero(ok)[np.sort(first)]
    a, b, rv, shortest = i[pair[sel]], j[pair[sel]], rv[sel], shortest[sel]
    if n < 2:
        raise InputError("the poses all have one gravity direction: turns about the vertical cannot see the rate "
                         "along it; give poses with different directions")
    lone = np.setdiff1d(np.arange(n), a[a != b])
    if lone.size:
        raise InputError(f"the pose with direction {np.round(U[lone[0]], 4).tolist()} joins no other by a turn of "
                         "less than 180° (only its opposite is there); add a pose between them")
    rng = rng if rng is not None else np.random.default_rng(0)
    rows, rest_rows, window, names = _jacobian_rows(U, a, b, rv, g_sens, GYRO_MODELS[model][1], rng)
    duration = timing.duration(np.linalg.norm(rv, axis=1))
    white = whitened_rows(rows, window, duration, names, noise)
    if rest_rows is None:
        rest_info = np.zeros((n, len(names), len(names)))
    else:
        rest_info = np.einsum("nrp,nrq->npq", rest_rows, rest_rows) / noise.rest_sd() ** 2
    return Candidates(model, U[idx], idx, U, a, b, rv, duration, shortest, white, rest_info, names, noise, timing)


def whitened_rows(rows: np.ndarray, window: np.ndarray, duration: np.ndarray, names, noise: GyroNoise) -> np.ndarray:
    """Rows (m, 2, p) of motions whose unwhitened rows were simulated over ``window`` (s), made at ``duration``
    (s): the per-second columns scaled by duration/window, whitened by the stated noise."""
    R = rows.copy()
    R[:, :, tcolumns(names)] *= (duration / window)[:, None, None]
    return R / noise.motion_sd(duration)[:, None, None]


def level_attitudes(u: np.ndarray) -> np.ndarray:
    """Body-to-world attitudes (m, 3, 3) putting each body direction u on the world's vertical."""
    from scipy.spatial.transform import Rotation

    z = np.array([0.0, 0.0, 1.0])
    n = np.cross(u, z)
    s, c = np.linalg.norm(n, axis=1), u @ z
    axis = np.where(s[:, None] > 1e-12, n / np.maximum(s, 1e-300)[:, None], _perpendicular(u))
    return Rotation.from_rotvec(axis * np.arctan2(s, c)[:, None]).as_matrix()


def _walk(a: np.ndarray, b: np.ndarray) -> list[int]:
    """An order of the edges a→b as one walk, with −(v + 1) where the walk jumps to vertex v (no edge left
    where it stands): each candidate starts where the last one ended, so few motions are wasted on jumps."""
    out: dict[int, list[int]] = {}
    for e in range(len(a) - 1, -1, -1):
        out.setdefault(int(a[e]), []).append(e)
    left = sorted(out)
    v, seq = int(a[0]), [-(int(a[0]) + 1)]
    for _ in range(len(a)):
        while not out.get(v):
            left = [w for w in left if out.get(w)]
            v = left[0]
            seq.append(-(v + 1))
        e = out[v].pop()
        seq.append(e)
        v = int(b[e])
    return seq


def _jacobian_rows(U, a, b, rotvec, g_sens: bool, bias: str, rng):
    """Unwhitened Jacobian rows of every candidate motion (m, 2, p), of one rest per direction (n, 3, p) (None
    without a bias), each motion's simulated window (s) and the parameter names: one chained recording, one
    problem, one compiled Jacobian."""
    from scipy.spatial.transform import Rotation

    seq = _walk(a, b)
    Q = Rotation.from_rotvec(rotvec).as_matrix()
    C, motion_of, vertex = [], [], []
    for s in seq:
        if s < 0:  # jump: a fresh pose at vertex −s − 1; the motion into it is not a candidate
            if C:
                motion_of.append(-1)
            C.append(level_attitudes(U[[-s - 1]])[0])
            vertex.append(-s - 1)
        else:
            motion_of.append(s)
            C.append(C[-1] @ Q[s])
            vertex.append(int(b[s]))
    full = get_gyro_model(g_sens)
    truth = full.default_vector(1.0)
    sim = simulate_imu(full, truth, attitudes=np.array(C), rate_hz=REF_RATE_HZ, rest_s=REF_REST_S,
                       motion_s=REF_MOTION_S - 1.0 / REF_RATE_HZ, noise_rate=SIM_NOISE, noise_acc_g=SIM_NOISE, rng=rng)
    problem = GyroProblem(sim.data, g_sensitivity=g_sens, bias=bias, scale=1.0)
    J = problem.jacobian_full(problem.from_sensor(truth))
    d = problem.data
    m = d.n_motions
    motion = J[: 2 * m].reshape(m, 2, -1) * problem.sd_motion[:, None, None]
    motion_of = np.array(motion_of)
    rows = np.empty((len(a), 2, J.shape[1]))
    rows[motion_of[motion_of >= 0]] = motion[motion_of >= 0]
    window = np.empty(len(a))
    window[motion_of[motion_of >= 0]] = (d.t[d.stop] - d.t[d.start])[motion_of >= 0]
    rest = None
    if problem.model.bias:
        R = J[2 * m:].reshape(d.n_rests, 3, -1) * problem.sd_rest[:, :, None]
        _, first = np.unique(np.array(vertex), return_index=True)
        rest = R[first]
    return rows, rest, window, tuple(problem.model.names)


def criterion(F: np.ndarray, kind: str = "D", ridge: float = 0.0) -> np.ndarray:
    """The criterion (S,) of informations F (S, p, p) in natural units (smaller is better): D, the geometric
    mean of the variances along the principal axes, det(F)^(−1/p); A, their mean; E, the largest; worst, the
    largest parameter variance diag(F⁻¹). inf where F is singular (relative eigenvalue below RTOL², the
    observability threshold of :mod:`optcal.analysis`); ``ridge`` > 0: of F + ridge·I, with no such test (a
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
