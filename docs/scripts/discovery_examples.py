"""The discovery reports and figures shown in docs/discovery.md: a simulated two-effect example and the
real recordings of the real corpus (tests/corpus.py: ``OPTCAL_CORPUS``, else the shared folder beside the clone;
read and cut into static positions by optcal.core.recording).

    .venv/bin/python docs/scripts/discovery_examples.py [--real DIR] [--figures docs/figures]

Prints each report (the text of ``optcal discover``) and writes discovery_example.png and
discovery_real_mpu6050.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from optcal import simulate
from optcal.app.workflows.discovery import discover
from optcal.core import recording as rc
from optcal.core.errors import InputError
from optcal.core.presets import draw_truth

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

REAL = corpus_root()


def halves(detection: rc.DetectionResult) -> np.ndarray:
    """Each static interval cut in two: the same orientation at two times (what a drift needs)."""
    iv = detection.intervals
    mid = (iv[:, 0] + iv[:, 1]) // 2
    out = np.concatenate([np.column_stack([iv[:, 0], mid]), np.column_stack([mid, iv[:, 1]])])
    return out[np.argsort(out[:, 0])]


def report(title: str, data, base: str, plot: Path | None = None) -> None:
    print(f"\n### {title}, base {base}\n")
    try:
        rep = discover(data, base=base)
    except InputError as exc:
        print(f"error: {exc}")
        return
    print(rep.summary())
    if plot is not None:
        rep.plot(plot)
        print(f"(figure: {plot})")


def simulated(figures: Path) -> None:
    """cubic + temperature_bias hidden in 36 positions (as in tests/test_discovery.py, seed 0)."""
    rng = np.random.default_rng(0)
    truth = draw_truth("linear9", rng)
    effects = {"cubic": {"K3_x": 2e-4, "K3_y": -2e-4, "K3_z": 2e-4},
               "temperature_bias": {"beta_x": 5e-6, "beta_y": -5e-6, "beta_z": 5e-6}}
    sim = simulate("linear9", truth, rng, scheme="36", noise_g=10e-6, temp=(20.0, 40.0), times=True,
                   effects=effects)
    data = dataclasses.replace(sim.data.subset(rng.permutation(36)), t=sim.data.t)
    print("\n### simulated: cubic + temperature_bias hidden, 36 positions, 10 µg noise (given)\n")
    rep = discover(data, noise_g=10e-6)
    print(rep.summary())
    rep.plot(figures / "discovery_example.png")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", type=Path, default=REAL)
    ap.add_argument("--figures", type=Path, default=Path("docs/figures"))
    args = ap.parse_args(argv)
    simulated(args.figures)

    # imucal: a six-position session in raw counts (about 2048 per g), 204.8 Hz
    rec = rc.read_recording(args.real / "imucal/annotated_session.csv", columns="ax=acc_x,ay=acc_y,az=acc_z",
                            rate=204.8, units="counts")
    det = rc.choose_threshold(rec, "diag6")
    print("\n" + rc.describe_detection(det))
    pos = rc.positions_from_recording(rec, det)
    report("imucal annotated_session (6 static intervals)", pos, "diag6")
    report("imucal annotated_session (6 static intervals)", pos, "linear9")
    report("imucal annotated_session, each interval cut in two (12 positions)",
           rc.positions_from_recording(rec, rc.given_intervals(rec, halves(det))), "diag6")

    # imucal: the Ferraris session in m/s², 102.4 Hz, static sections from its section list
    rec = rc.read_recording(args.real / "imucal/example_ferraris_session.csv", columns="ax=acc_x,ay=acc_y,az=acc_z",
                            rate=102.4, units="m/s2")
    det = rc.given_intervals(rec, *rc.read_intervals(args.real / "imucal/example_ferraris_session_list.json"))
    report("imucal example_ferraris_session (6 static sections)", rc.positions_from_recording(rec, det), "diag6")

    # MPU-6050: about ten poses in int16 counts (16384 per g), 100 Hz (from the file's Fs line)
    rec = rc.read_recording(args.real / "mpu6050/example_data_calibration.csv", columns="ax,ay,az", units="counts")
    det = rc.choose_threshold(rec, "diag6")
    print("\n" + rc.describe_detection(det))
    pos = rc.positions_from_recording(rec, det)
    report("MPU-6050 (10 static intervals)", pos, "diag6")
    report("MPU-6050 (10 static intervals)", pos, "linear9")
    cut = rc.positions_from_recording(rec, rc.given_intervals(rec, halves(det)))
    report("MPU-6050, each interval cut in two (20 positions)", cut, "diag6",
           plot=args.figures / "discovery_real_mpu6050.png")
    report("MPU-6050, each interval cut in two (20 positions)", cut, "linear9")


if __name__ == "__main__":
    main()
