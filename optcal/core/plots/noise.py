"""The figure of a noise analysis (docs/noise.md): the overlapping Allan deviation of each axis on log-log
axes with its intervals, the fitted curve σ² = N²/τ + (0.664·B)² + K²·τ/3 and its three lines (the method:
:mod:`optcal.core.noise`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def noise_figure(report) -> Figure:
    """σ(τ) in µg per axis of ``report`` (a :class:`optcal.core.noise.NoiseReport`; this module imports nothing of
    optcal.core.noise, which calls it) with its intervals, the fitted curve over the fitted points and its three
    lines (−1/2 with N marked at τ = 1 s, the floor 0.664·B, +1/2 with K marked at τ = 3 s; ▼ and △ mark
    upper bounds), against τ in s."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.5, 5.4), layout="constrained")
    ax = fig.add_subplot()
    colours = ("tab:blue", "tab:orange", "tab:green")
    shown = []
    for a, c in zip(report.axes, colours):
        y = a.adev_g * 1e6
        err = np.vstack([y - a.adev_low_g * 1e6, a.adev_high_g * 1e6 - y])
        ax.errorbar(a.tau_s, y, yerr=err, fmt="o", ms=3.5, color=c, capsize=2, label=f"σ_{a.axis}(τ)")
        shown += [*(a.adev_low_g * 1e6), *(a.adev_high_g * 1e6)]
        tt = np.geomspace(min(a.tau_s[0], a.white_tau_s), max(a.tau_s[-1], a.rw_tau_s), 60)
        if a.fit is not None:
            tf = np.geomspace(a.tau_s[a.fit.region][0], a.tau_s[a.fit.region][-1], 60)
            ax.plot(tf, np.sqrt(a.fit.variance(tf)) * 1e6, "-", color=c, lw=1.2, alpha=0.8)
        if a.white.value is not None:
            ax.plot(tt, a.term_adev_g("white", tt) * 1e6, "--", color=c, lw=0.8,
                    label=f"{a.axis}: N = {a.white.value * 1e6:.3g} µg/√Hz")
            ax.plot([a.white_tau_s], [a.white.value * 1e6], "s", color=c, mfc="none", ms=7)
            shown.append(a.white.value * 1e6)
        b = a.bias_instability
        if b.kind == "estimate":
            ax.axhline(float(a.term_adev_g("floor", 1.0)) * 1e6, color=c, ls=":", lw=0.9,
                       label=f"{a.axis}: B = {b.value * 1e6:.3g} µg (floor / 0.664)")
        else:
            ax.plot(b.tau_s, [float(a.term_adev_g("floor", 1.0)) * 1e6], "v", color=c, ms=6,
                    label=f"{a.axis}: B ≤ {b.value * 1e6:.3g} µg")
        k = a.random_walk
        if k.kind == "estimate":
            ax.plot(tt, a.term_adev_g("random_walk", tt) * 1e6, "-.", color=c, lw=0.8,
                    label=f"{a.axis}: K = {k.value * 1e6:.3g} µg/√s")
            ax.plot([a.rw_tau_s], [k.value * 1e6], "D", color=c, mfc="none", ms=6)
            shown.append(k.value * 1e6)
        else:
            ax.plot(k.tau_s, [float(a.term_adev_g("random_walk", k.tau_s[0])) * 1e6], "^", color=c, mfc="none", ms=6,
                    label=f"{a.axis}: K ≤ {k.value * 1e6:.3g} µg/√s")
    ax.set_xscale("log")
    ax.set_yscale("log")
    pos = [v for v in shown if v > 0 and np.isfinite(v)]
    ax.set_ylim(min(pos) / 1.6, max(pos) * 1.6)
    ax.grid(True, which="both", lw=0.3, alpha=0.6)
    ax.set_xlabel("averaging time τ [s]")
    ax.set_ylabel("overlapping Allan deviation [µg]")
    src = report.source
    name = Path(src).name if src and Path(src).is_file() else (src or "recording")
    ax.set_title(f"{name}: {report.duration_s:.4g} s at {report.rate_hz:.4g} Hz ({100 * report.ci:.3g}% intervals)",
                 fontsize=9)
    ax.text(0.01, 0.01, "fit: σ² = N²/τ + (0.664·B)² + K²·τ/3", transform=ax.transAxes, fontsize=7,
            color="0.3")
    ax.legend(fontsize=7, ncol=2, loc="best")
    return fig
