"""``optcal study report DIR``: ``report.md`` with tables and PNG figures, ``parameters.md`` with every
per-parameter statistic, and ``summary.json`` (one record per solver × scheme × model) for tools and CI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from . import anytime, figures
from .metrics import Group, cells, groups
from .store import Store


def _f(v, fmt: str = ".3g") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return format(v, fmt)


def _ci(v, ci, fmt: str = ".3g", scale: float = 1.0, unit: str = "") -> str:
    """'value [lo, hi]' (a 95 % bootstrap interval over runs); the value alone when there is none."""
    if v is None or not math.isfinite(v):
        return "–"
    text = format(v * scale, fmt) + unit
    if ci is None or not all(math.isfinite(c) for c in ci):
        return text
    return f"{text} [{format(ci[0] * scale, fmt)}, {format(ci[1] * scale, fmt)}]"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out + [""]


def _rank(gs: list[Group]) -> list[Group]:
    """Most accurate first; never-converging and failed groups last."""
    return sorted(gs, key=lambda g: (-round(g.success_rate, 6), np.nan_to_num(g.accuracy, nan=np.inf)))


def _label(g: Group) -> str:
    if g.reference:
        return f"traditional ({g.solver_name}, {g.reference_error_arcsec:g}″)"
    return g.solver


def _has_presets_bound(gs: list[Group]) -> bool:
    return any(np.isfinite(g.accuracy_presets) for g in gs)


def _summary_rows(gs: list[Group], nav: bool, cis: dict | None = None) -> list[list[str]]:
    """The per-cell table's rows; ``cis`` maps id(group) to its bootstrap intervals (anytime.group_ci)."""
    rows = []
    presets = _has_presets_bound(gs)
    for g in _rank(gs):
        s = g.summary()
        ci = (cis or {}).get(id(g), {})
        r = [
            f"`{_label(g)}`", _ci(s["success_rate"], ci.get("success_rate"), ".0f", 100, " %"),
            _ci(s["accuracy"], ci.get("accuracy"), ".2f"),
            *([_ci(s["accuracy_presets"], ci.get("accuracy_presets"), ".2f")] if presets else []),
            f"{_f(s['ver_mean_ug'], '.2f')} ({_f(s['ver_sd_ug'], '.2f')})",
            f"{_f(s['cost_median'], '.3e')} [{_f(s['cost_min'], '.2e')}, {_f(s['cost_max'], '.2e')}]",
            *([_ci(s["runtime_median_s"], ci.get("runtime_median_s"), ".3g")] if cis is not None else []),
            f"{_f(s['runtime_median_s'], '.3g')} [{_f(s['runtime_p10_s'], '.2g')}, {_f(s['runtime_p90_s'], '.2g')}]",
            _f(s["nfev_median"], ".0f"),
            _f(s["evals_per_s"], ",.0f"),
        ]
        if nav:
            r.append(f"{_f(s['nav_max_nmi'], '.3f')} / {_f(s['nav_mean_nmi'], '.3f')}")
        r.append(str(s["failed"]))
        rows.append(r)
    return rows


SUMMARY_HEADER = ["solver", "success", "RMSE/CRLB", "verification µg mean (SD)", "final cost median [min, max]",
                  "runtime s median [95 % CI]", "runtime s median [p10, p90]", "evaluations", "evaluations/s"]


def _crossing(levels: list[tuple[float, float]], value: float) -> str:
    """The orientation error above which the turntable metric exceeds ``value``."""
    a = [x for x, _ in levels]
    m = [y for _, y in levels]
    if m[0] > value:
        return f"at every orientation error tested (even {a[0]:g}″)"
    for (a1, m1), (a2, m2) in zip(levels, levels[1:]):
        if m1 <= value < m2:
            # linear in arcsec, logarithmic in the metric
            t = (math.log(value) - math.log(m1)) / (math.log(m2) - math.log(m1))
            return f"once the orientation error exceeds about {a1 + t * (a2 - a1):.0f}″ (between {a1:g}″ and {a2:g}″)"
    return f"at none of the orientation errors tested (up to {a[-1]:g}″)"


def _traditional_section(cell_key, gs: list[Group], figdir: Path, slug: str) -> list[str]:
    ref = sorted([g for g in gs if g.reference], key=lambda g: g.reference_error_arcsec)
    inf = [g for g in gs if not g.reference and g.ok]
    if not ref or not inf:
        return []
    model, scheme = cell_key
    lines = [f"### Traditional against in-field: {model}, {scheme} positions", ""]
    best_in = min(inf, key=lambda g: np.nan_to_num(g.accuracy, nan=np.inf))
    metrics = [("accuracy", "RMSE/CRLB", lambda s: s["accuracy"])]
    metrics.append(("verification", "verification |‖A‖−g| (µg)", lambda s: s["ver_mean_ug"]))
    if any(r.get("nav_max_nmi") is not None for g in gs for r in g.ok):
        metrics.append(("navigation", "5-h max position error (nmi)", lambda s: s["nav_max_nmi"]))
    header = ["calibration"] + [m[1] for m in metrics]
    rows = [[_label(g)] + [_f(fn(g.summary())) for _, _, fn in metrics] for g in ref]
    rows += [[f"in-field `{g.solver}`"] + [_f(fn(g.summary())) for _, _, fn in metrics] for g in inf]
    lines += _table(header, rows)
    for key, name, fn in metrics:
        levels = [(g.reference_error_arcsec, fn(g.summary())) for g in ref]
        if not all(np.isfinite(y) for _, y in levels):
            continue
        said = [f"`{g.solver}` ({_f(fn(g.summary()))}) {_crossing(levels, fn(g.summary()))}"
                for g in inf if np.isfinite(fn(g.summary()))]
        if not said:
            continue
        lines.append(f"- **{name}**: in-field calibration beats the turntable calibration: " + "; ".join(said) + ".")
        v = fn(best_in.summary())
        if len(levels) > 1 and np.isfinite(v):
            p = figures.traditional(levels, [(g.solver, fn(g.summary())) for g in inf], name,
                                    f"{model}, {scheme} positions: {name}", figdir / f"traditional_{key}_{slug}.png")
            lines.append(f"  ![{name}](figures/{p.name})")
    return lines + [""]


def _navigation_section(cell_key, gs: list[Group], nav_spec: dict, figdir: Path, slug: str) -> list[str]:
    nav = [g for g in gs if any(r.get("nav_max_nmi") is not None for r in g.ok)]
    if not nav:
        return []
    model, scheme = cell_key
    hours = nav_spec["hours"]
    att = ", ".join(f"{a:g}" for a in nav_spec.get("attitude_deg", (0, 0, 0)))
    lines = [f"### Static navigation ({hours:g} h): {model}, {scheme} positions", "",
             "Median over runs of each run's maximum and mean radial position error "
             f"(2020 paper, Eq. 23 and Table 6); attitude (roll, pitch, yaw) = ({att})°, known initial attitude.", ""]
    if any(g.unobservable() for g in nav if not g.reference):
        # With a known initial attitude a rotation of the body frame reads as a horizontal specific-force
        # error, so the navigation error sees exactly the directions the norm cost cannot.
        lines += ["With a known initial attitude, an error along the unobservable directions (a rotation of the "
                  "body frame) acts as a tilt: the in-field rows partly measure the presets there, not the data "
                  "(docs/navigation.md).", ""]
    rows = [["truth calibration", "0", "0"]]
    for g in sorted(nav, key=lambda g: (not g.reference, g.summary()["nav_max_nmi"])):
        s = g.summary()
        rows.append([_label(g), _f(s["nav_max_nmi"], ".4f"), _f(s["nav_mean_nmi"], ".4f")])
    lines += _table(["calibration", "max error (nmi)", "mean error (nmi)"], rows)
    p = figures.navigation(nav, hours, f"{model}, {scheme} positions: static navigation error",
                           figdir / f"navigation_{slug}.png")
    return lines + [f"![navigation](figures/{p.name})", ""]


def _anytime_section(rows: list[dict], order: list[str], spec: dict, figdir: Path) -> list[str]:
    """Runtime ECDFs, data and performance profiles, and their table (studies.anytime)."""
    L = ["## Anytime performance", ""]
    at = anytime.collect(rows, order)
    if at.empty:
        return L + ["No anytime records: this store's trials were written before studies recorded them "
                    "(run the study into a new folder to get them).", ""]
    cost_t = ", ".join(f"{t:g}" for t in anytime.COST_TARGETS)
    acc_t = ", ".join(f"{t:g}" for t in anytime.ACCURACY_TARGETS)
    (pk1, pt1), (pk2, pt2) = anytime.PROFILE_TARGETS
    L += [
        f"Every in-field trial against {len(anytime.COST_TARGETS)} cost targets and "
        f"{len(anytime.ACCURACY_TARGETS)} accuracy targets, over {len(at.problems)} problems "
        f"(model × scheme × run) and {len(at.solvers)} solvers (turntable configurations fit another cost and "
        "are left out):",
        "",
        f"- **cost targets**: relative gap (f − f_opt) / f_opt ≤ {cost_t}, with f the best cost so far and "
        "f_opt the optimum of the run's data (a reference scipy-lm fit from the presets; a trial that ends "
        "below it meets every cost target);",
        f"- **accuracy targets**: the trial's accuracy ≤ {acc_t}, where a trial's accuracy is the RMS over "
        "the parameters of |error| / CRLB (the error's observable part against its Cramér-Rao bound) of the "
        "best point so far. An efficient estimate scatters around 1 from run to run, so the optimum itself "
        "misses the tightest accuracy target in some runs.",
        "",
        "Evaluations to a target: the first point of the 10-per-decade evaluation grid at which it is met; "
        "never met, or a failed trial: ∞. **Runtime ECDF** (COCO / IOHprofiler): the fraction of "
        "(trial, target) pairs met within x evaluations, over runs, models, schemes and targets; the number "
        "in the legend is the area under it on the log axis (1 = every target at the first evaluation). "
        "**Data profile** (Moré & Wild 2009): the fraction of problems solved within κ (n + 1) evaluations "
        "(n parameters). **Performance profile** (Dolan & Moré 2002): the fraction of problems on which the "
        "solver needs at most τ times the evaluations of the fastest solver on that problem. The profiles "
        f"use the targets {pk1} {pt1:g} and {pk2} {pt2:g}. Figures: the {figures.MAX_LINES} best solvers of "
        "each panel in colour, all others grey.",
        "",
    ]
    if at.missing or at.no_optimum:
        L += [f"{at.missing} trial(s) without an anytime record (written before it existed) and "
              f"{at.no_optimum} without an optimum are left out of the respective targets.", ""]
    recs = at.table(spec["seed"])
    recs.sort(key=lambda r: (-np.nan_to_num(r["cost_area"], nan=-1), -np.nan_to_num(r["accuracy_area"], nan=-1)))
    order = [r["solver"] for r in recs]  # one colour per solver in every figure
    name = spec["name"]
    p1 = figures.runtime_ecdf(at, f"{name}: runtime ECDFs", figdir / "anytime_ecdf.png", order)
    p2 = figures.data_profiles(at, f"{name}: data profiles", figdir / "data_profiles.png", order)
    p3 = figures.performance_profiles(at, f"{name}: performance profiles", figdir / "performance_profiles.png", order)
    L += [f"![runtime ECDFs](figures/{p1.name})", "", f"![data profiles](figures/{p2.name})", "",
          f"![performance profiles](figures/{p3.name})", ""]
    k1, k2 = f"{pk1}_{pt1:g}", f"{pk2}_{pt2:g}"
    L += [f"Per solver, largest cost-ECDF area first; *reached*: share of (trial, target) pairs met within the "
          f"budget; *solved*: share of problems on which the profile target is met; *fastest*: share of problems "
          f"on which the solver meets it first (performance profile at τ = 1, ties count for each). "
          f"[lo, hi]: {100 * anytime.LEVEL:.0f} % bootstrap interval over runs.", ""]
    header = ["solver", "cost: reached", "cost: ECDF area", "accuracy: reached", "accuracy: ECDF area",
              f"solved {_target_name(pk1, pt1)}", f"fastest {_target_name(pk1, pt1)}",
              f"solved {_target_name(pk2, pt2)}", f"fastest {_target_name(pk2, pt2)}"]
    L += _table(header, [[f"`{r['solver']}`",
                          _ci(r["cost_reached"], r["cost_reached_ci"], ".0f", 100, " %"),
                          _ci(r["cost_area"], r["cost_area_ci"], ".2f"),
                          _ci(r["accuracy_reached"], r["accuracy_reached_ci"], ".0f", 100, " %"),
                          _ci(r["accuracy_area"], r["accuracy_area_ci"], ".2f"),
                          _ci(r[f"solved_{k1}"], r[f"solved_{k1}_ci"], ".0f", 100, " %"),
                          _ci(r[f"fastest_{k1}"], r[f"fastest_{k1}_ci"], ".0f", 100, " %"),
                          _ci(r[f"solved_{k2}"], r[f"solved_{k2}_ci"], ".0f", 100, " %"),
                          _ci(r[f"fastest_{k2}"], r[f"fastest_{k2}_ci"], ".0f", 100, " %")] for r in recs])
    return L


def _target_name(kind: str, target: float) -> str:
    return f"gap ≤ {target:g}" if kind == "cost" else f"accuracy ≤ {target:g}"


def _parameters_md(cs) -> str:
    lines = ["# Per-parameter statistics", "",
             "Error = estimate − truth over the runs that did not fail. CRLB: Cramér-Rao SD at the truth with "
             "the simulation noise; ratio = RMSE of the observable part / CRLB. Parameters marked * have weight "
             "in an unobservable direction: their ratio scores only their observable part.", ""]
    for (model, scheme), gs in cs.items():
        for g in gs:
            lines.append(f"## {model}, {scheme} positions: `{_label(g)}`")
            lines.append("")
            rows = [[p["name"] + ("" if p["observable"] else "*"), _f(p["mean"], ".3e"), _f(p["rmse"], ".3e"),
                     _f(p["sd"], ".3e"), _f(p["crlb"], ".3e"), _f(p["ratio"], ".3g")] for p in g.parameters()]
            lines += _table(["parameter", "mean error", "RMSE", "SD", "CRLB", "RMSE/CRLB"], rows)
    return "\n".join(lines)


def _json_safe(v):
    if isinstance(v, dict):
        return {k: _json_safe(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_json_safe(x) for x in v]
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer | np.bool_):
        return v.item()
    return v


def headline(folder: str | Path, top: int = 8) -> str:
    """The ``top`` solvers of each model × scheme (success, then accuracy), as markdown tables."""
    with Store.open_existing(folder) as store:
        spec, rows = store.spec, store.rows()
    out = []
    for (model, scheme), cg in cells(groups(rows, [s["label"] for s in spec["solvers"]])).items():
        ranked = _rank(cg)
        out.append(f"{model}, {scheme} positions ({min(top, len(ranked))} best of {len(ranked)}):")
        wp = _has_presets_bound(cg)
        out += _table(["solver", "success", "RMSE/CRLB"] + (["with presets"] if wp else [])
                      + ["verification µg", "runtime s"],
                      [[f"`{_label(g)}`", f"{100 * g.success_rate:.0f} %", _f(g.accuracy, ".2f")]
                       + ([_f(g.accuracy_presets, ".2f")] if wp else [])
                       + [_f(g.summary()["ver_mean_ug"], ".2f"), _f(g.summary()["runtime_median_s"], ".3g")]
                       for g in ranked[:top]])
    return "\n".join(out)


def overview(cs) -> list[str]:
    """One row per solver, one column per model × scheme: RMSE/CRLB, with presets also RMSE against the
    bound of data and presets (:attr:`Group.accuracy_presets`), and the success rate; plus the median
    runtime over all cells; solvers ordered by their mean rank over the cells."""
    keys = list(cs)
    by = {k: {g.solver: g for g in cg} for k, cg in cs.items()}
    names = list(dict.fromkeys(g.solver for cg in cs.values() for g in cg))
    rank = {n: [] for n in names}
    for k in keys:
        for i, g in enumerate(_rank(list(by[k].values()))):
            rank[g.solver].append(i)
    names.sort(key=lambda n: np.mean(rank[n]))
    rows = []
    for n in names:
        cellv = []
        for k in keys:
            g = by[k].get(n)
            if g is None:
                cellv.append("–")
                continue
            bp = g.accuracy_presets
            both = _f(g.accuracy, ".2f") + (f" / {_f(bp, '.2f')}" if np.isfinite(bp) else "")
            cellv.append(f"{both} ({100 * g.success_rate:.0f} %)")
        rts = [by[k][n].summary()["runtime_median_s"] for k in keys if n in by[k]]
        rates = [by[k][n].summary()["evals_per_s"] for k in keys if n in by[k]]
        first = next(by[k][n] for k in keys if n in by[k])
        rows.append([f"`{_label(first)}`"] + cellv + [_f(float(np.median(rts)), ".3g"),
                                                      _f(float(np.median(rates)), ",.0f")])
    return _table(["solver"] + [f"{m}, {s}" for m, s in keys] + ["runtime s", "evaluations/s"], rows)


def busy_share(session: dict) -> float | None:
    """The share of the session's worker time spent inside trials: the rest is start-up, scheduling,
    writing results and idle workers at the end."""
    t = session.get("trials_wall_s")
    if t is None or not session.get("wall_s") or not session.get("trials"):
        return None
    return t / (session["wall_s"] * session["workers"])


def _busy(session: dict) -> str:
    b = busy_share(session)
    return "" if b is None else f", workers in trials {100 * b:.1f} % of the time"


def write_report(folder: str | Path) -> Path:
    """Write ``report.md``, ``parameters.md``, ``summary.json`` and ``figures/*.png`` into ``folder``."""
    folder = Path(folder)
    with Store.open_existing(folder) as store:
        spec = store.spec
        rows = store.rows()
        sessions = json.loads(store.meta("sessions") or "[]")
        wall = float(store.meta("wall_s") or 0)
        spec_hash = store.meta("spec_hash")
    figdir = folder / "figures"
    figdir.mkdir(exist_ok=True)
    order = [s["label"] for s in spec["solvers"]]
    gs = groups(rows, order)
    cs = cells(gs)
    cis = {id(g): anytime.group_ci(g, spec["seed"]) for g in gs}
    expected = spec["runs"] * len(spec["models"]) * len(spec["schemes"]) * len(spec["solvers"])
    failed = sum(r["status"] != "ok" for r in rows)
    has_nav = any(r.get("nav_max_nmi") is not None for r in rows)
    budgets = {json.dumps(s["budget"], sort_keys=True) for s in spec["solvers"]}
    budget = (", ".join(f"{k} {v:g}" for k, v in spec["solvers"][0]["budget"].items()) or "the solvers' defaults"
              ) if len(budgets) == 1 else "per solver (see the spec)"

    L = [f"# Study `{spec['name']}`", ""]
    if spec.get("description"):
        L += [spec["description"], ""]
    L += [
        f"- Spec hash `{spec_hash}`; {len(rows)} of {expected} trials stored"
        + (" (**incomplete**: run the spec again into this folder to finish)" if len(rows) < expected else "")
        + f"; {failed} failed.",
        f"- {spec['runs']} Monte-Carlo runs, base seed {spec['seed']}; models {', '.join(spec['models'])}; "
        f"schemes {', '.join(spec['schemes'])} positions; noise {spec['noise_ug']:g} µg; placement tilt "
        f"{spec['tilt_deg']:g}°; truth `{spec['truth'] if isinstance(spec['truth'], str) else 'given values'}`; "
        f"presets `{spec['presets']}`; budget: {budget}.",
        f"- Verification: {spec['verification']['scheme']} positions, {spec['verification']['noise_ug']:g} µg noise. "
        + (f"Navigation: {spec['navigation']['hours']:g} h static at {spec['navigation']['latitude_deg']:g}° latitude."
           if has_nav else "Navigation: not computed."),
        f"- Wall time {wall:.1f} s over {len(sessions)} session(s): "
        + "; ".join(f"{s['executor']} ×{s['workers']}: {s['trials']} trials in {s['wall_s']:.1f} s"
                    + _busy(s) + (f" (code {s['code']})" if s.get("code") else "") for s in sessions),
        "",
        "**How to read.** *success*: share of runs whose final cost is within the 99.9 % χ² quantile of the "
        "cost at the optimum (reached the noise floor). *RMSE/CRLB*: RMS over parameters of each parameter's "
        "RMSE over runs divided by its Cramér-Rao bound (1 = as good as any unbiased estimator can be; "
        "unobservable directions excluded, see below). *RMSE/CRLB with presets*: the whole error against "
        "the bound of the data and the presets together (the presets as one more measurement of every "
        "parameter, with the manufacturer's error SD); no method can beat it, so a ratio below 1 in the "
        "first column and near 1 here means the accuracy came from the presets, not from the data. "
        "*Verification*: |‖A‖ − g| on an independent "
        "verification set with the estimated calibration (2020 paper, Table 5), mean over positions "
        "(SD over positions), averaged over runs. Runtime: solver time per calibration. "
        f"*value [lo, hi]* after success, RMSE/CRLB and the median runtime: {100 * anytime.LEVEL:.0f} % percentile "
        f"bootstrap interval over the Monte-Carlo runs ({anytime.RESAMPLES} resamples, seed {spec['seed']}).",
        "",
    ]
    if len(cs) > 1:
        with_p = any(_has_presets_bound(cg) for cg in cs.values())
        L += ["## Overview", "", ("RMSE/CRLB / RMSE/CRLB with presets" if with_p else "RMSE/CRLB")
              + " (success rate) of every solver in every model × scheme, most accurate "
              "first (mean rank over the columns); runtime: median over the columns of the median solver time.", ""]
        L += overview(cs)
    summary = []
    for (model, scheme), cg in cs.items():
        slug = f"{model}_{scheme}".replace(":", "-")
        L += [f"## {model}, {scheme} positions", ""]
        truth_ver = np.nanmean([g.summary()["ver_truth_ug"] for g in cg if g.ok]) if any(g.ok for g in cg) else np.nan
        L += [f"Truth calibration on the verification set: {_f(truth_ver, '.2f')} µg (the noise floor).", ""]
        header = (SUMMARY_HEADER[:3] + (["RMSE/CRLB with presets"] if _has_presets_bound(cg) else [])
                  + SUMMARY_HEADER[3:] + (["nav max / mean nmi"] if has_nav else []) + ["failed"])
        L += _table(header, _summary_rows(cg, has_nav, cis))
        for g in cg:
            summary.append({**g.summary(), **{f"{k}_ci": list(v) for k, v in cis[id(g)].items()},
                            "reference": g.reference, "reference_error_arcsec": g.reference_error_arcsec})
        ttl = f"{spec['name']}: {model}, {scheme} positions"
        # the turntable fit minimises another cost (3-D residuals): not on the cost figures
        norm = [g for g in cg if not g.reference] or cg
        f1 = figures.cost_per_run(norm, f"{ttl}: final cost per run", figdir / f"cost_{slug}.png")
        f2 = figures.convergence(norm, f"{ttl}: convergence", figdir / f"convergence_{slug}.png")
        f3 = figures.error_vs_crlb(cg, f"{ttl}: error against the Cramér-Rao bound", figdir / f"crlb_{slug}.png")
        f4 = figures.verification(cg, f"{ttl}: verification error per position", figdir / f"verification_{slug}.png")
        f0 = figures.ranking(cg, f"{ttl}: accuracy of every solver", figdir / f"ranking_{slug}.png")
        L += [f"![ranking](figures/{f0.name})", "",
              f"![final cost per run](figures/{f1.name})", "", f"![convergence](figures/{f2.name})", "",
              f"![error against CRLB](figures/{f3.name})", "", f"![verification](figures/{f4.name})", ""]
        # per-parameter ratios
        names = cg[0].names
        obs = cg[0].ok[0]["observable"] if cg[0].ok else [1] * len(names)
        L += ["RMSE / CRLB per parameter (\\* = observable part only):", ""]
        L += _table(["solver"] + [n + ("" if o else "\\*") for n, o in zip(names, obs)],
                    [[f"`{_label(g)}`"] + [_f(p["ratio"], ".2g") for p in g.parameters()] for g in _rank(cg)])
        un = [(g, g.unobservable()) for g in _rank(cg) if g.unobservable()]
        if un:
            dirs = [d["direction"] for d in un[0][1]]
            L += ["Unobservable directions (natural units; set by the presets, not by the data, so not scored): "
                  "RMS error along each, over runs.", ""]
            L += _table(["solver"] + [f"`{d}`" for d in dirs],
                        [[f"`{_label(g)}`"] + [_f(d["rms"], ".2e") for d in u] for g, u in un])
        L += _navigation_section((model, scheme), cg, spec["navigation"], figdir, slug)
        L += _traditional_section((model, scheme), cg, figdir, slug)
        fails = [(g, g.failures) for g in cg if g.failures]
        if fails:
            L += ["Failures:", ""] + [f"- `{g.solver}` ({g.n_failed}): " + "; ".join(m[:200] for m in f[:3])
                                      for g, f in fails] + [""]
    if len(cs):
        p = figures.accuracy_runtime(cs, f"{spec['name']}: accuracy against runtime", figdir / "accuracy_runtime.png")
        L += ["## Accuracy against runtime", "", f"![accuracy against runtime](figures/{p.name})", ""]
    L += _anytime_section(rows, order, spec, figdir)
    L += ["Per-parameter mean error, RMSE, SD and CRLB: [parameters.md](parameters.md). "
          "Every trial: `trials.csv` / `trials.parquet` / `study.sqlite`.", ""]
    (folder / "parameters.md").write_text(_parameters_md(cs))
    # strict JSON: a value that could not be computed (no presets, no navigation) is null, not NaN
    (folder / "summary.json").write_text(json.dumps(_json_safe(summary), indent=1, allow_nan=False))
    out = folder / "report.md"
    out.write_text("\n".join(L))
    return out
