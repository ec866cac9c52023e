"""The residual diagnostics' figure (docs/discovery.md shows it): one panel per diagnostic of
:mod:`optcal.discovery.diagnostics`, the final residuals against what it regresses on with the part its columns
explain, and the Lomb–Scargle periodograms; each panel's title gives the diagnostic's p-value at the floor.
matplotlib is imported inside the function, as in :mod:`optcal.plots`.
"""

from __future__ import annotations

import numpy as np

from ..plots import save_figure

U = 1e6  # g → µg
XLABEL = {"orientation": "azimuth of the direction (°)", "temperature": "temperature (°C)", "time trend": "time (s)",
          "periodicity": "time (s)", "order": "position (in order)", "duration": "samples averaged"}


def diagnostics_figure(report, path):
    """Draw the final fit's diagnostics of ``report`` (a :class:`optcal.discovery.results.DiscoveryReport`), save
    them to ``path`` and return the ``matplotlib.figure.Figure``."""
    from matplotlib.figure import Figure

    diag = report.diagnostics
    r = report.final.residuals[:report.final.problem.n_position_residuals] * U
    fig = Figure(figsize=(13.5, 7.4), layout="constrained")
    axes = fig.subplots(2, 4).ravel()
    A = report.final.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    panels = ["orientation", "temperature", "time trend", "periodicity", "order", "duration"]
    for ax, name in zip(axes, panels):
        d = diag.get(name)
        if name == "orientation" and d is not None:
            sc = ax.scatter(np.degrees(np.arctan2(u[:, 1], u[:, 0])), np.degrees(np.arcsin(np.clip(u[:, 2], -1, 1))),
                            c=r, cmap="coolwarm", vmin=-np.max(np.abs(r)), vmax=np.max(np.abs(r)), s=28)
            fig.colorbar(sc, ax=ax, label="residual (µg)")
            ax.set(xlabel=XLABEL[name], ylabel="elevation (°)")
        elif d is not None and d.x is not None:
            order = np.argsort(d.x, kind="stable")
            ax.plot(d.x, r, "o", ms=3.5, color="0.45", label="residual")
            if d.fitted is not None:
                ax.plot(np.asarray(d.x)[order], d.fitted[order] * U, "-", color="C3", lw=1.0,
                        label="part its columns explain")
            ax.axhline(0, color="k", lw=0.5)
            ax.set(xlabel=XLABEL[name], ylabel="residual (µg)")
            ax.legend(fontsize=7)
        ax.set_title(_title(d, name), fontsize=9)
    _periodogram_panel(axes[6], diag)
    _floor_panel(axes[7], report)
    save_figure(fig, path, dpi=100)
    return fig


def _title(d, name: str) -> str:
    if d is None:
        return name
    if not d.tested:
        return f"{name}: not tested ({d.note})"
    extra = f" at {d.extra['period_s']:.4g} s" if "period_s" in d.extra else ""
    flag = ", significant" if d.significant else ""
    label = "false alarm" if name == "periodicity" else "p"
    return f"{name}{extra}: {label} = {d.p_value:.2g}{flag}"


def _periodogram_panel(ax, diag) -> None:
    pg = diag.periodogram
    if pg is None:
        ax.set_visible(False)
        return
    period = 1.0 / pg["freqs_hz"]
    for name, p in zip(pg["series"], pg["powers"]):
        ax.plot(period, p, lw=0.9, label=name)
    d = diag.get("periodicity")
    if d is not None and "period_s" in d.extra:
        ax.axvline(d.extra["period_s"], color="k", ls="--", lw=0.7)
    ax.set_xscale("log")
    ax.set(xlabel="period (s)", ylabel="normalised power", title=f"Lomb–Scargle periodograms "
           f"({pg['n_independent']} independent frequencies)")
    ax.title.set_fontsize(9)
    ax.legend(fontsize=7)


def _floor_panel(ax, report) -> None:
    """Residuals of the list's model and the final one per position, with the floor's band."""
    n = report.final.problem.n_position_residuals
    pos = np.arange(n)
    if report.listed is not None and report.listed is not report.final:
        ax.plot(pos, report.listed.residuals[:n] * U, "o-", ms=3, lw=0.5, color="0.6", label=report.listed.model.name)
    ax.plot(pos, report.final.residuals[:n] * U, "o-", ms=3, lw=0.7, color="C3", label=report.final.model.name)
    floor = None if report.floor is None else report.floor.rms_g
    if floor:
        ax.axhspan(-floor * U, floor * U, color="C0", alpha=0.12, label=f"±1σ floor ({report.floor.kind})")
    ax.set(xlabel="position", ylabel="residual (µg)")
    ax.set_title(f"residuals ({report.verdict})", fontsize=9)
    ax.legend(fontsize=6)
