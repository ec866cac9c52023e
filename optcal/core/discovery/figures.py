"""The residual diagnostics' figure (docs/discovery.md shows two): one panel per diagnostic of
:mod:`optcal.core.discovery.diagnostics`, the residuals after the list's search (grey) and of the final model (red)
against what the diagnostic regresses on, with the part of the first its columns explain (the structure the
dictionary was searched for); the Lomb–Scargle periodograms; the residuals per position against the floor. Each
panel's title gives the diagnostic's p-value at the floor after the list and for the final model. matplotlib is
imported inside the function, as in :mod:`optcal.core.plots`.
"""

from __future__ import annotations

import numpy as np

from optcal.core.plots import save_figure

U = 1e6  # g → µg
PANELS = ("orientation", "temperature", "time trend", "periodicity", "order", "duration")
XLABEL = {"orientation": "azimuth of the direction (°)", "temperature": "temperature (°C)", "time trend": "time (s)",
          "periodicity": "time (s)", "order": "position (in order)", "duration": "samples averaged"}


def diagnostics_figure(report, path):
    """Draw ``report``'s diagnostics (a :class:`optcal.core.discovery.results.DiscoveryReport`), save them to ``path``
    and return the ``matplotlib.figure.Figure``."""
    from matplotlib.figure import Figure

    before, after = report.diagnostics_listed, report.diagnostics
    listed = report.listed if report.listed is not None else report.final
    n = report.final.problem.n_position_residuals
    r0, r1 = listed.residuals[:n] * U, report.final.residuals[:n] * U
    fig = Figure(figsize=(15.0, 7.6), layout="constrained")
    axes = fig.subplots(2, 4).ravel()
    for ax, name in zip(axes, PANELS):
        d0, d1 = before.get(name), after.get(name)
        ax.set_title(_title(name, d0, d1, report.final is not listed), fontsize=9)
        if d0 is None or d0.x is None:
            ax.set_axis_off()
            ax.text(0.5, 0.5, f"{name}: {d0.note if d0 is not None else 'not run'}", ha="center", va="center",
                    transform=ax.transAxes, fontsize=9, color="0.3")
            continue
        if name == "orientation":
            _orientation_panel(fig, ax, listed, r0)
            continue
        x = np.asarray(d0.x, float)
        if report.final is not listed:
            ax.plot(x, r0, "o", ms=3.5, color="0.6", label=f"after the list ({listed.model.name})")
        ax.plot(x, r1, "o", ms=3.5, color="C3", label="final model")
        if d0.fitted is not None:
            ax.plot(x, d0.fitted * U, "x", ms=5, color="k", mew=0.8, label="part its columns explain, after the list")
        ax.axhline(0, color="k", lw=0.5)
        ax.set(xlabel=XLABEL[name], ylabel="residual (µg)")
        ax.legend(fontsize=6.5)
    _periodogram_panel(axes[6], before)
    _floor_panel(axes[7], report, listed, r0, r1)
    save_figure(fig, path, dpi=100)
    return fig


def _title(name: str, d0, d1, two: bool) -> str:
    def p(d):
        if d is None or not d.tested:
            return "not tested"
        return f"{d.p_value:.2g}{' (sig.)' if d.significant else ''}"

    label = "false alarm" if name == "periodicity" else "p"
    period = f" {d0.extra['period_s']:.3g} s" if d0 is not None and "period_s" in d0.extra else ""
    if d0 is None or not d0.tested:
        return f"{name}: not tested"
    return f"{name}{period}: {label} = {p(d0)}" + (f" → {p(d1)}" if two else "")


def _orientation_panel(fig, ax, fit, r) -> None:
    """The residuals after the list on a map of the measured direction (azimuth, elevation)."""
    A = fit.specific_force
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    lim = float(np.max(np.abs(r))) or 1.0
    sc = ax.scatter(np.degrees(np.arctan2(u[:, 1], u[:, 0])), np.degrees(np.arcsin(np.clip(u[:, 2], -1, 1))), c=r,
                    cmap="coolwarm", vmin=-lim, vmax=lim, s=30)
    fig.colorbar(sc, ax=ax, label="residual after the list (µg)")
    ax.set(xlabel=XLABEL["orientation"], ylabel="elevation (°)")


def _periodogram_panel(ax, diag) -> None:
    pg = diag.periodogram
    if pg is None:
        ax.set_axis_off()
        ax.text(0.5, 0.5, "no periodogram (no time column)", ha="center", va="center", transform=ax.transAxes,
                fontsize=9, color="0.3")
        return
    period = 1.0 / pg["freqs_hz"]
    for name, p in zip(pg["series"], pg["powers"]):
        ax.plot(period, p, lw=0.9, label=name)
    d = diag.get("periodicity")
    if d is not None and "period_s" in d.extra:
        ax.axvline(d.extra["period_s"], color="k", ls="--", lw=0.7, label=f"peak {d.extra['period_s']:.4g} s")
    from matplotlib.ticker import NullFormatter

    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())  # the minor ticks' labels of a short decade overlap
    ax.set(xlabel="period (s)", ylabel="normalised power")
    ax.set_title(f"Lomb–Scargle after the list ({pg['n_independent']} indep. frequencies)", fontsize=9)
    ax.legend(fontsize=6.5)


def _floor_panel(ax, report, listed, r0, r1) -> None:
    """Residuals of the list's model and the final one per position, with the floor's band."""
    pos = np.arange(len(r1))
    if report.final is not listed:
        ax.plot(pos, r0, "o-", ms=3, lw=0.5, color="0.6", label=listed.model.name)
    ax.plot(pos, r1, "o-", ms=3, lw=0.7, color="C3", label=report.final.model.name)
    floor = None if report.floor is None else report.floor.rms_g
    if floor:
        ax.axhspan(-floor * U, floor * U, color="C0", alpha=0.12, label=f"±1σ floor ({report.floor.kind})")
    ax.set(xlabel="position", ylabel="residual (µg)")
    ax.set_title(f"per position: {report.verdict}", fontsize=9)
    ax.legend(fontsize=6)
