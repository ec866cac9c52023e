"""Following a plan of rotations (docs/planning.md, "Planning the rotations"): its file, a recording that follows
it, and what the gyroscope problem of that recording determines.

A plan file is a scheme file (:mod:`.schemefile`: ``dx, dy, dz`` per pose, read wherever a scheme is, in the
planned order) with the motion from each pose to the next on the pose's row: ``axis_x, axis_y, axis_z`` (unit
vector in the sensor frame), ``angle_deg`` (the turn about it, right-hand rule), ``duration_s`` (from leaving
the pose's rest to reaching the next's) and ``peak_dps`` (the peak rate on the simulator's smooth profile,
2·angle/duration); ``rest_s`` is each rest's time. The last pose has no motion.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.analysis import check_observable
from optcal.core.gyro.data import GyroData
from optcal.core.gyro.model import get_gyro_model
from optcal.core.gyro.plan import DISPLAY, GyroNoise, MotionPlan, level_attitudes, model_spec
from optcal.core.gyro.problem import GyroProblem
from optcal.core.gyro.simulate import simulate_imu
from optcal.core.plan.fixtures import to_faces

MOTION_COLUMNS = ("axis_x", "axis_y", "axis_z", "angle_deg", "duration_s")
TOL = 1e-3  # unit vectors and the motion's landing direction, to this much (rad): the file has 6-9 decimals


def axis_label(axis: np.ndarray) -> str:
    """'+x', '-z', ... when the axis is a sensor axis, else ''."""
    k = int(np.argmax(np.abs(axis)))
    return ("+" if axis[k] > 0 else "-") + "xyz"[k] if abs(abs(axis[k]) - 1.0) < 1e-6 else ""


def plan_csv(plan: MotionPlan, comments: list[str] = ()) -> str:
    """The plan file's text: the poses in order, each with the motion to the next."""
    d = plan.directions
    faces, alpha, beta = to_faces(d)
    angle = plan.angle_deg
    axis = plan.rotvec / np.maximum(np.deg2rad(angle), 1e-300)[:, None]
    lines = [f"# {c}" for c in comments]
    lines += ["# dx, dy, dz: unit specific-force direction of the pose in the sensor frame; face_down, alpha_deg, "
              "beta_deg: how it is placed (docs/planning.md, 'For a person: fixtures, faces and tilts, order, "
              "files, figure'); rest_s: its rest, s",
              "# axis_x, axis_y, axis_z, angle_deg: the motion to the next pose, one turn by angle_deg (right-hand "
              "rule) about that sensor-frame axis; duration_s: s; peak_dps: peak rate, °/s"]
    lines.append("position,dx,dy,dz,face_down,alpha_deg,beta_deg,rest_s," + ",".join(MOTION_COLUMNS) + ",peak_dps")
    rest = plan.cands.noise.rest_s
    for k in range(len(d)):
        row = f"{k + 1},{d[k, 0]:.9f},{d[k, 1]:.9f},{d[k, 2]:.9f},{faces[k]},{alpha[k]:.2f},{beta[k]:.2f},{rest:g}"
        if k < len(d) - 1:
            row += (f",{axis[k, 0]:.9f},{axis[k, 1]:.9f},{axis[k, 2]:.9f},{angle[k]:.4f},{plan.duration[k]:.3f},"
                    f"{plan.peak_dps[k]:.2f}")
        else:
            row += ",,,,,,"
        lines.append(row)
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class PlanFile:
    directions: np.ndarray  # (N, 3)
    rotvec: np.ndarray  # (N − 1, 3), rad, sensor frame
    duration: np.ndarray  # (N − 1,), s


def read_plan(path: str | Path) -> PlanFile:
    """A plan file's poses and motions, checked: unit directions and axes, turns of 0 to 180°, positive
    durations, and each motion landing the pose's gravity direction on the next pose's (to TOL rad)."""
    from scipy.spatial.transform import Rotation

    from optcal.core.plan.schemefile import read_scheme

    p = Path(path)
    d = read_scheme(p)  # the poses, with the scheme file's own checks and messages
    text = p.read_text(encoding="utf-8")
    rows = list(csv.reader(line for line in io.StringIO(text) if line.strip() and not line.lstrip().startswith("#")))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in MOTION_COLUMNS if c not in header]
    if missing:
        raise InputError(f"plan file {str(p)!r} lacks column(s) {', '.join(missing)}; write it with optcal plan "
                         "--sensor gyroscope -o")
    if len(d) < 2:
        raise InputError(f"plan file {str(p)!r} has {len(d)} pose; a plan of motions needs two or more")
    cols = [header.index(c) for c in MOTION_COLUMNS]
    out = []
    for k, row in enumerate(rows[1:len(d)], start=1):
        try:
            out.append([float(row[c]) for c in cols])
        except (IndexError, ValueError):
            raise InputError(f"plan file {str(p)!r}, data row {k}: {', '.join(MOTION_COLUMNS)} must be numbers (the "
                             "motion to the next pose)") from None
    m = np.array(out, float)
    axis, angle, duration = m[:, :3], m[:, 3], m[:, 4]
    checks = [(np.abs(np.linalg.norm(axis, axis=1) - 1.0) > TOL, "the axis is not a unit vector"),
              (~((angle >= 0) & (angle < 180)), "the angle must be 0 to 180°"),
              (~(duration > 0), "the duration must be positive")]
    for bad, what in checks:
        if np.any(bad):
            raise InputError(f"plan file {str(p)!r}, data row {int(np.flatnonzero(bad)[0]) + 1}: {what}")
    rotvec = axis / np.linalg.norm(axis, axis=1, keepdims=True) * np.deg2rad(angle)[:, None]
    landed = np.einsum("kij,kj->ki", Rotation.from_rotvec(rotvec).as_matrix(), d[1:])  # Q·u_{k+1} = u_k
    miss = np.arccos(np.clip(np.sum(landed * d[:-1], axis=1), -1.0, 1.0))
    if np.any(miss > TOL):
        k = int(np.argmax(miss))
        raise InputError(f"plan file {str(p)!r}, data row {k + 1}: the motion does not take pose {k + 1} to pose "
                         f"{k + 2} (it misses by {np.rad2deg(miss[k]):.3g}°); correct the axis or the angle")
    return PlanFile(d, rotvec, duration)


def simulate_plan(directions: np.ndarray, rotvec: np.ndarray, duration: np.ndarray, model: str, truth: np.ndarray,
                  noise: GyroNoise, rng: np.random.Generator, rate_hz: float = 100.0) -> GyroData:
    """A recording following a plan from the pose of ``directions[0]``: a rest of ``noise.rest_s``, then each
    motion (rotation vector, sensor frame, over its duration, on the simulator's smooth profile) and a rest, with
    white rate noise of the stated density and each rest's mean specific force off by the stated direction noise
    per axis. ``truth``: the simulated gyroscope's parameters (the model with the bias and, for gyro21,
    g-sensitivity, :func:`optcal.core.gyro.simulate.draw_truth`). One simulation per motion (each has its own
    duration), joined in time; every draw from ``rng``."""
    from scipy.spatial.transform import Rotation

    g_sens, _ = model_spec(model)
    full = get_gyro_model(g_sens)
    C = [level_attitudes(np.asarray(directions, float)[:1])[0]]
    for Q in Rotation.from_rotvec(np.atleast_2d(rotvec)).as_matrix():
        C.append(C[-1] @ Q)
    acc = noise.direction * np.sqrt(round(noise.rest_s * rate_hz))  # per sample, for the rest mean's SD
    t, W, F, rests, n = [], [], [], [], 0
    T = np.atleast_1d(duration)
    for k in range(len(T)):
        s = simulate_imu(full, truth, attitudes=np.array(C[k:k + 2]), rate_hz=rate_hz, rest_s=noise.rest_s,
                         motion_s=float(T[k]) - 1.0 / rate_hz, noise_rate=noise.density * np.sqrt(rate_hz),
                         noise_acc_g=acc, rng=rng).data
        r = s.detected_rests
        end = len(s.t) if k == len(T) - 1 else int(r[1, 0])  # the next rest is the next simulation's first
        rests += [r[0] + n] + ([r[1] + n] if k == len(T) - 1 else [])
        t.append(s.t[:end] + n / rate_hz)
        W.append(s.W[:end])
        F.append(s.F[:end])
        n += end
    return GyroData(np.concatenate(t), np.concatenate(W), np.concatenate(F), np.array(rests), units="rad/s")


def verdict(directions: np.ndarray, rotvec: np.ndarray, duration: np.ndarray, model: str, noise: GyroNoise,
            rng: np.random.Generator) -> int:
    """The rank of the gyroscope problem of a recording that follows the plan (simulated with the stated noise, a
    nominal sensor); an InputError naming the parameters it leaves undetermined when any are
    (:func:`optcal.core.gyro.analysis.check_observable`)."""
    g_sens, bias = model_spec(model)
    truth = get_gyro_model(g_sens).default_vector(1.0)
    data = simulate_plan(directions, rotvec, duration, model, truth, noise, rng)
    problem = GyroProblem(data, g_sensitivity=g_sens, bias=bias, scale=1.0)
    try:
        return check_observable(problem, problem.from_sensor(truth)).rank
    except InputError as exc:
        raise InputError(f"{model} on this plan: {exc}") from None


def _with_units(family_sd: dict) -> dict:
    return {f: {"sd": v, "unit": DISPLAY[f][1]} for f, v in family_sd.items()}


def summary(plan: MotionPlan, habitual: MotionPlan | None, rank: int) -> dict:
    """The plan as one JSON-ready record: poses, motions, every parameter's predicted SD in the unit a user
    reads (:data:`optcal.core.gyro.plan.DISPLAY`), the criterion against the habitual plan's, times, the rank."""
    c = plan.cands
    faces, alpha, beta = to_faces(plan.directions)
    angle = plan.angle_deg
    axis = plan.rotvec / np.maximum(np.deg2rad(angle), 1e-300)[:, None]
    poses = [{"position": k + 1, "dx": float(x), "dy": float(y), "dz": float(z), "face_down": f,
              "alpha_deg": float(a), "beta_deg": float(b)}
             for k, ((x, y, z), f, a, b) in enumerate(zip(plan.directions, faces, alpha, beta, strict=True))]
    motions = [{"from": k + 1, "to": k + 2, "axis": [float(v) for v in axis[k]], "about": axis_label(axis[k]),
                "angle_deg": float(angle[k]), "duration_s": float(plan.duration[k]),
                "peak_dps": float(plan.peak_dps[k])} for k in range(len(angle))]
    sd = []
    for n, v in zip(c.names, plan.sd, strict=True):
        k, unit = DISPLAY[n[0]]
        sd.append({"name": n, "sd": float(v * k) if np.isfinite(v) else None, "unit": unit})
    out = {"model": c.model, "n_poses": len(plan.order), "criterion": plan.kind, "criterion_value": plan.value,
           "criterion_unit": "variance in natural units (relative scale, rad, rad/s, (rad/s)/g)",
           "rank": rank, "n_parameters": len(c.names), "motion_s": plan.motion_s, "session_s": plan.session_s,
           "noise": {"rate_density_dps_rthz": float(np.rad2deg(c.noise.density)),
                     "rest_mean_ug": c.noise.direction * 1e6, "rest_s": c.noise.rest_s},
           "rate_limit_dps": c.timing.rate_limit_dps, "poses": poses, "motions": motions, "crlb": sd,
           "family_worst_sd": _with_units(plan.family_sd())}
    if habitual is not None:
        out["habitual"] = {"criterion_value": habitual.value, "motion_s": habitual.motion_s,
                           "session_s": habitual.session_s, "family_worst_sd": _with_units(habitual.family_sd()),
                           "factor": habitual.value / plan.value}
    return out
