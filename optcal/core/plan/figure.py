"""The figure of a plan (docs/planning.md, "For a person: fixtures, faces and tilts, order, files, figure"): the
directions on the sphere, as two equal-area (Lambert azimuthal) discs, the upper hemisphere (A_z ≥ 0, seen from +z) and
the lower (seen from −z), each position numbered in handling order and the path between consecutive positions drawn; a
reference scheme, when given, as grey crosses."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _lambert(d: np.ndarray, upper: bool) -> np.ndarray:
    z = d[:, 2] if upper else -d[:, 2]
    k = np.sqrt(2.0 / np.clip(1.0 + z, 1e-12, None)) / np.sqrt(2.0)  # the rim (z = 0) at radius 1
    x = d[:, 0] * k
    y = d[:, 1] * k if upper else -d[:, 1] * k  # seen from below: mirror so the disc is viewed from outside
    return np.stack([x, y], axis=1)


def plan_figure(directions: np.ndarray, title: str = "", reference: np.ndarray | None = None,
                reference_label: str = "") -> Figure:
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    d = np.asarray(directions, float)
    fig = Figure(figsize=(9.0, 4.8), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, upper in zip(axes, (True, False)):
        ax.add_patch(Circle((0, 0), 1.0, fill=False, lw=0.8))
        for r in (np.sqrt(1 - np.cos(np.deg2rad(a))) for a in (30, 60)):  # 30° and 60° from the pole
            ax.add_patch(Circle((0, 0), r, fill=False, lw=0.4, ls=":", color="0.5"))
        if reference is not None:
            ref = np.asarray(reference, float)
            m = ref[:, 2] >= 0 if upper else ref[:, 2] < 0
            p = _lambert(ref[m], upper)
            ax.plot(p[:, 0], p[:, 1], "x", color="0.6", ms=6, label=reference_label or None)
        m = d[:, 2] >= 0 if upper else d[:, 2] < 0
        idx = np.flatnonzero(m)
        p = _lambert(d[m], upper)
        # the handling path, segment by segment where both ends are in this hemisphere
        q = _lambert(d, upper)
        for i in range(len(d) - 1):
            if m[i] and m[i + 1]:
                ax.plot(q[i:i + 2, 0], q[i:i + 2, 1], "-", color="tab:blue", lw=0.7, alpha=0.5)
        ax.plot(p[:, 0], p[:, 1], "o", color="tab:blue", ms=7)
        labels: dict = {}  # a pose planned twice (or more) gets one label naming each of its positions
        for i, (x, y) in zip(idx, p):
            labels.setdefault((round(x, 2), round(y, 2)), []).append(str(i + 1))
        for (x, y), names in labels.items():
            ax.annotate(",".join(names), (x, y), xytext=(4, 4), textcoords="offset points", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlim(-1.12, 1.12)
        ax.set_ylim(-1.12, 1.12)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title("A_z ≥ 0 (z up), seen from +z: x right, y up" if upper else
                     "A_z < 0 (z down), seen from −z: x right, y down")
        if reference is not None and upper:
            ax.legend(loc="lower left", fontsize=8)
    if title:
        fig.suptitle(title)
    return fig
