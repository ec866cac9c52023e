"""The report's figures (matplotlib, Agg backend), after the 2020 paper's: final cost per run (Figures 5
and 6), convergence curves (Figure 4), verification error per position (Figure 9), static navigation
error (Figure 11); plus error against the Cramér-Rao bound and accuracy against runtime.

Drawing them is most of a large study's report time (matplotlib lays out and draws every tick of the
cost figure's forty panels, about 5 s of CPU each), and each figure is independent of the others: a
:class:`Renderer` draws them in worker processes, one per CPU, while the report's process computes its
tables and statistics. The drawing is deterministic, so the files are the same whichever process draws
them.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from optcal.studies.metrics import Group

MAX_LINES = 10  # solvers drawn on per-solver line charts (the most accurate ones)
# Worker processes pay off from about this many groups (solver × model × scheme) on: a worker takes about a
# second of CPU to start (Python, NumPy, matplotlib), a figure about 25-150 ms per group it draws.
PARALLEL_MIN_GROUPS = 40
MAX_WORKERS = 8  # beyond this the largest figure (the cost per run, one of 30) bounds the time anyway


def usable_cpus() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def figure_workers(n_groups: int) -> int:
    """Worker processes for a report of ``n_groups`` groups: one per CPU (up to :data:`MAX_WORKERS`), none
    (every figure drawn in the report's process) for a small study or on one CPU."""
    cpus = usable_cpus()
    return min(cpus, MAX_WORKERS) if n_groups >= PARALLEL_MIN_GROUPS and cpus > 1 else 0


def _start() -> None:
    _plt()


def _draw(fn: Callable, path: Path, args: tuple, kwargs: dict) -> Path:
    return fn(*args, path=path, **kwargs)


class Renderer:
    """Draws figures: in ``workers`` worker processes (spawned: a clean interpreter, whatever threads the
    calling process holds), or at once in this process when ``workers`` is 0. :meth:`finish` waits for
    every figure and raises a figure's error; a figure whose worker died (the pool broke) is drawn here.
    ``prepare`` maps each argument of a figure to what the figure gets, in either case (the report cuts its
    groups' rows to the columns the figures draw, so that a worker unpickles less). ``start``: start the
    workers at once, each importing matplotlib, instead of at the first figure. Used as a context manager,
    which stops the workers however the report ends."""

    def __init__(self, workers: int = 0, prepare: Callable | None = None, start: bool = False):
        self.prepare = prepare or (lambda a: a)
        self.pool = None
        if workers > 0:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            self.pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"))
            if start:  # start every worker now (a pool starts one per task submitted, up to its size)
                for _ in range(workers):
                    self.pool.submit(_start)
        self.jobs: list[tuple] = []

    def draw(self, fn: Callable, path: Path, *args, **kwargs) -> Path:
        """``fn(*args, path=path, **kwargs)``, now or in a worker; returns ``path``."""
        from concurrent.futures.process import BrokenProcessPool

        args, kwargs = tuple(map(self.prepare, args)), {k: self.prepare(v) for k, v in kwargs.items()}
        if self.pool is None:
            return _draw(fn, path, args, kwargs)
        job = (fn, path, args, kwargs)
        try:
            self.jobs.append((self.pool.submit(_draw, *job), job))
        except BrokenProcessPool:  # a worker died: this figure and the next ones are drawn here
            self.finish()
            _draw(*job)
        return path

    def finish(self) -> None:
        from concurrent.futures.process import BrokenProcessPool

        for future, job in self.jobs:
            try:
                future.result()
            except BrokenProcessPool:  # its worker died (killed, out of memory): draw it here
                _draw(*job)
        self.jobs = []
        self.close()

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
            self.pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _style(i: int) -> dict:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return {"color": cmap(i % 10), "linestyle": ("-", "--", ":", "-.")[(i // 10) % 4]}


def best(groups: list[Group], n: int = MAX_LINES) -> list[Group]:
    """The n most accurate groups (reference calibrations always kept), in their original order."""
    ranked = sorted(groups, key=lambda g: (np.nan_to_num(g.accuracy, nan=np.inf)))
    keep = {id(g) for g in ranked[:n]} | {id(g) for g in groups if g.reference}
    return [g for g in groups if id(g) in keep]


def _save(fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` whole or not at all (:func:`optcal.core.plots.save_figure`) and close it."""
    from optcal.core.plots import save_figure

    try:
        save_figure(fig, path, dpi=110, bbox_inches="tight")
    finally:
        _plt().close(fig)
    return path


def cost_per_run(groups: list[Group], title: str, path: Path) -> Path:
    """Final cost of every run, one panel per solver (2020 paper, Figures 5 and 6)."""
    plt = _plt()
    n = len(groups)
    ncol = min(4, n)
    nrow = int(np.ceil(n / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 2.4 * nrow), sharey=True, squeeze=False)
    for ax, g in zip(axes.flat, groups):
        runs = [r["run"] for r in g.ok]
        ax.semilogy(runs, g.column("fun"), "o-", ms=3, lw=0.8)
        ax.set_title(g.solver, fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("run", fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("final cost Σe²", fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def convergence(groups: list[Group], title: str, path: Path) -> Path:
    """Median best cost against evaluations, with the 10-90 % band over runs (2020 paper, Figure 4)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 5))
    for i, g in enumerate(best(groups)):
        x, med, lo, hi = g.convergence()
        if not len(x):
            continue
        st = _style(i)
        ax.loglog(x, med, label=g.solver, **st)
        ax.fill_between(x, lo, hi, color=st["color"], alpha=0.12, lw=0)
    ax.set_xlabel("cost evaluations")
    ax.set_ylabel("best cost Σe² (median, 10-90 % band)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def error_vs_crlb(groups: list[Group], title: str, path: Path) -> Path:
    """RMSE of each parameter (observable part) over runs against its Cramér-Rao bound."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 4.8))
    shown = best(groups)
    names = groups[0].names
    x = np.arange(len(names))
    w = 0.8 / max(len(shown), 1)
    crlb = None
    for i, g in enumerate(shown):
        ps = g.parameters()
        crlb = [p["crlb"] for p in ps]
        ax.bar(x - 0.4 + (i + 0.5) * w, [p.get("rmse_observable", np.nan) for p in ps], w,
               color=_style(i)["color"], label=g.solver)
    if crlb is not None:
        ax.plot(x, crlb, "k_", ms=22, mew=2, label="Cramér-Rao bound")
    ax.set_yscale("log")
    ax.set_xticks(x)
    ax.set_xticklabels(names, rotation=45, fontsize=8)
    ax.set_ylabel("RMSE over runs (natural units)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=3)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def verification(groups: list[Group], title: str, path: Path) -> Path:
    """|‖A‖ − g| per verification position, median over runs (2020 paper, Figure 9)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(9, 4.5))
    truth = None
    for i, g in enumerate(best(groups)):
        ok = g.ok
        if not ok:
            continue
        V = np.array([r["ver_err"] for r in ok])
        truth = np.array([r["ver_truth"] for r in ok])
        ax.plot(np.arange(1, V.shape[1] + 1), np.median(V, 0), marker="o", ms=3, label=g.solver, **_style(i))
    if truth is not None:
        ax.plot(np.arange(1, truth.shape[1] + 1), np.median(truth, 0), "k-", lw=2, alpha=0.5,
                label="truth calibration (noise floor)")
    ax.set_xlabel("verification position")
    ax.set_ylabel("|‖A‖ − g| (µg), median over runs")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def accuracy_runtime(cells: dict, title: str, path: Path, names: dict | None = None) -> Path:
    """Accuracy (RMSE/CRLB) against median runtime for every solver, one panel per model × scheme
    (``names``: each cell's name in its panel's title, "nonlinear12, 24 positions" by default).

    Each point (or cluster of points within 4 % in runtime and 1 % in accuracy: the least-squares methods all
    reach the same optimum) carries a number, and the key beside the panel names the solvers of each number:
    41 names written beside their points overlapped wherever solvers crowd."""
    plt = _plt()
    n = len(cells)
    ncol = min(2, n)
    nrow = int(np.ceil(n / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(10.5 * ncol, 6.5 * nrow), squeeze=False)
    numbered = []
    for ax, ((model, scheme), gs) in zip(axes.flat, cells.items()):
        pts = []
        for g in gs:
            s = g.summary()
            if not np.isfinite(s["accuracy"]) or not np.isfinite(s["runtime_median_s"]):
                continue
            staged = g.solver.startswith("staged:")
            ax.scatter(s["runtime_median_s"], s["accuracy"], marker="s" if staged else "o",
                       c="tab:orange" if staged else ("tab:green" if g.reference else "tab:blue"), s=22, zorder=3)
            pts.append((s["runtime_median_s"], s["accuracy"], g.solver))
        pts.sort()
        clusters: list[list] = []
        for x, y, name in pts:
            for c in clusters:
                if abs(np.log(x / c[0])) < 0.04 and abs(np.log(y / c[1])) < 0.01:
                    c[2].append(name)
                    break
            else:
                clusters.append([x, y, [name]])
        clusters.sort(key=lambda c: c[1])  # numbered from the most accurate
        key = "\n".join(f"{k:>2}  {', '.join(names)}" for k, (_, _, names) in enumerate(clusters, 1))
        ax.text(1.02, 1.0, key, transform=ax.transAxes, fontsize=6, va="top", ha="left", family="monospace")
        ax.set_xscale("log")
        ax.set_yscale("log")
        lo, hi = ax.get_ylim()
        ax.set_ylim(min(lo, 0.5), max(hi * 1.3, 2.0))
        numbered.append((ax, [(x, y, str(k)) for k, (x, y, _) in enumerate(clusters, 1)]))
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_xlabel("median runtime per calibration (s)")
        ax.set_ylabel("RMSE / CRLB (RMS over parameters)")
        name = (names or {}).get((model, scheme), f"{model}, {scheme} positions")
        ax.set_title(f"{name} (circles: joint, squares: staged)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.subplots_adjust(wspace=0.55)
    for ax, labels in numbered:  # placed in the final layout, where the pixel distances are the saved ones
        _place_numbers(ax, labels)
    return _save(fig, path)


def _place_numbers(ax, labels: list[tuple[float, float, str]]) -> None:
    """Write each number beside its point at the first of eight offsets where it overlaps neither an earlier
    number nor another point (in display pixels, the axes' scales and limits already set), else at the
    offset of least overlap."""
    fig = ax.figure
    scale = fig.dpi / 72.0
    w_char, h = 4.2 * scale, 7.0 * scale  # the digits' box at font size 6.5, in pixels
    offsets = [(3, 2), (3, -9), (-4, 5), (-4, -11), (6, -3), (-9, -3), (0, 7), (0, -13)]
    pts = ax.transData.transform([(x, y) for x, y, _ in labels]) if labels else np.zeros((0, 2))
    boxes: list[tuple[float, float, float, float]] = []

    def overlap(b) -> float:
        area = 0.0
        for c in boxes:
            area += max(0.0, min(b[2], c[2]) - max(b[0], c[0])) * max(0.0, min(b[3], c[3]) - max(b[1], c[1]))
        for px, py in pts:
            area += max(0.0, min(b[2], px + 3 * scale) - max(b[0], px - 3 * scale)) * \
                max(0.0, min(b[3], py + 3 * scale) - max(b[1], py - 3 * scale))
        return area

    for (x, y, text), (px, py) in zip(labels, pts):
        w = w_char * len(text)
        best = None
        for dx, dy in offsets:
            b = (px + dx * scale, py + dy * scale, px + dx * scale + w, py + dy * scale + h)
            o = overlap(b)
            if best is None or o < best[0]:
                best = (o, dx, dy, b)
            if o == 0:
                break
        _, dx, dy, b = best
        boxes.append(b)
        ax.annotate(text, (x, y), fontsize=6.5, xytext=(dx, dy), textcoords="offset points", zorder=4)


def ranking(groups: list[Group], title: str, path: Path) -> Path:
    """Every solver's RMSE/CRLB as a bar (most accurate at the top), with success rate and median runtime."""
    plt = _plt()
    rows = sorted((g for g in groups if np.isfinite(g.accuracy)), key=lambda g: -g.accuracy)
    fig, ax = plt.subplots(figsize=(8, 0.22 * len(rows) + 1.2))
    y = np.arange(len(rows))
    acc = [g.accuracy for g in rows]
    colours = ["tab:green" if g.reference else ("tab:orange" if g.solver.startswith("staged:") else "tab:blue")
               for g in rows]
    ax.barh(y, acc, color=colours, height=0.7)
    for i, g in enumerate(rows):
        s = g.summary()
        ax.text(acc[i] * 1.03, i, f"{100 * s['success_rate']:.0f} %, {s['runtime_median_s']:.3g} s", va="center",
                fontsize=6.5)
    ax.set_yticks(y)
    ax.set_yticklabels([g.solver for g in rows], fontsize=7)
    ax.set_xscale("log")
    ax.set_xlim(min(0.5, min(acc) * 0.8), max(acc) * 2.5)
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xlabel("RMSE / Cramér-Rao bound (RMS over parameters; 1 = efficient)   "
                  "[text: success rate, median runtime]")
    ax.set_title(title + "\n(blue: joint, orange: staged:)", fontsize=9)
    ax.grid(True, axis="x", which="both", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def navigation(groups: list[Group], hours: float, title: str, path: Path) -> Path:
    """Radial position error of a 5-hour static navigation run, median over runs (2020 paper, Figure 11)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    shown = [g for g in best(groups) if any(r["nav_curve"] for r in g.ok)]
    t = np.linspace(0, hours, 2)
    for i, g in enumerate(shown):
        C = np.array([r["nav_curve"] for r in g.ok if r["nav_curve"]])
        t = np.linspace(0, hours, C.shape[1])
        label = f"traditional ({g.reference_error_arcsec:g}″ turntable)" if g.reference else g.solver
        # Calibrations that agree draw on top of each other: later lines are thinner and dashed so that
        # every one stays visible.
        style = {**_style(i), "linestyle": ("-", "--", "-.", ":")[i % 4], "lw": max(2.8 - 0.6 * i, 1.0)}
        ax.plot(t, np.median(C, 0), label=label, **style)
    ax.plot(t, np.zeros_like(t), "k-", lw=2, label="truth calibration")
    ax.set_xlabel("time (h)")
    ax.set_ylabel("position error (nmi), median over runs")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def traditional(levels: list[tuple[float, float]], infield: list[tuple[str, float]], ylabel: str, title: str,
                path: Path) -> Path:
    """A metric of the turntable calibration against its orientation error, with in-field levels."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    a = np.array(levels, float)
    ax.plot(a[:, 0], a[:, 1], "ko-", lw=2, label="traditional (turntable reference)")
    for i, (name, v) in enumerate(infield):
        ax.axhline(v, label=f"in-field: {name}", **_style(i))
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlim(0, a[:, 0].max() * 1.3)
    ax.set_yscale("log")
    ax.set_xlabel("turntable orientation error (arcsec, 1σ per axis)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def _curve_panels(panels: list[dict], title: str, path: Path, order: list[str] | None = None,
                  n: int = MAX_LINES) -> Path:
    """Step curves (fraction against a log axis), one panel per entry of ``panels``: each panel's ``n``
    best curves (largest ``score``) in colour and in the legend, every other solver as a thin grey line,
    so that every solver is drawn and the figure stays readable with seventy of them. A solver keeps its
    colour in every panel (its place in ``order``, else in the first panel's ranking).

    A panel: ``title``, ``xlabel``, ``ylabel``, ``x`` (shared abscissa), ``curves`` [(label, y, score)],
    optional ``xscale`` ("log" or "log2") and ``xlim``."""
    plt = _plt()
    ncol = min(2, len(panels))
    nrow = int(np.ceil(len(panels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(7.2 * ncol, 6.2 * nrow), squeeze=False)
    colour: dict[str, int] = {}
    for name in order or []:
        colour.setdefault(name, len(colour))
    for ax, p in zip(axes.flat, panels):
        curves = [c for c in p["curves"] if np.any(np.isfinite(c[1]))]
        ranked = sorted(range(len(curves)), key=lambda i: -np.nan_to_num(curves[i][2], nan=-np.inf))
        for i in ranked:
            colour.setdefault(curves[i][0], len(colour))
        top = ranked[:n]
        x = np.asarray(p["x"], float)
        grey = ranked[n:]
        for k, i in enumerate(grey):
            ax.step(x, curves[i][1], where="post", color="0.65", lw=0.6, alpha=0.7,
                    label=f"{len(grey)} other solvers" if k == 0 else None, zorder=1)
        for i in top:
            name, y, score = curves[i]
            ax.step(x, y, where="post", lw=1.6, label=f"{name} ({score:.2f})" if np.isfinite(score) else name,
                    zorder=3, **_style(colour[name]))
        if p.get("xscale", "log") == "log2":
            ax.set_xscale("log", base=2)
        else:
            ax.set_xscale("log")
        if p.get("xlim"):
            ax.set_xlim(*p["xlim"])
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel(p["xlabel"])
        ax.set_ylabel(p["ylabel"])
        ax.set_title(p["title"], fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        # below the panel: no search for a free spot among seventy curves, and no curve hidden
        ax.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False,
                  title=p.get("legend_title"), title_fontsize=6.5)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# The title of an ECDF panel per kind of target: its words and the format of each target
ECDF_TARGETS = {"cost": ("cost targets (f − f_opt) / f_opt ≤ ", "{:g}"), "accuracy": ("accuracy targets ≤ ", "{:g}")}


def runtime_ecdf(at, title: str, path: Path, order: list[str] | None = None, only: list[str] | None = None) -> Path:
    """Runtime ECDFs (COCO / IOHprofiler): per solver the fraction of (trial, target) pairs reached against
    evaluations, one panel for the cost targets and one for the accuracy targets (:mod:`optcal.studies.anytime`).
    ``only``: draw these solvers alone (every one of them in colour, up to twice the usual number)."""
    from optcal.studies.anytime import grid

    x = grid(at.top)
    panels = []
    for kind, targets in at.targets.items():
        head, fmt = ECDF_TARGETS[kind]
        panels.append({
            "title": head + ", ".join(fmt.format(t) for t in targets), "xlabel": "cost evaluations",
            "ylabel": "fraction of (trial, target) pairs reached", "x": x, "legend_title": "solver (ECDF area)",
            "curves": [(s, at.ecdf(kind, i, x), at.area(kind, i)) for i, s in enumerate(at.solvers)
                       if only is None or s in only]})
    if only is not None:  # colours numbered within the subset, so that no two of its solvers share a style
        order = [s for s in (order or []) if s in only]
    return _curve_panels(panels, title, path, order, n=MAX_LINES if only is None else 2 * MAX_LINES)


def runtime_ecdf_time(at, title: str, path: Path, order: list[str] | None = None) -> Path:
    """Runtime ECDFs against seconds of solver time (the same (trial, target) pairs as :func:`runtime_ecdf`,
    each met at the solver time of the point that met it): what a user waiting for a calibration sees,
    where a solver's own overhead per evaluation counts as well as its evaluations."""
    lo = np.nanmin([np.nanmin(np.where(np.isfinite(h) & (h > 0), h, np.nan)) for h in at.hits_s.values()])
    hi = at.top_s
    x = np.logspace(np.log10(max(lo, 1e-6)), np.log10(max(hi, 2 * lo)), 200)
    panels = []
    for kind, targets in at.targets.items():
        head, fmt = ECDF_TARGETS[kind]
        panels.append({
            "title": head + ", ".join(fmt.format(t) for t in targets), "xlabel": "solver time (s)",
            "ylabel": "fraction of (trial, target) pairs reached", "x": x, "legend_title": "solver (reached)",
            "curves": [(s, at.ecdf_s(kind, i, x), at.reached_s(kind, i)) for i, s in enumerate(at.solvers)]})
    return _curve_panels(panels, title, path, order)


def data_profiles(at, title: str, path: Path, order: list[str] | None = None) -> Path:
    """Data profiles (Moré & Wild 2009) at the profile targets: the fraction of problems solved within κ
    budget units of n + 1 evaluations."""
    from optcal.studies.anytime import PROFILE_TARGETS, data_profile

    panels = []
    for kind, target in PROFILE_TARGETS:
        T, n = at.profile_matrix(kind, target), at.profile_n(kind, target)
        if not len(T):
            continue
        hi = at.top / (max(n.min(), 1) + 1)
        k = np.unique(np.logspace(np.log10(1 / (n.max() + 1)), np.log10(hi), 200))
        what = f"(f − f_opt) / f_opt ≤ {target:g}" if kind == "cost" else f"accuracy ≤ {target:g}"
        curves = [(s, data_profile(T[:, i], n, k), float(np.mean(np.isfinite(T[:, i]))))
                  for i, s in enumerate(at.solvers)]
        panels.append({"title": f"data profile: {what} ({len(T)} problems)",
                       "xlabel": "κ = evaluations / (n + 1)", "ylabel": "fraction of problems solved",
                       "x": k, "curves": curves, "legend_title": "solver (solved within budget)"})
    return _curve_panels(panels, title, path, order)


def performance_profiles(at, title: str, path: Path, order: list[str] | None = None) -> Path:
    """Performance profiles (Dolan & Moré 2002) at the profile targets: the fraction of problems on which a
    solver's evaluations are within a factor τ of the fastest solver's."""
    from optcal.studies.anytime import PROFILE_TARGETS, performance_profile, performance_ratios

    panels = []
    for kind, target in PROFILE_TARGETS:
        T = at.profile_matrix(kind, target)
        if not len(T):
            continue
        R = performance_ratios(T)
        fin = R[np.isfinite(R)]
        hi = max(2.0, float(fin.max()) * 1.5) if fin.size else 2.0
        tau = np.unique(np.concatenate([[1.0], np.logspace(0, np.log2(hi), 300, base=2.0)]))
        P = performance_profile(T, tau)
        what = f"(f − f_opt) / f_opt ≤ {target:g}" if kind == "cost" else f"accuracy ≤ {target:g}"
        panels.append({"title": f"performance profile: {what} ({len(T)} problems)",
                       "xlabel": "τ (evaluations / the fastest solver's)", "ylabel": "fraction of problems",
                       "x": tau, "xscale": "log2", "xlim": (1, hi),
                       "legend_title": "solver (mean of the profile over log τ)",
                       "curves": [(s, P[i], float(np.mean(P[i]))) for i, s in enumerate(at.solvers)]})
    return _curve_panels(panels, title, path, order)
