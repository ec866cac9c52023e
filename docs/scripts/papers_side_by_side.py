"""The papers side by side (docs/studies.md, "The papers side by side"): every number the 2020 BSAS paper
(Wang et al., Sensors 20(4), 2020) and the 2015 NAFSA paper (Gao, Guan & Wang, Journal of Sensors 2015,
509143) print where their text copies kept it, beside optcal's in the same setup or with the difference
named, and the tables of the bsas2020 and nafsa2015 studies.

What it computes:
  * the Cramér-Rao bound of the 2020 paper's simulation (seed15, 24 positions, the paper's truth, 10 µg per
    axis on each position's mean; optcal.core.analysis.crlb) against the magnitudes of its Table 3, and the
    noise those magnitudes imply: per position mean, σ = 10 µg · RMSE / CRLB (the bound is linear in σ),
    or, if the 10 µg were per sample, the samples each position would have to average, (CRLB / RMSE)²;
  * the noise the paper's final cost (its Figure 5) implies, under each reading of its Eq. 13 whose
    operator the copy lost (Σe² in g² or in (m/s²)², or Σ|e| in g), from the residual degrees of freedom
    and the leverages at the truth;
  * the bsas2020 and nafsa2015 studies through optcal.study (serial, so that each trial's time is its own),
    the per-parameter RMSE of staged BSAS, and the same with presets at the truth (presets_error_scale =
    1e-3);
  * on run 0's data of each study: the final cost of staged BSAS and BAS over many solver seeds (the 2020
    Figures 5 and 6), the cost after each stage for m = 10, 6, 2 beetles (its Figure 3), the 2015 MCS
    standard deviations (the SD of mcs:staged:*'s runs, ``extra["x_runs"]``, its Table 3) and the per-iteration
    convergence of
    the scale-factor stage (its Figure 5).

    .venv/bin/python docs/scripts/papers_side_by_side.py            # the documented size (about 3.5 min)
    .venv/bin/python docs/scripts/papers_side_by_side.py --small    # the test's size (about 10 s)
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import math
import time

import numpy as np

import optcal
from optcal.core.analysis import crlb, hat_values, projected_crlb
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.problem import CalibrationProblem, Counter
from optcal.core.simulate import simulate
from optcal.studies import spec as specs
from optcal.studies.metrics import groups
from optcal.studies.trial import SOLVER, key, stream, trial_budget, trials, world

NOISE_UG = 10.0  # 2020 §4.1: "the random bias of accelerometer is set as 10 ug"
G0 = 9.80665  # m/s² per g
N_POSITIONS = 24
FAMILIES = ("K", "b", "S", "K2")
UNIT = {"K": "", "b": " g", "S": " rad", "K2": " /g"}

# The 2020 paper's Table 3 (its §4.2, the paragraph before the table; the copy lost the minus signs of the
# exponents): "the accuracy of scale factors is 10^-5 in magnitude, the accuracy magnitude of biases can reach
# 10^-7 ~ 10^-8, ... installation angle errors ... 10^-5 ~ 10^-6, ... second-order nonlinear scale factors ...
# 10^-6 ~ 10^-7"; "The standard deviation magnitude of 15 calibration parameters ... 10^-5 ~ 10^-9".
TABLE3_RMSE = {"K": (1e-5, 1e-5), "b": (1e-8, 1e-7), "S": (1e-6, 1e-5), "K2": (1e-7, 1e-6)}
# Final costs: Figure 3 (§4.1, after 300 iterations, the four categories in order) and Figure 5 (§4.2).
FIG3_COSTS = {10: (8.365e-7, 7.564e-7, 8.112e-7, 7.344e-7), 6: (3.262e-6, 1.545e-6, 2.036e-6, 1.134e-6),
              2: (6.112e-4, 6.335e-6, 4.513e-6, 1.620e-6)}
FIG5_BSAS = (7.2e-7, 7.4e-7)
FIG6_BAS = (2e-2, 3.5e-2)
# The 2015 paper's Table 3 (§6.2): SDs of the 100 MCS runs, scale factors (volt/g) and biases (printed as
# volt/g too: a bias in volt, which is how this script reads it); the angles' and quadratic terms' SDs were lost.
SD2015_K = (0.06787, 0.07613, 0.05935)
SD2015_B = (0.001124, 0.000995, 0.001011)
CONVERGENCE_AT = (1, 2, 5, 10, 20, 24, 30, 60)
STAGE1_ITERATIONS = 60  # the fish swarms' default generations per category (the spec's setting)


def sci(v: float, digits: int = 3) -> str:
    """``v`` in scientific notation, ``digits`` significant digits, no padding: 1.12e-5, 2e-2."""
    m, e = f"{v:.{digits - 1}e}".split("e")
    if "." in m:
        m = m.rstrip("0").rstrip(".")
    return f"{m}e{int(e)}"


def fmt(v: float, digits: int = 3) -> str:
    """A number to ``digits`` significant digits, in scientific notation below 1e-3 and from 1e4."""
    if v is None or not math.isfinite(v):
        return "–"
    text = f"{v:.{digits}g}"
    if v != 0 and (abs(v) < 1e-3 or abs(v) >= 1e4 or "e" in text):
        return sci(v, digits)
    return text


def mag(v: float) -> str:
    """A power of ten as the paper prints it: 1e-7."""
    return f"1e{round(math.log10(v))}"


def secs(v: float) -> str:
    return f"{v:#.2g}".rstrip(".")


def pct(v: float) -> str:
    return f"{100 * v:.0f} %"


def span(values, digits: int = 3) -> str:
    lo, hi = float(np.min(values)), float(np.max(values))
    return fmt(lo, digits) if fmt(lo, digits) == fmt(hi, digits) else f"{fmt(lo, digits)}–{fmt(hi, digits)}"


def family(name: str) -> str:
    return name.split("_")[0]


# -- the bound and what the paper's magnitudes imply ----------------------------------------------------

def bound_2020(noise_ug: float = NOISE_UG) -> dict[str, np.ndarray]:
    """Cramér-Rao SD of every seed15 parameter on the nominal 24-position scheme at the paper's truth, per
    family; the angles' observable parts (seed15's three body-frame rotations are not observable)."""
    m = get_model("seed15")
    truth = {n: PAPER_TRUTH[n] for n in m.names}
    sim = simulate(m, truth, np.random.default_rng(0), scheme="24", noise_g=0.0)
    problem = CalibrationProblem(m, sim.data, check=False)
    x = sim.truth_vector(m)
    sd, mask = crlb(problem, x, noise_ug * 1e-6)
    sd = np.where(mask, sd, projected_crlb(problem, x, noise_ug * 1e-6)[0])
    return {f: sd[[family(n) == f for n in m.names]] for f in FAMILIES}


def implied(bound: dict[str, np.ndarray], noise_ug: float = NOISE_UG) -> dict[str, dict]:
    """Per family: the bound's range, the per-position noise the paper's RMSE range implies (µg), and the
    samples per position it implies if the stated noise were per sample."""
    out = {}
    for f in FAMILIES:
        c = float(np.mean(bound[f]))
        lo, hi = TABLE3_RMSE[f]
        out[f] = {"crlb": bound[f], "noise_ug": (noise_ug * lo / c, noise_ug * hi / c),
                  "samples": ((c / hi) ** 2, (c / lo) ** 2), "below": (c / hi, c / lo)}
    return out


def bound_rows(imp: dict[str, dict]) -> list[str]:
    """The rows of the Table 3 against the bound table (deterministic: the test finds them in the doc)."""
    rows = []
    for f in FAMILIES:
        d = imp[f]
        lo, hi = TABLE3_RMSE[f]
        paper = mag(lo) if lo == hi else f"{mag(lo)}–{mag(hi)}"
        lo_n, hi_n = d["samples"]
        if hi_n <= 1:
            samples = "1 (the paper's RMSE is above the bound)"
        else:
            samples = f"{fmt(max(lo_n, 1), 2)}–{fmt(hi_n, 2)}" if lo_n > 1 else f"1–{fmt(hi_n, 2)}"
        rows.append(f"| {f} | {paper}{UNIT[f]} | {span(d['crlb'])}{UNIT[f]} | {span(d['below'], 2)} | "
                    f"{span(d['noise_ug'], 2)} µg | {samples} |")
    return rows


def cost_readings(f_paper: float, problem: CalibrationProblem, x_full: np.ndarray) -> dict[str, float]:
    """The per-position noise (µg) a final cost ``f_paper`` implies under each reading of the 2020 paper's
    Eq. 13: E Σe² = σ²·(m − rank) and E Σ|e| = σ·√(2/π)·Σ√(1 − h_i) (h the leverages; first order)."""
    h = hat_values(problem, x_full)
    dof = len(h) - round(float(h.sum()))
    abs_per_sigma = math.sqrt(2 / math.pi) * float(np.sum(np.sqrt(1 - h)))
    return {"sq_g2": math.sqrt(f_paper / dof) * 1e6, "sq_ms2": math.sqrt(f_paper / dof) / G0 * 1e6,
            "abs_g": f_paper / abs_per_sigma * 1e6, "dof": dof, "abs_per_sigma": abs_per_sigma}


# -- optcal's runs --------------------------------------------------------------------------------------

def fresh(problem: CalibrationProblem) -> CalibrationProblem:
    """The shared in-field problem of a run with an evaluation counter of its own (as a study's trial has)."""
    p = copy.copy(problem)
    p.counter = Counter()
    return p


def study_2020(runs: int) -> dict:
    """bsas2020 through optcal.study: its summary, per-parameter RMSE per solver, and staged BSAS with the
    presets at the truth (1e-3 of the manufacturer's error)."""
    sp = specs.load("bsas2020")
    res = optcal.study(sp, runs=runs, executor="serial")
    order = [c.label for c in sp.solvers]
    gs = {g.solver: g for g in groups(res.trials.to_dict("records"), order)}
    near = dataclasses.replace(sp, presets_error_scale=1e-3, solvers=sp.solvers[:1])
    res_near = optcal.study(near, runs=runs, executor="serial")
    g_near = groups(res_near.trials.to_dict("records"))[0]
    return {"spec": sp, "groups": gs, "order": order, "near": g_near}


def per_family(g, key_: str = "rmse") -> dict[str, np.ndarray]:
    ps = g.parameters()
    return {f: np.array([p[key_] for p in ps if family(p["name"]) == f]) for f in FAMILIES}


def verification_range(g) -> tuple[float, float]:
    """Median over runs of the smallest and the largest verification error over the positions (µg)."""
    E = [np.asarray(r["ver_err"], float) for r in g.ok]
    return float(np.median([e.min() for e in E])), float(np.median([e.max() for e in E]))


def stage_costs(runs: int, beetles=(10, 6, 2)) -> dict[int, np.ndarray]:
    """Median over runs 0..runs-1 of the cost after each of the four stages of staged BSAS (p_pos 0.95,
    p_st 0.8, 300 iterations per stage) with m beetles: the 2020 paper's Figure 3a."""
    sp = specs.load("bsas2020")
    ts = [t for t in trials(sp) if t.config.label == "BSAS"][:runs]
    out = {}
    for m in beetles:
        F = []
        for t in ts:
            w = world(t)
            s = optcal_solver("staged:bsas", {**t.config.options, "inner.m": m})
            r = s.solve(fresh(w.yard), rng=stream(t.seed, SOLVER, t.run, key(t.model), key(t.scheme), key(f"m={m}")))
            F.append([st["fun"] for st in r.extra["stages"]])
        out[m] = np.median(np.array(F), axis=0)
    return out


def optcal_solver(name: str, options: dict):
    from optcal import solvers

    return solvers.get(name, **options)


def level_at(curve: np.ndarray, rel: float = 0.01) -> int:
    """The first iteration (1-based) from which the best cost so far is within ``rel`` of the curve's last."""
    return int(np.argmax(curve <= (1 + rel) * curve[-1])) + 1


def same_data_runs(seeds: int) -> dict[str, dict]:
    """Staged BSAS and BAS on run 0's data over ``seeds`` solver seeds: the final costs (the 2020 Figures 5
    and 6, the spread the search's randomness alone makes) and, per stage, the iteration from which the
    best cost is within 1 % of the stage's last (its Figure 4: 300 iterations per stage)."""
    sp = specs.load("bsas2020")
    ts = [t for t in trials(sp) if t.run == 0 and not t.config.reference]
    w = world(ts[0])
    out = {"f_opt": w.f_opt}
    for t in ts:
        per_stage = int(t.config.options["inner.iterations"])
        s = optcal_solver(t.config.name, t.config.options)
        rngs = np.random.default_rng(np.random.SeedSequence(t.seed, spawn_key=(SOLVER, key(t.config.label))))
        costs, levels = [], []
        for g in rngs.spawn(seeds):
            rec = {}

            def cb(info, rec=rec):
                rec[info["nit"]] = info["fun"]

            costs.append(s.solve(fresh(w.yard), rng=g, callback=cb).fun)
            curve = np.array([rec[i] for i in range(1, 4 * per_stage + 1)])
            levels.append([level_at(curve[k * per_stage:(k + 1) * per_stage]) for k in range(4)])
        out[t.config.label] = {"costs": np.array(costs), "levels": np.median(np.array(levels), axis=0)}
    return out


def study_2015(runs: int, mcs_runs: int) -> dict:
    """nafsa2015 through optcal.study, the MCS wrappers with ``mcs_runs`` runs (the spec: 100)."""
    sp = specs.load("nafsa2015")
    sp = dataclasses.replace(sp, solvers=tuple(
        dataclasses.replace(c, options={**c.options, "runs": mcs_runs}) if c.name.startswith("mcs:") else c
        for c in sp.solvers))
    res = optcal.study(sp, runs=runs, executor="serial")
    order = [c.label for c in sp.solvers]
    return {"spec": sp, "groups": {g.solver: g for g in groups(res.trials.to_dict("records"), order)},
            "order": order}


def mcs_sd(mcs_runs: int) -> dict[str, dict]:
    """The 2015 paper's MCS standard deviations: each mcs:staged:* configuration of nafsa2015 on run 0's data,
    exactly as the study's trial runs it (same generator, budget and target), with ``mcs_runs`` runs; the SD
    of the runs' estimates per parameter in natural units, against the data's Cramér-Rao bound."""
    sp = specs.load("nafsa2015")
    out = {}
    for t in trials(sp):
        if t.run != 0 or not t.config.name.startswith("mcs:"):
            continue
        w = world(t)
        s = optcal_solver(t.config.name, {**t.config.options, "runs": mcs_runs})
        problem = fresh(w.yard)
        r = s.solve(problem, budget=trial_budget(t.config, s, w.f_opt),
                    rng=stream(t.seed, SOLVER, t.run, key(t.model), key(t.scheme), key(t.config.label)))
        X = problem.to_full(np.asarray(r.extra["x_runs"], float))
        sd = X.std(axis=0, ddof=1)
        names = w.model.names
        out[t.config.label] = {"sd": dict(zip(names, sd)), "ratio": dict(zip(names, sd / w.bound[0])),
                               "k_over_b": sd[:3] / sd[3:6], "runs": r.extra["runs_done"]}
    return out


def convergence(seeds: int) -> dict[str, dict]:
    """The 2015 Figure 5: the scale-factor stage (the first of staged:afsa/oafsa/nafsa, 60 generations of 50
    fish) on nafsa2015's run 0 data, over ``seeds`` solver seeds. Per iteration the best cost so far (the
    solver's callback), as the RMS norm error over the positions, √(f/24) in µg; the iteration from which
    the best is within 1 % of the stage's final cost; the stage's evaluations."""
    sp = specs.load("nafsa2015")
    t0 = [t for t in trials(sp) if t.run == 0][0]
    w = world(t0)
    out = {}
    for label in ("AFSA", "OAFSA", "NAFSA"):
        cfg = next(c for c in sp.solvers if c.label == label)
        curves, nfev = [], []
        rngs = np.random.default_rng(np.random.SeedSequence(t0.seed, spawn_key=(SOLVER, key(f"fig5 {label}"))))
        for g in rngs.spawn(seeds):
            rec = {}

            def cb(info, rec=rec):
                rec[info["nit"]] = (info["fun"], info["nfev"])
                return True if info["nit"] >= STAGE1_ITERATIONS else None  # stage 1 only

            optcal_solver(cfg.name, cfg.options).solve(fresh(w.yard), rng=g, callback=cb)
            curves.append([rec[i][0] for i in range(1, STAGE1_ITERATIONS + 1)])
            nfev.append(rec[STAGE1_ITERATIONS][1])
        C = np.array(curves)
        level = [level_at(c) for c in C]
        rms = np.sqrt(np.median(C, axis=0) / N_POSITIONS) * 1e6
        out[label] = {"rms_ug": {i: float(rms[i - 1]) for i in CONVERGENCE_AT}, "level": level,
                      "nfev": float(np.median(nfev))}
    start = fresh(w.yard)
    out["start_ug"] = float(np.sqrt(start.cost(start.from_full(start.centre)) / N_POSITIONS) * 1e6)
    out["optimum_ug"] = float(np.sqrt(w.f_opt / N_POSITIONS) * 1e6)
    return out


# -- the tables -------------------------------------------------------------------------------------------

def nav(g) -> str:
    s = g.summary()
    return f"{fmt(s['nav_max_nmi'])} / {fmt(s['nav_mean_nmi'])}"


def table_2020(r: dict) -> list[str]:
    """The bsas2020 table of docs/studies.md."""
    out = ["| calibration | success | RMSE/CRLB | with presets | verification µg mean (SD) (Table 5) | evaluations "
           "| runtime s | 5-h max / mean error nmi (Table 6) |", "|---|---|---|---|---|---|---|---|"]
    first = r["groups"][r["order"][0]].summary()
    out.append(f"| truth | | | | {first['ver_truth_ug']:.2f} (noise floor) | | | 0 / 0 |")
    for label in r["order"]:
        g = r["groups"][label]
        s = g.summary()
        name = {"BSAS": "BSAS (staged)", "BAS": "BAS (staged)"}.get(label, "turntable, 10″")
        out.append(f"| {name} | {pct(s['success_rate'])} | {s['accuracy']:.2f} | {s['accuracy_presets']:.2f} | "
                   f"{s['ver_mean_ug']:.2f} ({s['ver_sd_ug']:.2f}) | {s['nfev_median']:,.0f} | "
                   f"{secs(s['runtime_median_s'])} | {nav(g)} |")
    return out


def table_2015(r: dict) -> list[str]:
    """The nafsa2015 table of docs/studies.md."""
    out = ["| solver | success | RMSE/CRLB | with presets | verification µg mean (SD) | final cost median | "
           "runtime s | evaluations | 5-h max / mean nmi |", "|---|---|---|---|---|---|---|---|---|"]
    for label in r["order"]:
        g = r["groups"][label]
        s = g.summary()
        out.append(f"| {label} | {pct(s['success_rate'])} | {s['accuracy']:.2f} | {s['accuracy_presets']:.2f} | "
                   f"{s['ver_mean_ug']:.2f} ({s['ver_sd_ug']:.2f}) | {fmt(s['cost_median'], 4)} | "
                   f"{secs(s['runtime_median_s'])} | {s['nfev_median']:,.0f} | {nav(g)} |")
    return out


def side_by_side(c: dict) -> list[str]:
    """The one table: every number the papers' text copies kept, beside optcal's."""
    imp, readings, r20, stages, same, r15, sds, conv, size = (
        c[k] for k in ("imp", "readings", "r20", "stages", "same", "r15", "sds", "conv", "size"))
    g20, g15 = r20["groups"], r15["groups"]
    bsas = g20["BSAS"]
    rm, ratio, sd = per_family(bsas), per_family(bsas, "ratio"), per_family(bsas, "sd")
    obs, rm_near = per_family(bsas, "rmse_observable"), per_family(r20["near"])
    n20, n15 = size["runs_2020"], size["runs_2015"]
    rows = ["| # | the paper's number (source) | paper | optcal | setup: same, or the difference |",
            "|---|---|---|---|---|"]

    def row(num, source, paper, ours, setup):
        rows.append(f"| {num} | {source} | {paper} | {ours} | {setup} |")

    row("1", "2020 §3, §4: 15 parameters, 24 positions (45° steps), 300 iterations per category, 50 runs; "
        "§5: 36 positions (30° steps), 5-h navigation", "15, 24, 300, 50; 36, 5 h",
        f"15 (seed15), 24, 300, {n20}; 36, 5 h", "same (bsas2020)")
    row("2", "2020 §4.1: \"the random bias of accelerometer is set as 10 ug\"", "10 µg",
        "10 µg per axis on each position's mean", "same number; the paper does not say whether per sample or per "
        "position (rows 3-6, 11)")
    label = {"K": "scale factors", "b": "biases", "S": "installation angles", "K2": "second-order terms"}
    for i, f in enumerate(FAMILIES):
        lo, hi = TABLE3_RMSE[f]
        paper = (mag(lo) if lo == hi else f"{mag(lo)}–{mag(hi)}") + UNIT[f]
        ours = f"staged BSAS {span(rm[f])}{UNIT[f]}"
        if f == "S":
            ours += f" (observable part {span(obs[f])})"
        ours += (f", {span(ratio[f], 2)} of the bound {span(imp[f]['crlb'])}; with presets at the truth "
                 f"{span(rm_near[f])}")
        row(str(3 + i), f"2020 §4.2, Table 3: RMSE of the {label[f]}", paper, ours,
            f"same ({n20} runs); the paper's value implies {span(imp[f]['noise_ug'], 2)} µg per position mean")
    all_sd = np.concatenate([sd[f] for f in FAMILIES])
    row("7", "2020 §4.2, Table 3: SD of the 15 parameters", "1e-9–1e-5",
        f"staged BSAS, SD over runs: {span(all_sd)}", f"same ({n20} runs)")
    for m, costs in FIG3_COSTS.items():
        row(f"8{'abc'[[10, 6, 2].index(m)]}", f"2020 §4.1, Figure 3: cost after 300 iterations per category, "
            f"m = {m}", ", ".join(sci(v, 4) for v in costs), ", ".join(fmt(v, 4) for v in stages[m]) + " g²",
            f"median of {size['stage_runs']} runs; the paper's cost unit and operator are lost (row 11)")
    lv = {k: "/".join(f"{v:.0f}" for v in same[k]["levels"]) for k in ("BSAS", "BAS")}
    row("9", "2020 §4.2, Figure 4: fastest descent in the first 20 iterations, BAS \"trapped\" after 20, BSAS "
        "\"continue[s] to search after 60\" (angles)", "20, 60",
        f"iterations to within 1 % of each stage's last cost (scale, bias, angles, second order): BSAS "
        f"{lv['BSAS']}, BAS {lv['BAS']}", f"median of {size['seeds']} solver seeds on run 0's data")
    f_opt = same["f_opt"]
    row("10a", "2020 §4.2, Figure 5: BSAS's final cost over 50 runs", f"{sci(FIG5_BSAS[0])}–{sci(FIG5_BSAS[1])}",
        f"{span(same['BSAS']['costs'], 4)} g² (the data's optimum {fmt(f_opt, 4)})",
        f"{size['seeds']} solver seeds on run 0's data; over {n20} data sets {span(bsas.column('fun'))}")
    row("10b", "2020 §4.2, Figure 6: BAS's final cost over 50 runs", f"{sci(FIG6_BAS[0])}–{sci(FIG6_BAS[1])}",
        f"{span(same['BAS']['costs'], 4)} g²", "as 10a: BAS is not stuck here")
    lo_b, hi_b = imp["b"]["noise_ug"]
    agree = [name for name, k in (("Σe² in g²", "sq_g2"), ("Σe² in (m/s²)²", "sq_ms2"), ("Σ\\|e\\| in g", "abs_g"))
             if lo_b <= readings[k] <= hi_b]
    row("11", "2020 Eq. 13 (operator lost) with Figure 5's 7.3e-7: the noise per position it implies", "–",
        f"Σe² in g²: {readings['sq_g2']:.0f} µg; Σe² in (m/s²)²: {readings['sq_ms2']:.1f} µg; Σ\\|e\\| in g: "
        f"{readings['abs_g']:.3f} µg", f"{readings['dof']} residual degrees of freedom; within row 4's range: "
        + (", ".join(agree) or "none"))
    b, t = bsas.summary(), g20["traditional@10as"].summary()
    vb, vt = verification_range(bsas), verification_range(g20["traditional@10as"])
    row("12", "2020 §5.1, Table 5: 36-position error mean (SD), traditional / proposed",
        "12.025 (8.296) / 7.253 (4.786) µg", f"{t['ver_mean_ug']:.2f} ({t['ver_sd_ug']:.2f}) / "
        f"{b['ver_mean_ug']:.2f} ({b['ver_sd_ug']:.2f}) µg; truth {b['ver_truth_ug']:.2f}",
        "simulated (10 µg, a 10″ turntable) against the paper's experiment")
    row("13", "2020 §5.1, Figure 9: error range, traditional / proposed", "1–35 / 1–25 µg",
        f"{vt[0]:.1f}–{vt[1]:.0f} / {vb[0]:.1f}–{vb[1]:.0f} µg", "as 12; median over runs of the smallest and the "
        "largest")
    row("14", "2020 §5.2, Table 6: 5-h max / mean error, traditional; proposed", "3.1229 / 1.8165; 3.0273 / "
        "1.7583 nmi", f"{nav(g20['traditional@10as'])}; {nav(bsas)} nmi",
        "accelerometer errors only (perfect gyroscopes, known attitude) against the experiment's whole drift")
    row("15", "2020 §5.2: latitude / longitude error, traditional; proposed", "0.0416 / 0.0445; 0.0402 / 0.0434",
        "–", "unit lost in the copy; optcal reports the radial error (Eq. 23)")
    row("16", "2020 §4.1: s0 = d0", "2.22e-16", "2.22e-16", "same (bsas's defaults)")
    row("17", "2015 §5.1-§6.2, §7.1: 15 coefficients in 4 categories, 100-time MCS, 24-position verification (45° "
        "steps)", "15, 4, 100, 24", f"15 (seed15), 4 stages, {size['mcs_runs']} runs, 24",
        f"nafsa2015; {n15} data sets, each with its own MCS runs")
    row("18", "2015 §6.1: CF between 0.000001 and 0.999999", "1e-6, 0.999999", "1e-6, 0.999999",
        "same (nafsa's defaults)")
    nafsa = sds["MCS-NAFSA"]
    sdk = [nafsa["sd"][f"K_{a}"] * 1e6 for a in "xyz"]
    sdb = [nafsa["sd"][f"b_{a}"] * 1e6 for a in "xyz"]
    rk = span([nafsa["ratio"][f"K_{a}"] for a in "xyz"], 2)
    rb = span([nafsa["ratio"][f"b_{a}"] for a in "xyz"], 2)
    row("19", "2015 §6.2, Table 3: SD of the scale factors over the MCS runs", ", ".join(map(str, SD2015_K)) +
        " volt/g", f"MCS-NAFSA {span(sdk, 2)} ppm, {rk} of the bound", f"{size['mcs_runs']} MCS runs on run 0's "
        "data; the paper's volt/g has no g-equivalent in the copy")
    row("20", "2015 §6.2, Table 3: SD of the biases", ", ".join(map(str, SD2015_B)) + " volt/g",
        f"MCS-NAFSA {span(sdb, 2)} µg, {rb} of the bound", "as 19")
    paper_ratio = np.array(SD2015_K) / np.array(SD2015_B)
    ours = "; ".join(f"{k} {span(v['k_over_b'], 2)}" for k, v in sds.items())
    row("21", "2015 §6.2: SD(scale)·1 g / SD(bias), x, y, z (from rows 19-20)", span(paper_ratio, 3), ours,
        "a ratio needs no unit")
    angles = "; ".join(f"{k} {span([v['ratio'][n] for n in v['ratio'] if n.startswith('S_')], 2)}"
                       for k, v in sds.items())
    row("22", "2015 §6.2, Table 3: SDs of the angles and quadratic terms", "lost in the copy",
        f"angles, of the bound: {angles}", "as 19")
    lvf = {k: f"{np.median(conv[k]['level']):.0f}" for k in ("AFSA", "OAFSA", "NAFSA")}
    row("23", "2015 §6.2, Figure 5: SAFSA rises slightly after 20 iterations, \"remains stable after 24\"", "20, 24",
        f"AFSA within 1 % of its last from iteration {lvf['AFSA']}", f"the scale-factor stage, {size['seeds_2015']} "
        "seeds on run 0's data; optcal's curve is the best so far, which cannot rise")
    row("24", "2015 §6.2, Figure 5: SAFSA's indicator level", "0.002584 volt/g",
        f"{conv['AFSA']['rms_ug'][STAGE1_ITERATIONS]:.2f} µg RMS norm error (from {conv['start_ug']:.1f} at the "
        f"presets)", "Eq. 18 lost; optcal shows √(Σe²/24)")
    row("25", "2015 §6.2, Figure 5: OAFSA diverges after 20 iterations, secondary initialisation at 30", "20, 30",
        f"OAFSA within 1 % from iteration {lvf['OAFSA']}; automatic restart after 8 stalled generations", "as 23")
    row("26", "2015 §6.2, Figure 5: NAFSA \"always convergent\", the fastest", "–",
        f"NAFSA within 1 % from iteration {lvf['NAFSA']} (median stage: {conv['NAFSA']['nfev']:,.0f} evaluations; "
        f"AFSA {conv['AFSA']['nfev']:,.0f})", "as 23")
    v = {k: g15[k].summary() for k in ("MCS-OAFSA", "MCS-NAFSA")}
    row("27", "2015 §7.1, Tables 5 and 6: 24-position verification, MCS-OAFSA / MCS-NAFSA", "lost in the copy",
        f"{v['MCS-OAFSA']['ver_mean_ug']:.2f} / {v['MCS-NAFSA']['ver_mean_ug']:.2f} µg mean (truth "
        f"{v['MCS-NAFSA']['ver_truth_ug']:.2f})", f"nafsa2015, {n15} data sets")
    for i, label in enumerate(("BSAS", "BAS")):
        s = g20[label].summary()
        row(f"28{'ab'[i]}", f"runtime of staged {label} (the 2020 paper prints none)", "–",
            f"{secs(s['runtime_median_s'])} s, {s['nfev_median']:,.0f} evaluations", f"median of {n20} trials")
    for i, label in enumerate(("AFSA", "OAFSA", "NAFSA", "MCS-AFSA", "MCS-OAFSA", "MCS-NAFSA")):
        s = g15[label].summary()
        row(f"29{'abcdef'[i]}", f"runtime of {label} (the 2015 paper prints none)", "–",
            f"{secs(s['runtime_median_s'])} s, {s['nfev_median']:,.0f} evaluations",
            f"median of {n15} trials" + (f", {size['mcs_runs']} MCS runs each" if "MCS" in label else ""))
    return rows


def convergence_rows(conv: dict) -> list[str]:
    head = "| solver | " + " | ".join(f"it {i}" for i in CONVERGENCE_AT) + " | levels at (10-90 %) | evaluations |"
    rows = [head, "|" + "---|" * (len(CONVERGENCE_AT) + 3)]
    for label in ("AFSA", "OAFSA", "NAFSA"):
        c = conv[label]
        lo, mid, hi = np.percentile(c["level"], [10, 50, 90])
        rows.append(f"| {label} | " + " | ".join(f"{c['rms_ug'][i]:.2f}" for i in CONVERGENCE_AT) +
                    f" | {mid:.0f} ({lo:.0f}-{hi:.0f}) | {c['nfev']:,.0f} |")
    return rows


SIZES = {"full": {"runs_2020": 50, "stage_runs": 6, "seeds": 50, "runs_2015": 4, "mcs_runs": 100, "seeds_2015": 20},
         "small": {"runs_2020": 6, "stage_runs": 2, "seeds": 8, "runs_2015": 1, "mcs_runs": 10, "seeds_2015": 5}}


def compute(size: dict) -> dict:
    """Every number of the tables, at ``size`` (SIZES)."""
    imp = implied(bound_2020())
    t0 = [t for t in trials(specs.load("bsas2020")) if t.run == 0][0]
    w = world(t0)
    readings = cost_readings(float(np.mean(FIG5_BSAS)), w.yard, w.x_true)
    timer = {}
    t = time.perf_counter()
    r20 = study_2020(size["runs_2020"])
    timer["bsas2020"] = time.perf_counter() - t
    stages = stage_costs(size["stage_runs"])
    same = same_data_runs(size["seeds"])
    t = time.perf_counter()
    r15 = study_2015(size["runs_2015"], size["mcs_runs"])
    timer["nafsa2015"] = time.perf_counter() - t
    sds = mcs_sd(size["mcs_runs"])
    conv = convergence(size["seeds_2015"])
    return {"imp": imp, "readings": readings, "r20": r20, "stages": stages, "same": same, "r15": r15,
            "sds": sds, "conv": conv, "size": size, "timer": timer}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--small", action="store_true", help="the test's size instead of the documented one")
    args = ap.parse_args()
    size = SIZES["small" if args.small else "full"]
    t = time.perf_counter()
    c = compute(size)
    print(f"size: {size}\n")
    print("The papers side by side:\n")
    print("\n".join(side_by_side(c)))
    print("\nThe 2020 Table 3 against the bound (10 µg per position mean):\n")
    print("| family | paper RMSE | CRLB at 10 µg | bound / paper | implied noise per position | samples per "
          "position if 10 µg per sample |\n|---|---|---|---|---|---|")
    print("\n".join(bound_rows(c["imp"])))
    print("\nThe 2015 Figure 5, optcal: RMS norm error (µg) of the best so far in the scale-factor stage:\n")
    print("\n".join(convergence_rows(c["conv"])))
    print(f"\nstart (presets) {c['conv']['start_ug']:.2f} µg, optimum {c['conv']['optimum_ug']:.2f} µg")
    print("\nbsas2020:\n")
    print("\n".join(table_2020(c["r20"])))
    print("\nnafsa2015:\n")
    print("\n".join(table_2015(c["r15"])))
    print("\nstudy wall times (serial): " + ", ".join(f"{k} {v:.0f} s" for k, v in c["timer"].items()))
    print(f"total {time.perf_counter() - t:.0f} s")


if __name__ == "__main__":
    main()
