"""The labelled benchmark of rest detection (issue #29, item 8): recall of labelled rests and precision by sample
of the old detection (segment_static, the accelerometer alone), the variance detector with its threshold search
(choose_threshold, model diag6) and the new detection (segment_static with its defaults, judging the
accelerometer and the gyroscope: tests/test_rest_labels.py's find_rests) on every labelled recording of the real
corpus and on simulated hand-held IMU recordings. Prints one markdown table to stdout (for
docs/segmentation.md).

    .venv/bin/python docs/scripts/rest_benchmark.py
    .venv/bin/python docs/scripts/rest_benchmark.py --slow-line

The second prints how the new detection scores against the gyroscope's labels made with other values of their
attitude line (optcal.core.recording.labels.SLOW_DEG, 0.2° by default), one row per recording with a gyroscope.

The corpus: where tests/corpus.py finds it (OPTCAL_CORPUS, else its default beside the clone); its
labelled recordings and their labels are tests/test_rest_labels.py's LABELLED table. Labels (independent of
all three detectors) and scores are optcal.core.recording.labels': the gyroscope's stillness where there is a
gyroscope, and the source's own intervals where it gives them (their precision by the gyroscope's labels, or
without a gyroscope by the conservative off-pose rule). A labelled rest (at least 0.5 s) is recalled when the
kept intervals attributed to it (each to the labelled rest it overlaps most) cover at least half of it;
precision by sample is the fraction of kept samples labelled still.

Simulated: optcal.core.synthetic_imu.handheld_imu, 20 poses at 100 Hz unless said, five seeds per case (pooled:
rests and samples summed; time per recording), scored against the simulator's truth; the row "gyroscope
labels" is the labeller itself against that truth.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from corpus import corpus_present, corpus_root  # noqa: E402
from test_rest_labels import (  # noqa: E402
    LABELLED,
    MIN_STATIC_S,
    SIM_CASES,
    UNLABELLED,
    find_rests,
)

import optcal.core.recording.labels as labels  # noqa: E402
from optcal.app.workflows.recording import choose_threshold  # noqa: E402
from optcal.core.errors import InputError  # noqa: E402
from optcal.core.recording import segment_static  # noqa: E402
from optcal.core.recording.labels import gyro_labels, interval_labels, score_rests  # noqa: E402
from optcal.core.synthetic_imu import handheld_imu  # noqa: E402

SEEDS = range(5)
NEW = "new"


def _old(acc, gyro):  # issue #20's segmentation, the accelerometer alone
    return segment_static(acc, gyro=False, refine=False).intervals


def _variance(acc, gyro):
    try:
        return choose_threshold(acc, "diag6").intervals
    except InputError:  # too few intervals at every threshold
        return np.zeros((0, 2), np.int64)


def _new(acc, gyro):
    return find_rests(acc, gyro).intervals


DETECTORS = {"old": _old, "variance (diag6)": _variance, NEW: _new}


def _run(det, acc, gyro):
    t0 = time.perf_counter()
    try:
        iv = det(acc, gyro)
    except InputError:
        iv = np.zeros((0, 2), np.int64)
    return np.asarray(iv, np.int64).reshape(-1, 2), time.perf_counter() - t0


def _row(name, source, det, scores, seconds):
    lab = sum(s["n_labelled"] for s in scores)
    rec = sum(s["n_recalled"] for s in scores)
    found = sum(s["n_found"] for s in scores)
    kept = sum(s["kept_samples"] for s in scores)
    moving = sum(s["moving_kept_samples"] for s in scores)
    recall = f"{rec / lab:.3f}" if lab else "–"
    precision = f"{1 - moving / kept:.4f}" if kept else "–"
    print(f"| {name} | {source} | {det} | {lab} | {found} | {recall} | {precision} | {seconds:.3f} |")


def real():
    for load in LABELLED.values():
        case = load(corpus_root())
        found = {det: _run(fn, case.acc, case.gyro) for det, fn in DETECTORS.items()}
        for source, lab in case.labels.items():
            for det, (iv, sec) in found.items():
                _row(case.name, source, det, [score_rests(iv, lab, min_static=case.min_static)], sec)


def simulated():
    for case, kw in SIM_CASES.items():
        rows = {det: ([], 0.0) for det in [*DETECTORS, "gyroscope labels"]}
        for seed in SEEDS:
            s = handheld_imu(np.random.default_rng(seed), **kw)
            truth = interval_labels(s.rests, len(s.acc), still=s.still, source="truth")
            m = max(1, int(round(MIN_STATIC_S * s.acc.rate)))
            for det, fn in [*DETECTORS.items(), ("gyroscope labels", lambda a, g: gyro_labels(g, a).rests)]:
                iv, sec = _run(fn, s.acc, s.gyro)
                scores, total = rows[det]
                rows[det] = (scores + [score_rests(iv, truth, min_static=m)], total + sec)
        for det, (scores, total) in rows.items():
            _row(f"simulated hand-held: {case}", "truth", det, scores, total / len(SEEDS))


SLOW_LINES = (0.15, 0.2, 0.25, 0.3, 0.4)  # °


def slow_line():
    """Recall / precision of the new detection against gyroscope labels made with each of SLOW_LINES."""
    print("| recording | " + " | ".join(f"labels at {d}°" for d in SLOW_LINES) + " |")
    print("|---|" + "---|" * len(SLOW_LINES))
    default = labels.SLOW_DEG
    try:
        for load in LABELLED.values():
            case = load(corpus_root())
            lab = case.labels.get("gyroscope")
            if lab is None:
                continue
            found = find_rests(case.acc, case.gyro).intervals
            cells = []
            for d in SLOW_LINES:
                labels.SLOW_DEG = d
                sc = score_rests(found, gyro_labels(case.gyro, case.acc, units_per_dps=lab.info["units_per_dps"]),
                                 min_static=case.min_static)
                met = sc["recall"] >= 0.95 and sc["precision"] >= 0.99
                cell = f"{sc['recall']:.3f} / {sc['precision']:.4f}"
                cells.append(f"**{cell}**" if met else cell)
            print(f"| {case.name} | " + " | ".join(cells) + " |")
    finally:
        labels.SLOW_DEG = default
    print("\n(bold: both targets met)")


if __name__ == "__main__" and sys.argv[1:] == ["--slow-line"]:
    slow_line()
elif __name__ == "__main__":
    print("| recording | labels | detector | rests labelled | found | recall | precision by sample | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    if corpus_present():
        real()
    else:
        print(f"| (the real corpus is absent: {corpus_root()}) | | | | | | | |")
    simulated()
    print(f"\nNot labelled: {'; '.join(f'{k} ({v})' for k, v in UNLABELLED.items())}.")
