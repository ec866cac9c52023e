"""imucal's Ferraris session (MIT; the real corpus's imucal/, tests/corpus.py) calibrated end to end by optcal:
accelerometer (diag6: the six axis-aligned poses do not determine linear9's angles), then gyroscope from the
motions between the rests, then the three 360° turns about the vertical that the Ferraris procedure is built
on, integrated with the calibrated rate: an independent check, since a turn about the vertical leaves the
gravity direction where it was and so tells the fit nothing about its own axis's scale.

Reproduce:

    .venv/bin/python docs/scripts/gyro_imucal.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

DATA = corpus_root() / "imucal"
RATE = 102.4  # Hz (README of the data)


def calibrate_imucal(bias: str = "rests") -> dict:
    from optcal.app.fit import calibrate
    from optcal.app.workflows.gyro import calibrate_gyro
    from optcal.app.workflows.recording import positions_from_raw
    from optcal.core.gyro.data import GyroData
    from optcal.core.recording import read_recording

    path = DATA / "example_ferraris_session.csv"
    positions = positions_from_raw(path, columns="ax=acc_x,ay=acc_y,az=acc_z", rate=RATE, units="m/s2",
                                   model="diag6")
    det = positions.extra["detection"]
    cal = calibrate(positions, "diag6")
    gyr = read_recording(path, "ax=gyr_x,ay=gyr_y,az=gyr_z", RATE, "volts")
    F = cal.model.inverse(np.asarray(cal.x, float)[None], det.recording.N)[0]
    data = GyroData(det.recording.t, gyr.N, F, det.intervals, units="deg/s")
    fit = calibrate_gyro(data, bias=bias, scale=180.0 / np.pi)
    p = fit.problem
    sections = json.loads((DATA / "example_ferraris_session_list.json").read_text())
    turns = {}
    for name in ("x_rot", "y_rot", "z_rot"):
        a, b = sections[name]["start"], sections[name]["end"]
        turns[name] = {key: _turn(p, xv, a, b) for key, xv in (("calibrated_deg", fit.x), ("nominal_deg", p.centre))}
    return {"names": p.model.names, "x": fit.x, "stderr": fit.stderr, "chi2_dof": fit.chi2_dof,
            "n_rests": data.n_rests, "n_motions": data.n_motions, "rank": fit.observability.rank,
            "angles_before": p.motion_angles(p.centre), "angles_after": p.motion_angles(fit.x), "turns": turns,
            "acc_model": cal.model.name}


def _turn(p, x, a: int, b: int) -> float:
    """The angle (°) turned from sample a to b: the integrated rate (trapezoid) along its mean direction, which
    counts whole turns (a quaternion's angle would wrap at 360°); the turns are about one axis, so the
    integrated rate is the rotation to well within the differences shown."""
    d = p.data
    w = p.model.inverse(x, d.W[a:b + 1], d.F[a:b + 1])
    v = np.trapezoid(w, d.t[a:b + 1], axis=0)
    return float(np.rad2deg(np.linalg.norm(v)))


def main() -> int:
    out = calibrate_imucal()
    print(f"rests {out['n_rests']}, motions {out['n_motions']}, accelerometer {out['acc_model']}, "
          f"chi2/dof {out['chi2_dof']:.1f}, rank {out['rank']}")
    for n, v, s in zip(out["names"], out["x"], out["stderr"], strict=True):
        print(f"| {n} | {v:.6g} | {s:.2g} |")
    for key in ("angles_before", "angles_after"):
        v = np.rad2deg(out[key])
        print(f"{key}: RMS {np.sqrt(np.mean(v**2)):.3f}°, max {v.max():.3f}°")
    for name, t in out["turns"].items():
        print(f"{name}: {t['nominal_deg']:.2f}° nominal, {t['calibrated_deg']:.2f}° calibrated (the hand turned 360°)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
