"""The figure of a raw recording (docs/design.md, "Raw recordings"): the outputs with the static intervals shaded, the
variance statistic of Tedaldi et al. (2014, §IV-A) with its threshold, and each position's residual."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from optcal.core.recording.detection import DetectionResult
    from optcal.core.recording.reading import Recording

MAX_POINTS = 20000  # longer recordings are drawn as min/max per block, which keeps every spike visible


def recording_figure(recording: Recording, detection: DetectionResult, residuals_g) -> Figure:
    """Three panels against time (s): the outputs (sensor units) with the intervals shaded and saturated
    samples marked, the variance statistic ς with the threshold k·ς_init (when the intervals were detected),
    and the residual of each interval's position (µg) as a bar over the interval."""
    from matplotlib.figure import Figure

    rec, det = recording, detection
    res = np.asarray(residuals_g, float).ravel()
    panels = 3 if det.statistic is not None else 2
    fig = Figure(figsize=(11, 2.6 * panels), layout="constrained")
    axes = fig.subplots(panels, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.5, 1.5][:panels]})
    ax = axes[0]
    step = max(1, len(rec) // MAX_POINTS)
    for j, c in enumerate("xyz"):
        if step == 1:
            ax.plot(rec.shown_t, rec.N[:, j], lw=0.6, label=f"a{c}")
        else:
            m = len(rec) // step * step
            blocks = rec.N[:m, j].reshape(-1, step)
            # the block means as a line (a fill of blocks a few samples wide is too thin to see), and
            # their min/max around it, which keeps every spike visible
            (line,) = ax.plot(rec.shown_t[:m:step], blocks.mean(1), lw=0.6, label=f"a{c}")
            ax.fill_between(rec.shown_t[:m:step], blocks.min(1), blocks.max(1), lw=0, alpha=0.5, color=line.get_color())
    for s, e in det.intervals:
        for a in axes:
            a.axvspan(rec.shown_t[s], rec.shown_t[e - 1], color="tab:green", alpha=0.15, lw=0)
    if rec.saturated.any():
        ts = rec.shown_t[rec.saturated]
        ax.plot(ts, np.full(len(ts), np.max(rec.N)), "|", color="red", label="saturated")
    ax.set_ylabel(f"output [{rec.units}]")
    ax.set_title(f"{Path(rec.path).name if rec.path else 'recording'}: {det.n_intervals} static intervals")
    ax.legend(loc="upper right", fontsize=8, ncol=4)
    if det.statistic is not None:
        squared = f"({rec.units})²" if "/" in rec.units else f"{rec.units}²"
        a = axes[1]
        a.semilogy(rec.shown_t[::step], det.statistic[::step], lw=0.6, color="k")
        a.axhline(det.threshold, color="tab:red", lw=0.8, label=f"threshold {det.k:g}·ς_init")
        a.set_ylabel(f"ς (variance norm) [{squared}]")
        a.legend(loc="upper right", fontsize=8)
    a = axes[-1]
    mid = np.array([rec.shown_t[s:e].mean() for s, e in det.intervals])
    width = np.array([rec.t[e - 1] - rec.t[s] for s, e in det.intervals])
    if len(res) == len(mid):
        a.bar(mid, res * 1e6, width=np.maximum(width, rec.duration / 200), color="tab:blue")
    a.axhline(0, color="k", lw=0.5)
    if len(res) and np.max(np.abs(res)) < 1e-9:  # an exact fit (as many positions as parameters): rounding
        a.set_ylim(-1.0, 1.0)
    a.set_ylabel("residual [µg]")
    a.set_xlabel("time [s]" if rec.origin == 0 else "time from the first sample [s]")
    return fig
