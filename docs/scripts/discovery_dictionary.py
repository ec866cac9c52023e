"""The measurements of docs/discovery.md's sections on the dictionary, the diagnostics and the real recordings
(issue 31): the hidden effects outside the list (named in how many of 20 seeds, the residual against the
effect-free one), the false-discovery rate on effect-free data, the simulated example's report and figures, and
``optcal discover`` on every recording of the real corpus (tests/corpus.py: ``OPTCAL_CORPUS``, else the shared
folder beside the clone), with the diagnostics' figure of one.

    .venv/bin/python docs/scripts/discovery_dictionary.py [effects] [null] [diagnostics] [example] [corpus]
                     [--seeds 20] [--null-seeds 200] [--figures docs/figures]

With no section named, all five. Prints Markdown tables and reports; writes discovery_dictionary_example.png,
discovery_dictionary_steps.png and discovery_real_hassan_bao_49.png into --figures.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from optcal.app.cli import main as cli
from optcal.app.workflows.discovery import discover, fit_model
from optcal.core.model import get_model

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder
from test_discovery_dictionary import EFFECTS, NOISE, hidden, named  # noqa: E402  the tests' effects and data

U = 1e6
MIKOV = ["--raw", "--units", "m/s2", "--gravity-ms2", "9.81", "--rate", "100", "--columns", "ax=0,ay=1,az=2"]
# Every recording of the real corpus with the options of its default command (tests/test_corpus_wild.py's CORPUS)
CORPUS = {
    "imucal labelled": ("imucal/annotated_session.csv",
                        ["--raw", "--units", "counts", "--rate", "204.8", "--gravity-ms2", "9.81"]),
    "imucal continuous": ("imucal/example_ferraris_session.csv",
                          ["--raw", "--units", "m/s2", "--rate", "102.4", "--gravity-ms2", "9.81"]),
    "MPU-6050": ("mpu6050/example_data_calibration.csv", ["--raw", "--units", "counts"]),
    "Xsens MTi (imu_tk)": ("imu_tk/xsens_acc.mat.gz", ["--raw", "--units", "counts", "--gravity-ms2", "9.81744"]),
    "Hassan & Bao 24": ("hassan_bao/CalibrationOfLowCostTriaxialInertialSensors.mat", ["--units", "g"]),
    "Hassan & Bao 49": ("hassan_bao/CalibrationOfLowCostTriaxialInertialSensors50.mat", ["--units", "g"]),
    "Hassan & Bao phone": ("hassan_bao/MobileAccData30orientationRawSample01.mat",
                           ["--raw", "--units", "m/s2", "--rate", "50"]),
    **{f"Mikov imu{i}": (f"mikov/imu{i}.log.gz", MIKOV) for i in range(5)},
    "CK-Explorer": ("ck_explorer/acc_log.csv", ["--raw", "--units", "g", "--rate", "100"]),
    "TWLogger": ("twlogger/T1D0711-00.CSV.gz", ["--raw", "--units", "counts", "--gravity-ms2", "9.81"]),
    "sensor-fusion full sphere": ("sunsided/full_sphere_accelerometer.mat", ["--raw", "--units", "g"]),
    "sensor-fusion tilt sphere": ("sunsided/tilt_sphere_accelerometer.mat", ["--raw", "--units", "g"]),
    "shen_gesture": ("shen_gesture/caldata.mat", ["--raw", "--units", "counts", "--columns", "0,1,2,3"]),
    "sdr_rev2 long": ("sdr_rev2/IMU_Rev2_Data_Long.txt.gz", ["--raw", "--units", "m/s2", "--columns", "0,1,2,3"]),
    "sdr_rev2 short": ("sdr_rev2/IMU_Rev2_Data_Short.txt.gz", ["--raw", "--units", "m/s2", "--columns", "0,1,2,3"]),
}
FIGURE_OF = "Hassan & Bao 49"


def effects(seeds: int) -> None:
    """Each hidden effect in ``seeds`` seeds: named (alone), the residual within 1.3 × the effect-free one."""
    print("\n| effect (term) | formula | named (alone) | gap closed | base RMS | final RMS | effect-free RMS | "
          "seconds |")
    print("|---|---|---|---|---|---|---|---|")
    from optcal.core.model import TERMS

    for term in EFFECTS:
        got = alone = closed = 0
        base, final, free = [], [], []
        t0 = time.perf_counter()
        for seed in range(seeds):
            _, data = hidden(term, seed)
            _, clean = hidden(None, seed)
            rep = discover(data, noise_g=NOISE)
            ok = any(named(s.kept, term) for s in rep.found)
            ref = fit_model(get_model("linear9"), clean, 1.0).rms
            got += ok
            alone += ok and len(rep.added) == 1
            closed += ok and rep.final.rms <= 1.3 * ref
            base.append(rep.initial.rms)
            final.append(rep.final.rms)
            free.append(ref)
        sec = (time.perf_counter() - t0) / seeds
        med = lambda v: f"{statistics.median(v) * U:.1f} µg"  # noqa: E731
        print(f"| `{term}` | {TERMS[term].description} | {got}/{seeds} ({alone}) | {closed}/{seeds} | {med(base)} "
              f"| {med(final)} | {med(free)} | {sec:.2f} |")


def null(seeds: int) -> None:
    """Effect-free data: how often anything is named (by the list or the dictionary)."""
    listed = dictionary = partial = anything = 0
    for seed in range(seeds):
        _, data = hidden(None, 5000 + seed)
        rep = discover(data, noise_g=NOISE)
        listed += any(s.source == "list" for s in rep.steps if s.kept in rep.final_model.terms)
        dictionary += bool(rep.found)
        partial += bool(rep.partial)
        anything += bool(rep.added or rep.partial)
    print(f"\neffect-free, {seeds} seeds of 40 random poses with temperature and time: anything named in "
          f"{anything} ({anything / seeds:.1%}): a list term in {listed}, a dictionary term in {dictionary}, a term "
          f"reported as not closing the gap in {partial}")


def diagnostics(seeds: int) -> None:
    """The diagnostics' two tests: on the product effect of the tests (seed 0) each diagnostic's p against the
    floor and against the residual left; on effect-free data with 30 µg of white noise beyond the stated 10 µg
    (and at the true floor, 31.6 µg), how often each diagnostic's p falls below 0.01."""
    from optcal.core.discovery.diagnostics import diagnose, floor_of
    from optcal.core.discovery.dictionary import feature_context

    _, data = hidden("ax.ay@z", 0)
    rep = discover(data, noise_g=NOISE)
    print("\nax.ay@z, seed 0, after the list: p against the floor / against the residual left / the larger")
    for d in rep.diagnostics_listed.items:
        if d.tested:
            print(f"    {d.name:12s} {d.extra['p_floor']:.2g} / {d.extra['p_residual']:.2g} / {d.p_value:.2g}")
    names, low = None, {"stated 10 µg": [], "true 31.6 µg": []}
    for seed in range(seeds):
        _, data = hidden(None, seed)
        rng = np.random.default_rng(100 + seed)
        data = dataclasses.replace(data, N=data.N + 30e-6 * rng.standard_normal(data.N.shape))
        fit = fit_model(get_model("linear9"), data, 1.0)
        for label, sigma in (("stated 10 µg", NOISE), ("true 31.6 µg", np.hypot(NOISE, 30e-6))):
            dg = diagnose(fit, data, floor_of(fit, np.full(len(data), sigma), True), 0.01, feature_context(data))
            tested = [d for d in dg.items if d.tested]
            names = [d.name for d in tested]
            low[label].append([d.p_value < 0.01 for d in tested])
    print(f"\n{seeds} seeds, 40 random poses, 30 µg of white noise beyond 10 µg: share of p < 0.01")
    for label, rows in low.items():
        share = np.mean(rows, axis=0)
        print(f"    floor {label}: " + ", ".join(f"{n} {v:.1%}" for n, v in zip(names, share)))


def example(figures: Path) -> None:
    """The oscillating bias of the tests (seed 1): its report, the diagnostics' and the steps' figures."""
    _, data = hidden("osc600@x", 1)
    rep = discover(data, noise_g=NOISE)
    print("\n### simulated: bias_x oscillating with a 10-minute period, 40 positions, 10 µg noise (given)\n")
    print(rep.summary())
    rep.plot_diagnostics(figures / "discovery_dictionary_example.png")
    rep.plot(figures / "discovery_dictionary_steps.png")


def _discover(path: Path, args: list[str], base: str, extra=()) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli(["discover", str(path), *args, "--base", base, *extra])
    return code, out.getvalue(), err.getvalue()


def corpus(figures: Path) -> None:
    """``optcal discover`` on every recording, base linear9 (diag6 where the poses are too few for it)."""
    root = corpus_root()
    print("\n| recording | positions | base | RMS before → after | floor | list | dictionary | verdict | "
          "diagnostics significant |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, (rel, args) in CORPUS.items():
        for base in ("linear9", "diag6"):
            code, out, err = _discover(root / rel, args, base, ["--json"])
            if code == 0:
                break
        if code != 0:
            print(f"| {name} | | | refused: {err.strip().split(': error: ')[-1]} | | | | | |")
            continue
        d = json.loads(out)
        floor = d["floor"]
        fl = "none" if floor["kind"] is None else f"{floor['kind']} {floor['sigma_g'] * U:.0f} µg"
        steps = [s["added"] for s in d["steps"] if s["source"] == "list"]
        found = [f["term"] for f in d["found"]]
        part = [p["term"] for p in d["partial"]]
        removed = [f"{r['term']} ({r['kind']})" for r in d["removed"]]
        dic = ", ".join(f"`{t}`" for t in found) or ("nearest " + ", ".join(f"`{t}`" for t in part) + ", not closing"
                                                     if part else "—")
        if removed:
            dic += "; " + ", ".join(removed)
        sig = [x["name"] for x in d["diagnostics_listed"]["items"] if x.get("significant")]
        print(f"| {name} | {d['n_positions']} | {d['base']} | {d['rms_initial_g'] * U:.0f} → "
              f"{d['rms_final_g'] * U:.0f} µg | {fl} | {', '.join(steps) or '—'} | {dic} | {d['verdict']} | "
              f"{', '.join(sig) or '—'} |")
    rel, args = CORPUS[FIGURE_OF]
    code, out, _ = _discover(root / rel, args, "linear9",
                             ["--diagnostics", str(figures / "discovery_real_hassan_bao_49.png"), "--force"])
    print(f"\n### {FIGURE_OF}, base linear9\n")
    print(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sections", nargs="*", metavar="SECTION",
                    help="effects, null, diagnostics, example, corpus (default: all)")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--null-seeds", type=int, default=200)
    ap.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures")
    args = ap.parse_args(argv)
    sections = ("effects", "null", "diagnostics", "example", "corpus")
    bad = sorted(set(args.sections) - set(sections))
    if bad:
        ap.error(f"unknown section(s) {', '.join(bad)}; choose from {', '.join(sections)}")
    args.sections = args.sections or list(sections)
    np.seterr(all="ignore")
    if "effects" in args.sections:
        effects(args.seeds)
    if "null" in args.sections:
        null(args.null_seeds)
    if "diagnostics" in args.sections:
        diagnostics(args.null_seeds)
    if "example" in args.sections:
        example(args.figures)
    if "corpus" in args.sections:
        corpus(args.figures)


if __name__ == "__main__":
    main()
