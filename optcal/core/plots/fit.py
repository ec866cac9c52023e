"""The figure of a fit's per-position residuals (docs/design.md, "Per-position residuals, outliers, the robust loss,
what the data determine and weak fits"): each position's residual (µg) with its
noise band (±σ_i, the floor of each mean with the sensor's correlated noise when the data carry it,
docs/noise.md; and the outlier threshold ±t·σ_i·√(1−h_i)), the white-noise floor σ/√n beside it when the two
differ, the outliers marked and named, and for an outlier its prediction error from the other positions. For
positions from a raw recording the tick labels also give each interval's time (s)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MAX_TICKS = 40  # more positions than this get every k-th tick label


def _tick_labels(cal, diag) -> list[str]:
    det = cal.problem.data.extra.get("detection") if isinstance(cal.problem.data.extra, dict) else None
    labels = []
    for i in range(len(diag.index)):
        text = str(int(diag.position[i]))
        if diag.labels[i] not in (None, ""):
            text += f"\n{diag.labels[i]}"
        if det is not None and len(det.intervals) == len(diag.index):
            s, e = det.intervals[i]
            text += f"\n{det.recording.shown_t[s:e].mean():.1f} s"
        labels.append(text)
    return labels


def _white_band(cal) -> np.ndarray | None:
    """σ/√n of each position residual (µg), as the figure's σ band is built (the RMS of the three axes with a
    reference); None without n and sx, sy, sz."""
    from optcal.core.analysis import white_sigma

    w = white_sigma(cal.problem, cal.x)
    if w is None:
        return None
    n = len(cal.problem.data)
    return (w if w.size == n else np.sqrt(np.mean(w.reshape(n, 3) ** 2, axis=1))) * 1e6


def fit_figure(cal, path=None) -> Figure:
    """Residual per position of the calibration ``cal`` (an :class:`optcal.core.calibration.Calibration`)
    against its noise; written to ``path`` (its suffix names the format, :func:`optcal.core.plots.save_figure`)
    when given."""
    from matplotlib.figure import Figure

    diag = cal.diagnostics
    idx = np.asarray(diag.index)
    r = diag.residual_g * 1e6
    sig = diag.noise_g * 1e6
    band = diag.threshold * sig * np.sqrt(np.clip(1.0 - diag.leverage, 0.0, 1.0))
    fig = Figure(figsize=(max(7.0, 0.32 * len(idx) + 3.0), 4.2), layout="constrained")
    ax = fig.subplots()
    est = cal.fit.estimator if cal.fit.noise_source == "measured" and diag.sigma_source == "measured" else None
    what = {"allan": "Allan model", "white": "σ/√n", "stated": "se_x, se_y, se_z"}.get(est)
    ax.fill_between(idx, -sig, sig, step="mid", color="tab:green", alpha=0.25, lw=0,
                    label=f"±σ ({diag.sigma_source} noise{': ' + what if what else ''})")
    white = _white_band(cal) if est in ("allan", "stated") else None
    if white is not None:
        ax.step(idx, white, where="mid", color="tab:green", lw=0.8, ls=":", label="±σ/√n (white noise alone)")
        ax.step(idx, -white, where="mid", color="tab:green", lw=0.8, ls=":")
    ax.step(idx, band, where="mid", color="tab:red", lw=0.8, ls="--",
            label=f"outlier threshold ±{diag.threshold:.2f} σ·√(1−h)")
    ax.step(idx, -band, where="mid", color="tab:red", lw=0.8, ls="--")
    ok = ~diag.outlier
    ax.vlines(idx, 0, r, color="0.5", lw=0.8)
    ax.plot(idx[ok], r[ok], "o", color="tab:blue", ms=4, label="residual")
    if diag.outlier.any():
        out = np.flatnonzero(diag.outlier)
        ax.plot(idx[out], r[out], "o", color="tab:red", ms=6, label="outlier: residual")
        off = diag.off[out] * 1e6
        ax.plot(idx[out], off, "x", color="tab:red", ms=7, label="outlier: off the other positions' fit")
        for i, o in zip(out, off):
            ax.annotate(f"{diag.name(i)}\n{o:.4g} µg, {diag.statistic[i]:.3g} σ", (idx[i], o), fontsize=8,
                        xytext=(4, 4), textcoords="offset points", color="tab:red")
    ax.axhline(0, color="k", lw=0.5)
    step = max(1, int(np.ceil(len(idx) / MAX_TICKS)))
    ax.set_xticks(idx[::step], _tick_labels(cal, diag)[::step], fontsize=7)
    ax.set_xlabel("position")
    ax.set_ylabel("residual ‖A‖ − g [µg]" if not cal.problem.reference else "residual, 3-axis misfit [µg]")
    loss = "" if cal.loss == "linear" else f", loss {cal.loss}"
    chi = ("" if cal.fit.chi2 is None else
           f", χ²/dof {cal.fit.chi2 / cal.fit.dof:.3g} (p = {cal.fit.p_value:.2g})")
    ax.set_title(f"{cal.model.name}, {cal.solver}{loss}: {len(idx)} positions, RMS {cal.fit.rms_g * 1e6:.3g} µg{chi}, "
                 f"{int(diag.outlier.sum())} outlier(s)", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    if path is not None:
        from optcal.core.plots import save_figure

        save_figure(fig, path)
    return fig
