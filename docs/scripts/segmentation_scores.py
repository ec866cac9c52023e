"""Precision and recall of static-interval detection, old (variance detector with the threshold search,
Tedaldi et al. 2014) against new (change-point segmentation, optcal.core.recording.segment), on simulated
recordings with known poses and on the real corpus (tests/corpus.py: ``OPTCAL_CORPUS``, else the shared folder
beside the clone). Prints the tables of docs/segmentation.md.

    .venv/bin/python docs/scripts/segmentation_scores.py

Simulated: optcal.core.synthetic_recording, 100 Hz, 12 random poses, five seeds per case. A found interval is a true
positive when it overlaps one true rest by at least half its own length and lies inside it but for 0.3 s
(30 samples) at each end; a rest is recalled when a true positive lies in it; IoU is that of the static
samples. Real: the references are sections people chose inside their poses (shorter than the rests), so
there a reference section counts as found when at least 90 % of it lies in found intervals, and a found
interval is a hit when it overlaps a reference section ("extra" intervals are often real poses the
reference leaves out). Runs in about a minute.
"""

from __future__ import annotations

import gzip
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from optcal.app.workflows.recording import choose_threshold
from optcal.core.errors import InputError
from optcal.core.recording import interval_scores, label_intervals, read_recording, segment_static
from optcal.core.synthetic_recording import poses_recording, tumble_recording

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

DATA = corpus_root()
TOL = 30
SEEDS = range(5)


def old(rec, model="linear9"):
    """The former default: the variance detector with imu_tk's threshold search k = 2…10."""
    try:
        return choose_threshold(rec, model).intervals
    except InputError:
        return np.zeros((0, 2), np.int64)


def new(rec, **kw):
    return segment_static(rec, **kw).intervals


CASES = {
    "3 s poses, 90 °/s turns": dict(hold_s=3.0),
    "1 s poses, 90 °/s turns": dict(hold_s=1.0),
    "0.5 s poses, 90 °/s turns": dict(hold_s=0.5),
    "1 s poses, steps (no motion)": dict(hold_s=1.0, motion="step"),
    "3 s poses, steps (no motion)": dict(hold_s=3.0, motion="step"),
    "3 s poses, 10 mg + 1 mg flicker": dict(hold_s=3.0, noise_g=1e-2, flicker_g=1e-3),
    "3 s poses, clipped at 0.9 g, 0.1 % drops": dict(hold_s=3.0, clip_g=0.9, drop_fraction=1e-3),
}


def simulated():
    print("| case | detector | precision | recall | IoU | intervals found / true |")
    print("|---|---|---|---|---|---|")
    for name, kw in CASES.items():
        rows = {"old": [], "new": []}
        for seed in SEEDS:
            syn = poses_recording(np.random.default_rng(seed), **kw)
            rec = syn.recording
            if kw.get("drop_fraction"):  # the variance detector cannot take NaN: drops as saturated samples
                rec_old = type(rec)(rec.t, np.nan_to_num(rec.N), None, rec.units, rec.rate,
                                    rec.saturated | ~np.isfinite(rec.N).all(axis=1), rec.path)
            else:
                rec_old = rec
            for det, iv in (("old", old(rec_old)), ("new", new(rec, min_static_s=min(0.5, kw["hold_s"])))):
                rows[det].append(interval_scores(iv, syn.rests, len(rec), TOL))
        for det, sc in rows.items():
            p = np.mean([s["precision"] for s in sc])
            r = np.mean([s["recall"] for s in sc])
            iou = np.mean([s["iou"] for s in sc])
            nf = sum(s["n_found"] for s in sc)
            nt = sum(s["n_true"] for s in sc)
            print(f"| {name} | {det} | {p:.3f} | {r:.3f} | {iou:.3f} | {nf} / {nt} |")


def tumbles():
    print("\n| tumble (60 s, 2 mg white + 0.5 mg flicker) | detector | runs with any interval | intervals "
          "found (5 runs) | intervals outside a pause |")
    print("|---|---|---|---|---|")
    for rate in (0.5, 1.0, 2.0, 5.0, 10.0, 20.0):
        for pauses in (0, 3):
            out = {"old": [0, 0, 0], "new": [0, 0, 0]}
            for seed in SEEDS:
                syn = tumble_recording(np.random.default_rng(seed), turn_rate_dps=rate, pauses=pauses,
                                       flicker_g=5e-4)
                rec = syn.recording
                for det, iv in (("old", old(rec, "diag6")), ("new", new(rec))):
                    sc = interval_scores(iv, syn.rests, len(rec), TOL)
                    out[det][0] += len(iv) > 0
                    out[det][1] += len(iv)
                    out[det][2] += sc["n_false"]
            label = f"{rate:g} °/s" + (f", {pauses} pauses of 2 s" if pauses else "")
            for det, (runs, n, false) in out.items():
                print(f"| {label} | {det} | {runs} / 5 | {n} | {false} |")


def _loadmat(path):
    from scipy.io import loadmat

    m = loadmat(path)
    (a,) = [v for k, v in m.items() if not k.startswith("__")]
    return a.T if a.shape[0] == 3 else a


def _real_scores(found, ref, n):
    found = np.asarray(found).reshape(-1, 2)
    ov = np.clip(np.minimum(found[:, None, 1], ref[None, :, 1]) - np.maximum(found[:, None, 0], ref[None, :, 0]),
                 0, None)
    covered = ov.sum(axis=0) / (ref[:, 1] - ref[:, 0])
    hits = (ov > 0).any(axis=1)
    a, b = np.zeros(n, bool), np.zeros(n, bool)
    for s, e in found:
        a[s:e] = True
    for s, e in ref:
        b[s:e] = True
    return {"found": len(found), "ref": len(ref), "ref_found": int((covered >= 0.9).sum()),
            "hits": int(hits.sum()), "iou": float((a & b).sum() / max((a | b).sum(), 1))}


def real():
    tmp = Path(tempfile.mkdtemp())
    sets = []
    # imucal: labelled six-position session (label column "part"), 204.8 Hz counts
    rec = read_recording(DATA / "imucal" / "annotated_session.csv", columns="acc_x,acc_y,acc_z", rate=204.8,
                         units="counts", labels="part")
    poses = ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"]
    sets.append(("imucal labelled session (6 labelled poses)", rec, label_intervals(rec, poses).intervals, "diag6"))
    # imucal: continuous session with its section list
    rec = read_recording(DATA / "imucal" / "example_ferraris_session.csv", rate=102.4, units="m/s2")
    sec = json.loads((DATA / "imucal" / "example_ferraris_session_list.json").read_text())
    ref = np.array([[v["start"], v["end"]] for k, v in sec.items() if not k.endswith("_rot")])
    sets.append(("imucal continuous session (6 listed sections)", rec, ref, "diag6"))
    # MPU-6050: static_intervals.csv (inclusive ends)
    rec = read_recording(DATA / "mpu6050" / "example_data_calibration.csv", units="counts")
    ref = np.loadtxt(DATA / "mpu6050" / "static_intervals.csv", delimiter=",").T.astype(int)
    ref[:, 1] += 1
    sets.append(("MPU-6050 hand-turned (10 reference intervals)", rec, ref, "diag6"))
    # Hassan & Bao phone: their 30 hand-picked sections (CombinedAlgorithm.m; 1-based inclusive)
    from test_corpus import HB_PHONE_IV  # the sections as the corpus tests state them

    a = _loadmat(DATA / "hassan_bao" / "MobileAccData30orientationRawSample01.mat")
    p = tmp / "phone.csv"
    np.savetxt(p, a, delimiter=",", header="ax,ay,az", comments="", fmt="%.17g")
    rec = read_recording(p, rate=50.0, units="m/s2")
    sets.append(("Hassan & Bao phone, hand-held (30 sections; 50 Hz assumed)", rec, HB_PHONE_IV, "diag6"))
    # imu_tk's Xsens recording: no reference intervals (counts only)
    x = tmp / "xsens.mat"
    x.write_bytes(gzip.decompress((DATA / "imu_tk" / "xsens_acc.mat.gz").read_bytes()))
    xs = read_recording(x, units="counts", saturation=65535)

    print("\n| recording | detector | intervals found | reference sections found (≥ 90 % covered) | found "
          "intervals on a section | IoU of static samples |")
    print("|---|---|---|---|---|---|")
    for name, rec, ref, model in sets:
        for det, iv in (("old", old(rec, model)), ("new", new(rec))):
            sc = _real_scores(iv, ref, len(rec))
            print(f"| {name} | {det} | {sc['found']} | {sc['ref_found']} / {sc['ref']} | {sc['hits']} / "
                  f"{sc['found']} | {sc['iou']:.2f} |")
    print(f"| imu_tk Xsens MTi (no reference) | old | {len(old(xs))} | – | – | – |")
    print(f"| imu_tk Xsens MTi (no reference) | new | {len(new(xs))} | – | – | – |")


def timing():
    syn = poses_recording(np.random.default_rng(0), n_poses=400, hold_s=8.0)
    rec = syn.recording
    segment_static(rec)  # imports ruptures
    t0 = time.perf_counter()
    segment_static(rec)
    t_new = time.perf_counter() - t0
    t0 = time.perf_counter()
    old(rec)
    t_old = time.perf_counter() - t0
    print(f"\n{len(rec)} samples (1 h at 100 Hz, 400 poses): segmentation {t_new:.2f} s, variance detector with "
          f"the threshold search (9 linear9 fits) {t_old:.2f} s")


if __name__ == "__main__":
    simulated()
    tumbles()
    real()
    timing()
