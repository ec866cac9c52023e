"""The plain-text report of model discovery (what ``optcal discover`` prints; docs/discovery.md shows
examples): the base fit, each step with its test and fitted parameters, the candidates of each round, the
final model against the noise floor and the verdict (docs/design.md, "Model discovery").

The functions read a :class:`optcal.core.discovery.results.DiscoveryReport` by its attributes; of discovery they import
only :func:`optcal.core.discovery.dictionary.list_part`, so the report can call them without a cycle.
"""

from __future__ import annotations

import numpy as np

from optcal.core.discovery.dictionary import list_part

U = 1e6  # g → µg


def summary(report) -> str:
    """The report as lines of text."""
    f = report.final
    lines = [f"base {report.base}: {len(f.problem.data)} positions, residual RMS {report.initial.rms * U:.3f} µg; "
             f"a term is added when p < α/k (α = {report.alpha:g}, k candidates tested) and "
             f"ΔBIC < {report.bic_threshold:g}"]
    list_steps = [s for s in report.steps if s.source == "list"]
    for k, s in enumerate(list_steps, 1):
        lines += step_lines(k, s)
        lines.append("    candidates this round:")
        lines += round_lines([x for x in s.scores if x is not s.chosen])
    lines.append("last round of the list (nothing added):" if report.last_round else "no candidate of the list left "
                 "to test")
    lines += round_lines(report.last_round)
    if report.diagnostics_listed is not None:
        lines.append(f"residual diagnostics after the list ({report.diagnostics_listed.floor.describe()}): "
                     f"{report.diagnostics_listed.summary()}")
    if report.dictionary is not None:
        lines += dictionary_lines(report, len(list_steps))
    floor = "unknown (no n, sx, sy, sz in the data)" if report.noise_g is None else (
        f"σ = {report.noise_g * U:.3f} µg (RMS over positions), expected RMS {report.expected_rms * U:.3f} µg")
    lines.append(f"final model {f.model.name}: residual RMS {f.rms * U:.3f} µg; noise floor {floor}")
    chi = report.chi2
    detail = "" if chi is None else f" (χ² = {chi[0]:.1f} on {chi[1]} dof, p = {chi[2]:.3g})"
    if chi is None and report.lack_of_fit is not None:
        F, q, dof, p = report.lack_of_fit
        detail = f" (lack of fit against the replicates: F({q},{dof}) = {F:.3g}, p = {p:.3g})"
    lines.append(f"verdict: {report.verdict}{detail}")
    lines += ending(report)
    lines += [f"note: {n}" for n in report.notes]
    return "\n".join(lines)


def step_lines(k: int, s) -> list[str]:
    from optcal.core.model import TERMS

    c = s.chosen
    what = f" ({TERMS[s.term].description})" if s.source == "dictionary" else ""
    verb = f"replace {s.replaces} by" if s.replaces else "add"
    against = f" (the test against the model without {s.replaces}:" if s.replaces else ","
    lines = [f"step {k}: {verb} {s.term}{what}: RMS {s.before.rms * U:.3f} → {s.after.rms * U:.3f} µg{against} "
             f"F({c.q},{c.dof}) = {c.f_statistic:.4g}, p = {c.p_value:.3g} (threshold "
             f"{s.p_threshold:.3g}), ΔBIC = {c.delta_bic:.2f}, LR = {c.lr_statistic:.2f}" + (")" if s.replaces else "")]
    units = s.after.model.units(s.after.problem.data.units)
    for n, v in s.parameters.items():
        se = s.stderr[n]
        unit = units[n] if s.source == "dictionary" else ""
        lines.append(f"    {n:8s} {v: .6e} ± {se:.2e} {unit}".rstrip() if np.isfinite(se)
                     else f"    {n:8s} {v: .6e} {unit}".rstrip())
    if s.source == "dictionary":
        phys = TERMS[s.term].feature.physical()
        if phys is not None:
            vals = ", ".join(f"{v * phys[0]:.4g}" for v in s.parameters.values())
            lines.append(f"    per unit of the context: {vals} {phys[1]}")
        if s.equivalents:
            lines.append("    the norm of static positions cannot tell it from: " + ", ".join(
                f"{t} ({TERMS[t].description})" for t in s.equivalents))
        part = list_part(s.term)
        if part:
            lines.append(f"    it is the list's {part.replace(chr(39) + 's ', ' (')}) on this output alone")
    if s.alternatives:
        lines.append("    nearly as good (ΔBIC within 2: confounded on these data): " + ", ".join(s.alternatives))
    return lines


def dictionary_lines(report, k0: int) -> list[str]:
    """The dictionary's search: what it held, each step, the terms removed, the last round."""
    d = report.dictionary
    parts = ["products and powers of the axes to order 3"]
    if d["temp_scale_C"]:
        parts.append(f"powers of (T − T̄)/{d['temp_scale_C']:g} °C")
    if d["time_scale_s"]:
        parts.append(f"powers of (t − t0)/{d['time_scale_s']:g} s")
    rounds = [r for r in d.get("periods_by_round_s", [d["periods_s"]]) if r]
    if rounds:
        each = "; then ".join(", ".join(f"{p:g}" for p in r) + " s" for r in rounds)
        parts.append(f"sinusoids at the periodogram's peaks, round by round: {each} (over "
                     f"{d['n_independent_frequencies']} independent frequencies)")
    parts.append("the previous pose's signs")
    rule = (f"a feature is added when p < α/k (k = {d['k']:.1f}) and ΔBIC < {report.bic_threshold:g}" if d["k"] > 0
            else "none could be tested (too few degrees of freedom, or the model explains them already)")
    lines = [f"dictionary: {d['atoms']} features ({'; '.join(parts)}); {rule}"]
    steps = [s for s in report.steps if s.source == "dictionary"] or report.partial
    for j, s in enumerate(steps, k0 + 1):
        lines += step_lines(j, s)
    for r in report.removed:
        if r.kind == "replaced":
            continue  # said by the step that replaced it
        if r.kind == "narrowed":
            lines.append(f"narrowed {r.term} to {r.after} (the other outputs: p = {r.p_value:.3g} together, ≥ α)")
        else:
            lines.append(f"removed {r.term}: p = {r.p_value:.3g} once {r.after} is in (≥ α = {report.alpha:g})")
    last = sorted([s for s in report.dictionary_last_round if s.tested], key=lambda s: s.p_value)[:5]
    if last:
        m = len(report.final.problem.data)
        lines.append("dictionary's last round (nothing added), best five:")
        lines += [f"    {s.term:18s} p = {s.p_value:.3g}, ΔBIC = {s.delta_bic:+.2f}, RMS would be "
                  f"{np.sqrt(s.rss_after / m) * U:.3f} µg" for s in last]
    return lines


def ending(report) -> list[str]:
    """What the search found, or, honestly, what remains and that no term explains it."""
    out = []
    for s in report.found:
        how = ("closes the gap to the floor" if report.closes_gap else
               "significant, but without a floor whether it closes the gap is unknown")
        out.append(f"found: {s.formula} [{s.kept}]: {how}; fit it with --model {report.base}+"
                   f"{'+'.join(t.kept for t in report.found)}")
    diag = report.diagnostics
    if report.verdict == "something remains":
        sig = [] if diag is None else diag.significant
        where = ", ".join(f"{d.name}" + (f" (period {d.extra['period_s']:.4g} s)" if "period_s" in d.extra else "")
                          + f" p = {d.p_value:.2g}" for d in sig) or "no single diagnostic"
        near = ""
        if report.partial:
            s = report.partial[-1]
            floor = report.floor.rms_g if report.floor is not None else None
            near = (f"; the nearest, {s.term} ({s.formula}), brings the RMS {report.listed.rms * U:.3f} → "
                    f"{s.after.rms * U:.3f} µg" + (f" (the floor's RMS {floor * U:.3f} µg)" if floor else "")
                    + (f", but the test at the floor still gives p = {report.gap_p:.2g}"
                       if report.gap_p is not None else ""))
        out.append(f"structure remains: {where} is significant; no term of the list or the dictionary closes "
                   f"the gap{near}")
    elif diag is not None and diag.significant:
        where = ", ".join(f"{d.name} p = {d.p_value:.2g}" for d in diag.significant)
        out.append(f"structure remains below the omnibus test: {where} is significant, although the residual as a "
                   "whole passes; no term of the list or the dictionary explains it")
    if report.floor is not None and report.floor.kind is None:
        out.append("floor unknown: " + report.floor.describe().split(": ", 1)[1])
    return out


def round_lines(scores) -> list[str]:
    """One line per candidate of a round: tested ones by p-value (with what the RMS would be), then the
    skipped ones with the reason."""
    out = []
    for s in sorted(scores, key=lambda s: (not s.tested, s.p_value if s.tested else 0)):
        if s.tested:
            out.append(f"    {s.term:18s} p = {s.p_value:.3g}, ΔBIC = {s.delta_bic:+.2f}, "
                       f"RMS would be {s.fit.rms * U:.3f} µg")
        else:
            out.append(f"    {s.term:18s} skipped: {s.note}")
    return out
