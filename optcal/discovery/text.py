"""The plain-text report of model discovery (what ``optcal discover`` prints; docs/discovery.md shows
examples): the base fit, each step with its test and fitted parameters, the candidates of each round, the
final model against the noise floor and the verdict (docs/design.md §12).

The functions read a :class:`optcal.discovery.results.DiscoveryReport` by its attributes; they import
nothing of discovery, so the report can call them without a cycle.
"""

from __future__ import annotations

import numpy as np

U = 1e6  # g → µg


def summary(report) -> str:
    """The report as lines of text."""
    f = report.final
    lines = [f"base {report.base}: {len(f.problem.data)} positions, residual RMS {report.initial.rms * U:.3f} µg; "
             f"a term is added when p < α/k (α = {report.alpha:g}, k candidates tested) and "
             f"ΔBIC < {report.bic_threshold:g}"]
    for k, s in enumerate(report.steps, 1):
        c = s.chosen
        lines.append(f"step {k}: add {s.term}: RMS {s.before.rms * U:.3f} → {s.after.rms * U:.3f} µg, "
                     f"F({c.q},{c.dof}) = {c.f_statistic:.4g}, p = {c.p_value:.3g} (threshold "
                     f"{s.p_threshold:.3g}), ΔBIC = {c.delta_bic:.2f}, LR = {c.lr_statistic:.2f}")
        for n, v in s.parameters.items():
            se = s.stderr[n]
            lines.append(f"    {n:8s} {v: .6e} ± {se:.2e}" if np.isfinite(se) else f"    {n:8s} {v: .6e}")
        if s.alternatives:
            lines.append("    nearly as good (ΔBIC within 2: confounded on these data): " + ", ".join(s.alternatives))
        lines.append("    candidates this round:")
        lines += round_lines([x for x in s.scores if x is not c])
    lines.append("last round (nothing added):" if report.last_round else "no candidate left to test")
    lines += round_lines(report.last_round)
    floor = "unknown (no n, sx, sy, sz in the data)" if report.noise_g is None else (
        f"σ = {report.noise_g * U:.3f} µg (RMS over positions), expected RMS {report.expected_rms * U:.3f} µg")
    lines.append(f"final model {f.model.name}: residual RMS {f.rms * U:.3f} µg; noise floor {floor}")
    chi = report.chi2
    detail = "" if chi is None else f" (χ² = {chi[0]:.1f} on {chi[1]} dof, p = {chi[2]:.3g})"
    lines.append(f"verdict: {report.verdict}{detail}")
    lines += [f"note: {n}" for n in report.notes]
    return "\n".join(lines)


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
