"""Parts of a study's ``report.md`` (:func:`optcal.studies.report.write_report`): the markdown helpers the report
shares (numbers with their bootstrap interval, tables, a group's label, a scheme's name with its size, the
accuracy per position), the report's head (the study and how to read its tables), and the sections a
report has only when the study calls for them: traditional against in-field calibration (docs/design.md,
"Report"), static navigation (2020 paper, Eq. 23 and Table 6) and anytime performance (runtime ECDFs, data and
performance profiles; :mod:`optcal.studies.anytime`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from optcal.studies import anytime, figures
from optcal.studies.metrics import Group


def fmt(v, spec: str = ".3g") -> str:
    """``v`` in the format ``spec``; "–" for a missing or non-finite value."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return format(v, spec)


def with_ci(v, ci, spec: str = ".3g", scale: float = 1.0, unit: str = "") -> str:
    """'value [lo, hi]' (a 95 % bootstrap interval over runs); the value alone when there is none."""
    if v is None or not math.isfinite(v):
        return "–"
    text = format(v * scale, spec) + unit
    if ci is None or not all(math.isfinite(c) for c in ci):
        return text
    return f"{text} [{format(ci[0] * scale, spec)}, {format(ci[1] * scale, spec)}]"


def md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A markdown table's lines, then an empty line."""
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return out + [""]


def label_of(g: Group) -> str:
    """A group's name in the report: the solver's label, or the turntable calibration with its error."""
    if g.reference:
        return f"traditional ({g.solver_name}, {g.reference_error_arcsec:g}″)"
    return g.solver


def positions_of(scheme: str) -> int | None:
    """How many positions a scheme name holds (docs/design.md, "Position schemes"): 6, 24 and 36 by name, N in
    plan:<D|A|E>N and random:N, the rows of a scheme file; None when not known (a scheme file no longer there)."""
    name = str(scheme)
    if name.isdigit():
        return int(name)
    head, _, rest = name.partition(":")
    digits = rest.split(":")[0].lstrip("DAE") if head == "plan" else rest
    if head in ("plan", "random") and digits.isdigit():
        return int(digits)
    if name.lower().endswith(".csv"):
        from optcal.core.errors import InputError
        from optcal.core.plan.schemefile import read_scheme

        try:
            return len(read_scheme(name))
        except (InputError, OSError):
            return None
    return None


def scheme_phrase(scheme: str) -> str:
    """A scheme as the report names it: "24 positions", "plan:D15 (15 positions)"."""
    n = positions_of(scheme)
    if str(scheme).isdigit():
        return f"{scheme} positions"
    return f"{scheme} ({n} positions)" if n else f"scheme {scheme}"


def schemes_phrase(schemes) -> str:
    """Several schemes: "24, 36 positions" when all are named by their size, else each as :func:`scheme_phrase`."""
    if all(str(s).isdigit() for s in schemes):
        return f"{', '.join(map(str, schemes))} positions"
    return ", ".join(scheme_phrase(s) for s in schemes)


def per_position(values, n: int | None, sigma: float) -> float:
    """Accuracy per position: the RMS of ``values`` (per-parameter RMSEs or Cramér-Rao bounds, in the
    model's natural units with outputs in g) times √n over the noise SD σ (g) of a reading. A scheme's
    bounds fall as σ/√n at a given geometry, so this number is the geometry's (and the solver's) alone, and
    compares schemes of different sizes; NaN when n or σ is not known."""
    v = np.asarray([x for x in values if x is not None], float)
    v = v[np.isfinite(v)]
    if not v.size or not n or not sigma or not sigma > 0:
        return float("nan")
    return float(np.sqrt(np.mean(v**2)) * math.sqrt(n) / sigma)


PER_POSITION_TEXT = (
    "*RMSE·√N/σ (per position)*: the accuracy per position, to compare schemes of different sizes N (RMSE/CRLB "
    "cannot: each scheme has its own bound): RMS over parameters of each parameter's RMSE over runs (its "
    "observable part) times √N over the noise SD σ of a reading, each parameter in the model's natural units "
    "with outputs in g (scale factors and angles times 1 g, biases in g, K2 times (1 g)²: the specific force "
    "its error makes at 1 g). A scheme's bounds fall as σ/√N at a given geometry, so this is what its geometry "
    "and the solver make of each position: the 24- and 36-position rotation schemes have the same bound per "
    "position (given above each table), a scheme whose positions tell more has a smaller one. ")


def accelerometer(spec: dict) -> bool:
    """Whether a study is of the accelerometer's problem (a spec without ``problem`` is): the accuracy per
    position divides by its noise per reading, which the gyroscope's problem does not have."""
    return spec.get("problem", "accelerometer") == "accelerometer"


def ranked_on(presets: bool) -> str:
    """What the report ranks on (:func:`optcal.studies.report.rank_value`), in words."""
    return ("RMSE/CRLB with presets (the bound of data and presets together)" if presets
            else "RMSE/CRLB (the data's bound)")


def preamble(spec: dict, rows: list[dict], spec_hash: str, presets: bool, final_gap: float,
             stagnation=None) -> list[str]:
    """The report's head: the study, its trials and settings, a placeholder line "@@WALL@@" for the wall
    time (known only at the end), and how to read the tables."""
    expected = spec["runs"] * len(spec["models"]) * len(spec["schemes"]) * len(spec["solvers"])
    failed = sum(r["status"] != "ok" for r in rows)
    has_nav = any(r.get("nav_max_nmi") is not None for r in rows)
    budgets = {json.dumps(s["budget"], sort_keys=True) for s in spec["solvers"]}
    budget = (", ".join(f"{k} {v:g}" for k, v in spec["solvers"][0]["budget"].items()) or "the solvers' defaults"
              ) if len(budgets) == 1 else "per solver (see the spec)"
    L = [f"# Study `{spec['name']}`", ""]
    if spec.get("description"):
        L += [spec["description"], ""]
    truth = spec['truth'] if isinstance(spec['truth'], str) else 'given values'
    if accelerometer(spec):
        setting = (f"noise {spec['noise_ug']:g} µg; placement tilt {spec['tilt_deg']:g}°; truth `{truth}`")
        extra = (f"- Verification: {scheme_phrase(spec['verification']['scheme'])}, "
                 f"{spec['verification']['noise_ug']:g} µg noise. "
                 + (f"Navigation: {spec['navigation']['hours']:g} h static at "
                    f"{spec['navigation']['latitude_deg']:g}° latitude." if has_nav else "Navigation: not computed."))
    else:
        g = spec["gyroscope"]
        setting = (f"the gyroscope's problem: {g['rate_hz']:g} Hz, rests of {g['rest_s']:g} s, {g['profile']} turns "
                   f"of {g['motion_s']:g} s, white rate noise {g['noise_rad_s_rthz']:g} rad/s/√Hz, bias random walk "
                   f"{g['bias_walk_rad_s2_rthz']:g} rad/s²/√Hz, nominal scale {g['scale']:g} counts per rad/s, "
                   f"{spec['noise_ug']:g} µg on each rest's mean specific force; truth `{truth}`")
        extra = "- Verification and navigation: none (the gyroscope's problem has neither)."
    L += [
        f"- Spec hash `{spec_hash}`; {len(rows)} of {expected} trials stored"
        + (" (**incomplete**: run the spec again into this folder to finish)" if len(rows) < expected else "")
        + f"; {failed} failed.",
        f"- {spec['runs']} Monte-Carlo runs, base seed {spec['seed']}; models {', '.join(spec['models'])}; "
        f"schemes {schemes_phrase(spec['schemes'])}; {setting}; presets `{spec['presets']}`; budget: {budget}.",
        extra,
        "@@WALL@@",
        "",
        "**How to read.** *At noise floor*: share of runs whose final cost is within the 99.9 % χ² quantile of "
        "the cost at the optimum (the `success_rate` of summary.json). It is a statistical test, not a distance "
        "to the optimum: a final cost up to that quantile passes, even when it lies well above the optimum of "
        "the run's data, so it is much looser than the anytime table's *solved gap ≤ 0.01* (the cost within 1 % "
        "of that optimum); a staged solver, which keeps parameters near the presets, can be at the noise floor "
        "in every run and within 1 % of the optimum in few. "
        "*RMSE/CRLB*: RMS over parameters of each parameter's "
        "RMSE over runs divided by its Cramér-Rao bound (1 = as good as any unbiased estimator can be; "
        "unobservable directions excluded, see below). *RMSE/CRLB with presets*: the whole error against "
        "the bound of the data and the presets together (the presets as one more measurement of every "
        "parameter, with the manufacturer's error SD); no method can beat it, so a ratio below 1 in the "
        "first column and near 1 here means the accuracy came from the presets, not from the data. "
        + (PER_POSITION_TEXT if accelerometer(spec) else "") +
        f"Solvers are ranked on {ranked_on(presets)}. "
        + ("*Verification*: |‖A‖ − g| on an independent "
           "verification set with the estimated calibration (2020 paper, Table 5), mean over positions "
           "(SD over positions), averaged over runs. *Final cost*: Σ (‖A‖ − g)² over the positions, in g². "
           if accelerometer(spec) else
           "*Final cost*: the χ² of the whitened residuals (each motion's two, each rest's three when the bias is "
           "fitted; docs/gyroscope.md), no unit. ") +
        "*Runtime*: solver time per calibration. *Evaluations*: evaluations of the cost over the whole data set "
        "per calibration; a Jacobian counts as one (so a Levenberg-Marquardt fit's few evaluations are residual "
        "vectors and Jacobians together), and a trial stops once its cost is within "
        f"{final_gap:g} of its data's optimum, so a fast method uses far fewer than its budget"
        + (f"; a trial whose solver takes the stagnation rule (CMA-ES, in staged:'s stages too; nevergrad's and "
           f"mealpy's optimisers with stop_on_stagnation) also ends once its best cost has improved by no more "
           f"than {stagnation.rtol:g} of itself over the last {100 * stagnation.share:g} % of its budget "
           "(*ended by* in the solver settings). "
           if stagnation is not None else ". ") +
        "*Navigation*: position error after the hours of static navigation, in nautical miles (nmi). "
        f"*value [lo, hi]* after the share at the noise floor, RMSE/CRLB and the median runtime: "
        f"{100 * anytime.LEVEL:.0f} % percentile "
        f"bootstrap interval over the Monte-Carlo runs ({anytime.RESAMPLES} resamples, seed {spec['seed']}).",
        "",
    ]
    return L


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


def traditional_section(cell_key, gs: list[Group], figdir: Path, slug: str, render: figures.Renderer) -> list[str]:
    ref = sorted([g for g in gs if g.reference], key=lambda g: g.reference_error_arcsec)
    inf = [g for g in gs if not g.reference and g.ok]
    if not ref or not inf:
        return []
    model, scheme = cell_key
    lines = [f"### Traditional against in-field: {model}, {scheme_phrase(scheme)}", ""]
    best_in = min(inf, key=lambda g: np.nan_to_num(g.accuracy, nan=np.inf))
    metrics = [("accuracy", "RMSE/CRLB", lambda s: s["accuracy"])]
    metrics.append(("verification", "verification |‖A‖−g| (µg)", lambda s: s["ver_mean_ug"]))
    if any(r.get("nav_max_nmi") is not None for g in gs for r in g.ok):
        metrics.append(("navigation", "5-h max position error (nmi)", lambda s: s["nav_max_nmi"]))
    header = ["calibration"] + [m[1] for m in metrics]
    rows = [[label_of(g)] + [fmt(fn(g.summary())) for _, _, fn in metrics] for g in ref]
    rows += [[f"in-field `{g.solver}`"] + [fmt(fn(g.summary())) for _, _, fn in metrics] for g in inf]
    lines += md_table(header, rows)
    for key, name, fn in metrics:
        levels = [(g.reference_error_arcsec, fn(g.summary())) for g in ref]
        if not all(np.isfinite(y) for _, y in levels):
            continue
        said = [f"`{g.solver}` ({fmt(fn(g.summary()))}) {_crossing(levels, fn(g.summary()))}"
                for g in inf if np.isfinite(fn(g.summary()))]
        if not said:
            continue
        lines.append(f"- **{name}**: in-field calibration beats the turntable calibration: " + "; ".join(said) + ".")
        v = fn(best_in.summary())
        if len(levels) > 1 and np.isfinite(v):
            p = render.draw(figures.traditional, figdir / f"traditional_{key}_{slug}.png", levels,
                            [(g.solver, fn(g.summary())) for g in inf], name,
                            f"{model}, {scheme_phrase(scheme)}: {name}")
            lines.append(f"  ![{name}](figures/{p.name})")
    return lines + [""]


def navigation_section(cell_key, gs: list[Group], nav_spec: dict, figdir: Path, slug: str,
                       render: figures.Renderer) -> list[str]:
    nav = [g for g in gs if any(r.get("nav_max_nmi") is not None for r in g.ok)]
    if not nav:
        return []
    model, scheme = cell_key
    hours = nav_spec["hours"]
    att = ", ".join(f"{a:g}" for a in nav_spec.get("attitude_deg", (0, 0, 0)))
    lines = [f"### Static navigation ({hours:g} h): {model}, {scheme_phrase(scheme)}", "",
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
        rows.append([label_of(g), fmt(s["nav_max_nmi"], ".4f"), fmt(s["nav_mean_nmi"], ".4f")])
    lines += md_table(["calibration", "max error (nmi)", "mean error (nmi)"], rows)
    p = render.draw(figures.navigation, figdir / f"navigation_{slug}.png", nav, hours,
                    f"{model}, {scheme_phrase(scheme)}: static navigation error")
    return lines + [f"![navigation](figures/{p.name})", ""]


def anytime_section(rows: list[dict], order: list[str], spec: dict, figdir: Path,
                    render: figures.Renderer) -> list[str]:
    """Runtime ECDFs, data and performance profiles, and their table (optcal.studies.anytime)."""
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
    p1 = render.draw(figures.runtime_ecdf, figdir / "anytime_ecdf.png", at, f"{name}: runtime ECDFs", order=order)
    search = search_methods(spec, at.solvers)
    if search:
        ref = [s for s in ("scipy-lm",) if s in at.solvers]
        p0 = render.draw(figures.runtime_ecdf, figdir / "anytime_ecdf_search.png", at,
                         f"{name}: runtime ECDFs of the search methods" + (" and scipy-lm" if ref else ""),
                         order=order, only=search + ref)
    p2 = render.draw(figures.data_profiles, figdir / "data_profiles.png", at, f"{name}: data profiles", order=order)
    p3 = render.draw(figures.performance_profiles, figdir / "performance_profiles.png", at,
                     f"{name}: performance profiles", order=order)
    L += [f"![runtime ECDFs](figures/{p1.name})", ""]
    if at.hits_s and any(np.isfinite(h).any() for h in at.hits_s.values()):
        pt = render.draw(figures.runtime_ecdf_time, figdir / "anytime_ecdf_time.png", at,
                         f"{name}: runtime ECDFs against solver time", order=order)
        L += ["The same (trial, target) pairs against solver time, each met at the time its point was found "
              "(a solver's own overhead per evaluation counts here; the number in the legend is the share reached):",
              "", f"![runtime ECDFs against time](figures/{pt.name})", ""]
    if search:
        L += [f"The search methods alone (every solver of the metaheuristic and global families, run jointly: "
              f"{', '.join(f'`{s}`' for s in search)}), beside scipy-lm, each in colour:", "",
              f"![runtime ECDFs of the search methods](figures/{p0.name})", ""]
    L += [f"![data profiles](figures/{p2.name})", "",
          f"![performance profiles](figures/{p3.name})", ""]
    k1, k2 = f"{pk1}_{pt1:g}", f"{pk2}_{pt2:g}"
    L += [f"Per solver, largest cost-ECDF area first; *reached*: share of (trial, target) pairs met within the "
          f"budget; *solved*: share of problems on which the profile target is met; *fastest*: share of problems "
          f"on which the solver meets it first (performance profile at τ = 1, ties count for each). "
          f"[lo, hi]: {100 * anytime.LEVEL:.0f} % bootstrap interval over runs.", ""]
    header = ["solver", "cost: reached", "cost: ECDF area", "accuracy: reached", "accuracy: ECDF area",
              f"solved {_target_name(pk1, pt1)}", f"fastest {_target_name(pk1, pt1)}",
              f"solved {_target_name(pk2, pt2)}", f"fastest {_target_name(pk2, pt2)}"]
    L += md_table(header, [[f"`{r['solver']}`",
                          with_ci(r["cost_reached"], r["cost_reached_ci"], ".0f", 100, " %"),
                          with_ci(r["cost_area"], r["cost_area_ci"], ".2f"),
                          with_ci(r["accuracy_reached"], r["accuracy_reached_ci"], ".0f", 100, " %"),
                          with_ci(r["accuracy_area"], r["accuracy_area_ci"], ".2f"),
                          with_ci(r[f"solved_{k1}"], r[f"solved_{k1}_ci"], ".0f", 100, " %"),
                          with_ci(r[f"fastest_{k1}"], r[f"fastest_{k1}_ci"], ".0f", 100, " %"),
                          with_ci(r[f"solved_{k2}"], r[f"solved_{k2}_ci"], ".0f", 100, " %"),
                          with_ci(r[f"fastest_{k2}"], r[f"fastest_{k2}_ci"], ".0f", 100, " %")] for r in recs])
    return L


def search_methods(spec: dict, present: list[str]) -> list[str]:
    """The labels of the spec's in-field configurations whose solver belongs to the metaheuristic or global
    family (docs/design.md, "The solver contract": a solver's ``family``), in the spec's order: the derivative-free
    searches that the anytime figures put side by side (a wrapper, such as staged:, has its own family and is left
    out). A configuration that can no longer be built (a solver since removed) is left out."""
    from optcal import solvers

    out = []
    for c in spec.get("solvers", []):
        label = c.get("label") or c["name"]
        if label not in present or c.get("reference"):
            continue
        try:
            family = solvers.get(c["name"], **c.get("options", {})).family
        except Exception:  # noqa: BLE001 - an old store may name a solver this installation lacks
            continue
        if family in ("metaheuristic", "global"):
            out.append(label)
    return out


def _target_name(kind: str, target: float) -> str:
    return f"gap ≤ {target:g}" if kind == "cost" else f"accuracy ≤ {target:g}"
