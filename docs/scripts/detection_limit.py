"""Measure the discovery workflow's detection limits and false-addition rates (docs/discovery.md).

For each candidate term, the smallest effect size at which ``optcal.discover`` names the term in at least
90 % of seeds, found by bisection (in log size) over sizes, each size run on the same seeds (common random
numbers: a seed fixes the truth, the orientations and the noise, so the rate rises with the size). Also the
rate at which anything is added to data without a hidden effect. Prints markdown tables.

    .venv/bin/python docs/scripts/detection_limit.py --seeds 40 --null-seeds 200 [--terms cubic,...]

The data are made as in tests/test_discovery.py (``hidden``): 10 µg noise per axis on each position's
mean, a linear9 truth drawn per seed, the effect with size s on every parameter of the term and alternating
signs (+s, −s, +s, ...). For the temperature and time terms (30 random orientations) the temperature
set-points are visited in a random order, since simulate()'s linear ramp over equally spaced positions
makes T − T0 and t − t0 proportional (the two would be the same regressor).

These are the list's limits: the search of the candidate terms alone (``dictionary=False``); the dictionary's
search that follows it by default is measured by docs/scripts/discovery_dictionary.py.
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import sys
import time

import numpy as np

from optcal import simulate
from optcal.app.workflows.discovery import discover
from optcal.core.discovery import DEFAULT_ALPHA, DEFAULT_BIC_THRESHOLD
from optcal.core.model import TERMS
from optcal.core.presets import draw_truth

NOISE = 10e-6
PATTERN = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0)
# term: (scheme, base, starting size (named in every test seed), temperature and time columns)
TERMS_TABLE = {
    "quadratic": ("36", "linear9", 1.5e-4, False),
    "cubic": ("24", "linear9", 2e-4, False),
    "scale_asymmetry": ("36", "linear9", 5e-4, False),
    "cross_coupling": ("24", "linear9", 1.2e-4, False),
    "temperature_bias": ("random:30", "linear9", 8e-6, True),
    "temperature_scale": ("random:30", "linear9", 1.5e-5, True),
    "bias_drift": ("random:30", "linear9", 2.5e-7, True),
    "misalignment": ("24", "diag6", 1.2e-4, False),
}
UNITS = {"quadratic": "g/g²", "cubic": "g/g³", "scale_asymmetry": "", "cross_coupling": "1/g",
         "temperature_bias": "g/°C", "temperature_scale": "1/°C", "bias_drift": "g/s", "misalignment": "rad"}


def effect(term, size):
    return {p: size * PATTERN[k] for k, p in enumerate(TERMS[term].params)}


def hidden(effects, scheme, seed, base="linear9", columns=False):
    rng = np.random.default_rng(seed)
    truth = draw_truth(base, rng)
    kw = {"temp": (20.0, 40.0), "times": True} if columns else {}
    sim = simulate(base, truth, rng, scheme=scheme, noise_g=NOISE, effects=effects, **kw)
    data = sim.data
    if columns:
        if any("t" in TERMS[t].needs for t in effects):
            data = dataclasses.replace(data, temp=rng.permutation(data.temp))
        else:
            data = dataclasses.replace(data.subset(rng.permutation(len(data))), t=data.t)
    return data


class Counter:
    runs = 0


def rate(term, size, seeds):
    """Per size: the fraction of seeds that name the term (named), that name exactly it (exact), that
    add anything (any), the mean base RMS / noise (lift), and the terms named instead of it (wrong)."""
    scheme, base, _, columns = TERMS_TABLE[term]
    out = {"named": 0.0, "exact": 0.0, "any": 0.0, "lift": 0.0, "wrong": collections.Counter()}
    for seed in range(seeds):
        rep = discover(hidden({term: effect(term, size)}, scheme, seed, base, columns), base=base, noise_g=NOISE,
                       dictionary=False)
        Counter.runs += 1
        out["named"] += (term in rep.added) / seeds
        out["exact"] += (rep.added == [term]) / seeds
        out["any"] += bool(rep.added) / seeds
        out["lift"] += rep.initial.rms / NOISE / seeds
        out["wrong"].update(t for t in rep.added if t != term)
    return out


def limit(term, seeds, target=0.9, resolution=1.1):
    """Bisection in log size between a size below the limit and one at or above it."""
    start = TERMS_TABLE[term][2]
    hi, r_hi = start, rate(term, start, seeds)
    while r_hi["named"] < target:
        hi *= 2
        r_hi = rate(term, hi, seeds)
    lo = hi / 4
    r_lo = rate(term, lo, seeds)
    while r_lo["named"] >= target:
        hi, r_hi = lo, r_lo
        lo /= 4
        r_lo = rate(term, lo, seeds)
    while hi / lo > resolution:
        mid = np.sqrt(hi * lo)
        r = rate(term, mid, seeds)
        if r["named"] >= target:
            hi, r_hi = mid, r
        else:
            lo, r_lo = mid, r
    return hi, r_hi, lo, r_lo


def null_rate(scheme, columns, seeds, base="linear9"):
    added = 0
    for seed in range(seeds):
        rep = discover(hidden({}, scheme, 10_000 + seed, base, columns), base=base, noise_g=NOISE, dictionary=False)
        Counter.runs += 1
        added += bool(rep.added)
    return added


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=40, help="seeds per effect size (default 40)")
    ap.add_argument("--null-seeds", type=int, default=200, help="seeds per scheme without an effect (200)")
    ap.add_argument("--terms", help="comma-separated subset of the terms")
    ap.add_argument("--out", help="also write the tables to this file")
    args = ap.parse_args(argv)
    terms = args.terms.split(",") if args.terms else list(TERMS_TABLE)
    t0 = time.perf_counter()
    lines = [f"Settings: α = {DEFAULT_ALPHA} (Bonferroni over the candidates tested per step), ΔBIC < "
             f"{DEFAULT_BIC_THRESHOLD}, noise {NOISE * 1e6:g} µg per axis; effect sizes to a 10 % step "
             f"(bisection in log size); {args.seeds} seeds per size.", "",
             "| term | scheme (base) | 90 % limit s₉₀ | at s₉₀: named (exactly) | at s₉₀: anything added "
             "| base RMS / noise at s₉₀ | just below: size, named, anything added | named instead (at both) | runs |",
             "|---|---|---|---|---|---|---|---|---|"]
    for term in terms:
        before = Counter.runs
        hi, r_hi, lo, r_lo = limit(term, args.seeds)
        scheme, base, _, _ = TERMS_TABLE[term]
        unit = f" {UNITS[term]}" if UNITS[term] else ""
        wrong = r_hi["wrong"] + r_lo["wrong"]
        wrong_txt = ", ".join(f"{t} ×{n}" for t, n in wrong.most_common()) or "none"
        lines.append(f"| {term} | {scheme} ({base}) | {hi:.3g}{unit} | {r_hi['named']:.0%} ({r_hi['exact']:.0%}) | "
                     f"{r_hi['any']:.0%} | {r_hi['lift']:.2f} | {lo:.3g}, {r_lo['named']:.0%}, {r_lo['any']:.0%} | "
                     f"{wrong_txt} | {Counter.runs - before} |")
        print(lines[-1], file=sys.stderr, flush=True)
    lines += ["", f"No hidden effect ({args.null_seeds} seeds per scheme, linear9 truth):", "",
              "| scheme | candidates tested | runs with any term added | rate |", "|---|---|---|---|"]
    if args.null_seeds:
        for scheme, columns, k in (("24", False, 4), ("36", False, 4), ("random:30", True, 7)):
            n = null_rate(scheme, columns, args.null_seeds)
            cols = " with temp, t" if columns else ""
            lines.append(f"| {scheme}{cols} | {k} | {n} of {args.null_seeds} | {n / args.null_seeds:.1%} |")
            print(lines[-1], file=sys.stderr, flush=True)
    lines += ["", f"{Counter.runs} discover runs, {time.perf_counter() - t0:.0f} s."]
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
