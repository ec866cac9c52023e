"""The figure of model discovery (docs/discovery.md shows two): the residuals per position of the base and
the final model against the noise band, then one panel per added term, an added-variable plot (the
residuals against the term's fitted combination, :meth:`optcal.core.discovery.results.Step.added_variable`,
before and after the term is added; docs/design.md, "Model discovery").
"""

from __future__ import annotations

import numpy as np

from optcal.core.plots import save_figure

U = 1e6  # g → µg


def figure(report, path):
    """Draw ``report`` (a :class:`optcal.core.discovery.results.DiscoveryReport`), save it to ``path`` (the format
    from its suffix; a path that cannot be written is one line) and return the ``matplotlib.figure.Figure``."""
    from matplotlib.figure import Figure

    n = 1 + len(report.steps)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig = Figure(figsize=(4.6 * cols, 3.6 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    _residuals_panel(axes[0], report)
    for k, (s, ax) in enumerate(zip(report.steps, axes[1:]), 1):
        _step_panel(ax, k, s)
    for ax in axes[n:]:
        ax.set_visible(False)
    save_figure(fig, path, dpi=110)
    return fig


def _residuals_panel(ax, report) -> None:
    pos = np.arange(len(report.initial.residuals))
    ax.plot(pos, report.initial.residuals * U, "o-", ms=3, lw=0.6, color="0.55", label=f"{report.base}")
    ax.plot(pos, report.final.residuals * U, "o-", ms=3, lw=0.8, color="C3", label=report.final.model.name)
    if report.noise_g is not None:
        ax.axhspan(-report.noise_g * U, report.noise_g * U, color="C0", alpha=0.12, label="±1σ noise")
    ax.set(xlabel="position", ylabel="residual ‖A‖ − g (µg)", title=f"residuals per position ({report.verdict})")
    ax.legend(fontsize=7)


def _step_panel(ax, k: int, s) -> None:
    xr = s.added_variable() * U
    ax.plot(xr, s.before.residuals * U, "o", ms=4, color="0.55", label=f"before (RMS {s.before.rms * U:.2f} µg)")
    ax.plot(xr, s.after.residuals * U, "o", ms=4, color="C3", label=f"after (RMS {s.after.rms * U:.2f} µg)")
    lim = np.array([xr.min(), xr.max()])
    ax.plot(lim, lim, "--", color="0.3", lw=0.7, label="slope 1")
    ax.axhline(0, color="k", lw=0.5)
    ax.set(xlabel=f"fitted {s.term} term, base part removed (µg)", ylabel="residual (µg)",
           title=f"step {k}: add {s.term} (p = {s.chosen.p_value:.2g})")
    ax.legend(fontsize=7)
