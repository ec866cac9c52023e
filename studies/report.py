"""``optcal study report DIR``: ``report.md`` with tables and PNG figures, ``parameters.md`` with every
per-parameter statistic, and ``summary.json`` (one record per solver × scheme × model) for tools and CI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from . import anytime, figures
from .metrics import Group, cells, groups
from .report_sections import anytime_section, fmt, label_of, md_table, navigation_section, traditional_section, with_ci
from .store import Store


def _rank(gs: list[Group]) -> list[Group]:
    """Most accurate first; never-converging and failed groups last."""
    return sorted(gs, key=lambda g: (-round(g.success_rate, 6), np.nan_to_num(g.accuracy, nan=np.inf)))


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
            f"`{label_of(g)}`", with_ci(s["success_rate"], ci.get("success_rate"), ".0f", 100, " %"),
            with_ci(s["accuracy"], ci.get("accuracy"), ".2f"),
            *([with_ci(s["accuracy_presets"], ci.get("accuracy_presets"), ".2f")] if presets else []),
            f"{fmt(s['ver_mean_ug'], '.2f')} ({fmt(s['ver_sd_ug'], '.2f')})",
            f"{fmt(s['cost_median'], '.3e')} [{fmt(s['cost_min'], '.2e')}, {fmt(s['cost_max'], '.2e')}]",
            *([with_ci(s["runtime_median_s"], ci.get("runtime_median_s"), ".3g")] if cis is not None else []),
            f"{fmt(s['runtime_median_s'], '.3g')} [{fmt(s['runtime_p10_s'], '.2g')}, {fmt(s['runtime_p90_s'], '.2g')}]",
            fmt(s["nfev_median"], ".0f"),
            fmt(s["evals_per_s"], ",.0f"),
        ]
        if nav:
            r.append(f"{fmt(s['nav_max_nmi'], '.3f')} / {fmt(s['nav_mean_nmi'], '.3f')}")
        r.append(str(s["failed"]))
        rows.append(r)
    return rows


SUMMARY_HEADER = ["solver", "success", "RMSE/CRLB", "verification µg mean (SD)", "final cost median [min, max]",
                  "runtime s median [95 % CI]", "runtime s median [p10, p90]", "evaluations", "evaluations/s"]


def _parameters_md(cs) -> str:
    lines = ["# Per-parameter statistics", "",
             "Error = estimate − truth over the runs that did not fail. CRLB: Cramér-Rao SD at the truth with "
             "the simulation noise; ratio = RMSE of the observable part / CRLB. Parameters marked * have weight "
             "in an unobservable direction: their ratio scores only their observable part.", ""]
    for (model, scheme), gs in cs.items():
        for g in gs:
            lines.append(f"## {model}, {scheme} positions: `{label_of(g)}`")
            lines.append("")
            rows = [[p["name"] + ("" if p["observable"] else "*"), fmt(p["mean"], ".3e"), fmt(p["rmse"], ".3e"),
                     fmt(p["sd"], ".3e"), fmt(p["crlb"], ".3e"), fmt(p["ratio"], ".3g")] for p in g.parameters()]
            lines += md_table(["parameter", "mean error", "RMSE", "SD", "CRLB", "RMSE/CRLB"], rows)
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
        out += md_table(["solver", "success", "RMSE/CRLB"] + (["with presets"] if wp else [])
                      + ["verification µg", "runtime s"],
                      [[f"`{label_of(g)}`", f"{100 * g.success_rate:.0f} %", fmt(g.accuracy, ".2f")]
                       + ([fmt(g.accuracy_presets, ".2f")] if wp else [])
                       + [fmt(g.summary()["ver_mean_ug"], ".2f"), fmt(g.summary()["runtime_median_s"], ".3g")]
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
            both = fmt(g.accuracy, ".2f") + (f" / {fmt(bp, '.2f')}" if np.isfinite(bp) else "")
            cellv.append(f"{both} ({100 * g.success_rate:.0f} %)")
        rts = [by[k][n].summary()["runtime_median_s"] for k in keys if n in by[k]]
        rates = [by[k][n].summary()["evals_per_s"] for k in keys if n in by[k]]
        first = next(by[k][n] for k in keys if n in by[k])
        rows.append([f"`{label_of(first)}`"] + cellv + [fmt(float(np.median(rts)), ".3g"),
                                                      fmt(float(np.median(rates)), ",.0f")])
    return md_table(["solver"] + [f"{m}, {s}" for m, s in keys] + ["runtime s", "evaluations/s"], rows)


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
        L += [f"Truth calibration on the verification set: {fmt(truth_ver, '.2f')} µg (the noise floor).", ""]
        header = (SUMMARY_HEADER[:3] + (["RMSE/CRLB with presets"] if _has_presets_bound(cg) else [])
                  + SUMMARY_HEADER[3:] + (["nav max / mean nmi"] if has_nav else []) + ["failed"])
        L += md_table(header, _summary_rows(cg, has_nav, cis))
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
        L += md_table(["solver"] + [n + ("" if o else "\\*") for n, o in zip(names, obs)],
                    [[f"`{label_of(g)}`"] + [fmt(p["ratio"], ".2g") for p in g.parameters()] for g in _rank(cg)])
        un = [(g, g.unobservable()) for g in _rank(cg) if g.unobservable()]
        if un:
            dirs = [d["direction"] for d in un[0][1]]
            L += ["Unobservable directions (natural units; set by the presets, not by the data, so not scored): "
                  "RMS error along each, over runs.", ""]
            L += md_table(["solver"] + [f"`{d}`" for d in dirs],
                        [[f"`{label_of(g)}`"] + [fmt(d["rms"], ".2e") for d in u] for g, u in un])
        L += navigation_section((model, scheme), cg, spec["navigation"], figdir, slug)
        L += traditional_section((model, scheme), cg, figdir, slug)
        fails = [(g, g.failures) for g in cg if g.failures]
        if fails:
            L += ["Failures:", ""] + [f"- `{g.solver}` ({g.n_failed}): " + "; ".join(m[:200] for m in f[:3])
                                      for g, f in fails] + [""]
    if len(cs):
        p = figures.accuracy_runtime(cs, f"{spec['name']}: accuracy against runtime", figdir / "accuracy_runtime.png")
        L += ["## Accuracy against runtime", "", f"![accuracy against runtime](figures/{p.name})", ""]
    L += anytime_section(rows, order, spec, figdir)
    L += ["Per-parameter mean error, RMSE, SD and CRLB: [parameters.md](parameters.md). "
          "Every trial: `trials.csv` / `trials.parquet` / `study.sqlite`.", ""]
    (folder / "parameters.md").write_text(_parameters_md(cs))
    # strict JSON: a value that could not be computed (no presets, no navigation) is null, not NaN
    (folder / "summary.json").write_text(json.dumps(_json_safe(summary), indent=1, allow_nan=False))
    out = folder / "report.md"
    out.write_text("\n".join(L))
    return out
