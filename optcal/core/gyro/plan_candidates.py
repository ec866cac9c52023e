"""The candidate motions between a scheme's poses and their information (docs/planning.md, "Planning the
rotations").

The information of a candidate motion comes from the gyroscope problem's own Jacobian at nominal parameters
(scale 1, no misalignment, bias or g-sensitivity): every candidate motion of every pair of poses is
simulated once, chained in one recording (:func:`optcal.core.gyro.simulate.simulate_imu`, noise-free), and
:meth:`optcal.core.gyro.problem.GyroProblem.jacobian_full` gives all their rows in one compiled call; the rows
are unwhitened and whitened again with the stated noise. A motion of duration T (the time from leaving one
rest to reaching the next) has the scale and misalignment columns of its rows independent of T (the rate
error integrates to the same angle error however fast the turn) and its bias and g-sensitivity columns
proportional to T (they act per second), so one simulation at a reference duration serves every duration.
Its residuals' SD is √(2σ_u² + N²·T) (:meth:`optcal.core.gyro.data.GyroData.motion_sd`: σ_u a rest's
gravity-direction noise, N the rate noise density), a rest's three rate residuals' SD N/√(rest time)
(:meth:`optcal.core.gyro.data.GyroData.rest_sd`).
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.model import get_gyro_model
from optcal.core.gyro.plan import (
    GYRO_MODELS,
    MAX_ANGLE_DEG,
    Candidates,
    GyroNoise,
    Timing,
    body_axis_rotations,
    level_attitudes,
    model_spec,
    rotation_family,
)
from optcal.core.gyro.problem import GyroProblem
from optcal.core.gyro.simulate import simulate_imu

# The candidates' simulation: 100 samples per motion of 1 s, rests of 10 samples (their means only count).
REF_RATE_HZ, REF_MOTION_S, REF_REST_S = 100.0, 1.0, 0.1
SIM_NOISE = 1e-9  # the candidates' recording is noise-free but for this (the problem refuses constant columns)


def distinct(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct unit directions U (n, 3) and the index of each pose's direction in U."""
    d = np.asarray(directions, float)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    _, first, inverse = np.unique(np.round(d, 9), axis=0, return_index=True, return_inverse=True)
    keep = np.sort(first)
    remap = np.empty(len(first), int)
    remap[np.argsort(first)] = np.arange(len(first))
    return d[keep], remap[np.ravel(inverse)]


def tcolumns(names) -> np.ndarray:
    """The columns that act per second of motion (bias, g-sensitivity)."""
    return np.array([n[0] in "bG" for n in names])


def candidates(directions: np.ndarray, model: str = "gyro12", *, noise: GyroNoise | None = None,
               timing: Timing | None = None, headings: int = 8, rng: np.random.Generator | None = None) -> Candidates:
    """All candidate motions between the distinct directions of ``directions``: for every ordered pair, the
    family's ``headings`` members and the turns about the sensor's axes, each at most MAX_ANGLE_DEG; a pair of
    equal directions only when the poses repeat it (a turn about the vertical)."""
    g_sens, _ = model_spec(model)
    noise, timing = noise or GyroNoise(), timing or Timing()
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
