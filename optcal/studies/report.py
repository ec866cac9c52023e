"""``optcal study report DIR``: ``report.md`` with tables and PNG figures, ``parameters.md`` with every
per-parameter statistic, and ``summary.json`` (one record per solver × scheme × model) for tools and CI."""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import json
import math
from pathlib import Path

import numpy as np

from optcal.core.atomicfile import atomic_write
from optcal.core.errors import InputError
from optcal.studies import anytime, figures, paired
from optcal.studies.metrics import Group, cells, groups
from optcal.studies.report_sections import (
    accelerometer,
    anytime_section,
    fmt,
    label_of,
    md_table,
    navigation_section,
    per_position,
    positions_of,
    preamble,
    ranked_on,
    scheme_phrase,
    traditional_section,
    with_ci,
)
from optcal.studies.store import Store

# summary.json: 2 = an object (study, provenance, records, paired, settings); 1 was the list of records alone
SUMMARY_FORMAT = 2


class FinishedGroup(Group):
    """A :class:`optcal.studies.metrics.Group` whose rows no longer change (a report's): each derived number is
    computed once, where a plain group recomputes its per-parameter statistics at every use (the report
    asks for them hundreds of times: ranking, tables, figures, records). Callers get copies of the cached
    dicts, so that no caller can change what another one reads."""

    ok = functools.cached_property(Group.ok.fget)
    success_rate = functools.cached_property(Group.success_rate.fget)
    failures = functools.cached_property(Group.failures.fget)
    accuracy = functools.cached_property(Group.accuracy.fget)
    accuracy_presets = functools.cached_property(Group.accuracy_presets.fget)

    @functools.cached_property
    def _parameters(self) -> list[dict]:
        return Group.parameters(self)

    def parameters(self) -> list[dict]:
        return [dict(p) for p in self._parameters]

    @functools.cached_property
    def _summary(self) -> dict:
        return Group.summary(self)

    def summary(self) -> dict:
        return dict(self._summary)

    @functools.cached_property
    def _unobservable(self) -> list[dict]:
        return Group.unobservable(self)

    def unobservable(self) -> list[dict]:
        return [dict(d) for d in self._unobservable]

    def for_figures(self) -> FinishedGroup:
        """A copy for the figures: every statistic computed from the whole rows, the rows cut to
        :data:`FIGURE_COLUMNS` (about 40 % of a row), which is what a figure worker unpickles."""
        for name in ("ok", "success_rate", "failures", "accuracy", "accuracy_presets", "_parameters", "_summary",
                     "_unobservable"):
            getattr(self, name)
        c = copy.copy(self)
        c.rows = [{k: r.get(k) for k in FIGURE_COLUMNS} for r in self.rows]
        c.__dict__["ok"] = [r for r in c.rows if r["status"] == "ok"]
        return c


# The row columns optcal.studies.figures draws from (beside the groups' statistics).
FIGURE_COLUMNS = ("run", "status", "converged", "names", "fun", "trace", "ver_err", "ver_truth", "nav_curve",
                  "nav_max_nmi")


class FigureInputs:
    """The report's :class:`optcal.studies.figures.Renderer` ``prepare``: a group, a list of groups or a dict of
    lists of groups (the cells) becomes the same of :meth:`FinishedGroup.for_figures` copies, each group's
    made once; anything else goes as it is."""

    def __init__(self):
        self.copies: dict[int, FinishedGroup] = {}

    def __call__(self, a):
        if isinstance(a, FinishedGroup):
            if id(a) not in self.copies:
                self.copies[id(a)] = a.for_figures()
            return self.copies[id(a)]
        if isinstance(a, list) and a and all(isinstance(g, FinishedGroup) for g in a):
            return [self(g) for g in a]
        if isinstance(a, dict) and a and all(isinstance(v, list) for v in a.values()):
            return type(a)((k, self(v)) for k, v in a.items())
        return a


def finished_groups(rows: list[dict], order: list[str] | None = None) -> list[FinishedGroup]:
    """:func:`optcal.studies.metrics.groups` as :class:`FinishedGroup` (the report's groups)."""
    return [FinishedGroup(**{f.name: getattr(g, f.name) for f in dataclasses.fields(g)}) for g in groups(rows, order)]


def rank_value(g: Group) -> float:
    """What the report ranks on: RMSE/CRLB against the bound of data and presets together when the study
    has presets (the bound no method beats, so a method the presets help does not lead for that alone),
    else RMSE/CRLB against the data's bound."""
    return g.accuracy_presets if np.isfinite(g.accuracy_presets) else g.accuracy


def _rank(gs: list[Group]) -> list[Group]:
    """Most accurate first (:func:`rank_value`) among the groups at the noise floor as often; never-converging
    and failed groups last."""
    return sorted(gs, key=lambda g: (-round(g.success_rate, 6), np.nan_to_num(rank_value(g), nan=np.inf)))


def _has_presets_bound(gs: list[Group]) -> bool:
    return any(np.isfinite(g.accuracy_presets) for g in gs)


def accuracy_per_position(g: Group, n: int | None, sigma: float) -> float:
    """A group's RMSE·√N/σ (:func:`optcal.studies.report_sections.per_position` of its per-parameter RMSEs, their
    observable parts as in RMSE/CRLB) for its scheme's ``n`` positions and the noise SD ``sigma`` (g); NaN
    for a turntable configuration, which fits other positions."""
    if g.reference:
        return float("nan")
    return per_position([p.get("rmse_observable") for p in g.parameters()], n, sigma)


def crlb_per_position(gs: list[Group], n: int | None, sigma: float) -> float:
    """The Cramér-Rao bound per position of a model × scheme (the bounds of its in-field trials, which share
    their data sets, as :func:`accuracy_per_position` takes the RMSEs)."""
    g = next((g for g in gs if not g.reference and g.ok), None)
    return float("nan") if g is None else per_position([p["crlb"] for p in g.parameters()], n, sigma)


def _summary_rows(gs: list[Group], nav: bool, cis: dict | None = None,
                  per_pos: dict | None = None, verification: bool = True) -> list[list[str]]:
    """The per-cell table's rows; ``cis`` maps id(group) to its bootstrap intervals (anytime.group_ci),
    ``per_pos`` to its accuracy per position (a column when given); ``verification``: the verification
    column (the accelerometer's; the gyroscope's problem has no verification set)."""
    rows = []
    presets = _has_presets_bound(gs)
    for g in _rank(gs):
        s = g.summary()
        ci = (cis or {}).get(id(g), {})
        r = [
            f"`{label_of(g)}`", with_ci(s["success_rate"], ci.get("success_rate"), ".0f", 100, " %"),
            with_ci(s["accuracy"], ci.get("accuracy"), ".2f"),
            *([with_ci(s["accuracy_presets"], ci.get("accuracy_presets"), ".2f")] if presets else []),
            *([fmt(per_pos[id(g)], ".3g")] if per_pos is not None else []),
            *([f"{fmt(s['ver_mean_ug'], '.2f')} ({fmt(s['ver_sd_ug'], '.2f')})"] if verification else []),
            f"{fmt(s['cost_median'], '.2e')} [{fmt(s['cost_min'], '.2e')}, {fmt(s['cost_max'], '.2e')}]",
            (with_ci(s["runtime_median_s"], ci.get("runtime_median_s"), ".3g") if cis is not None else
             f"{fmt(s['runtime_median_s'], '.3g')} "
             f"[{fmt(s['runtime_p10_s'], '.3g')}, {fmt(s['runtime_p90_s'], '.3g')}]"),
            fmt(s["nfev_median"], ",.0f"),
            fmt(s["evals_per_s"], ",.0f"),
        ]
        if nav:
            r.append(f"{fmt(s['nav_max_nmi'], '.4f')} / {fmt(s['nav_mean_nmi'], '.4f')}")
        r.append(str(s["failed"]))
        rows.append(r)
    return rows


SUMMARY_HEADER = ["solver", "at noise floor", "RMSE/CRLB", "verification µg mean (SD)",
                  "final cost (g²) median [min, max]", "runtime s median [95 % CI]", "evaluations (median)",
                  "evaluations/s"]
NAV_HEADER = "5-h navigation error max / mean (nautical miles)"
PER_POSITION_HEADER = "RMSE·√N/σ (per position)"
GYRO_COST_HEADER = "final χ² median [min, max]"  # the gyroscope's whitened residuals: no unit


def parameter_units(spec: dict, model: str) -> dict[str, str]:
    """{parameter: unit} of a study's model: the accelerometer's with outputs in g (the studies simulate
    specific force in g), the gyroscope's with outputs in counts (its simulated sensor's)."""
    if accelerometer(spec):
        from optcal.core.model import get_model

        return get_model(model).units("g")
    from optcal.core.gyro.model import param_units

    return param_units("counts")


def _parameters_md(cs, spec: dict) -> str:
    lines = ["# Per-parameter statistics", "",
             "Error = estimate − truth over the runs that did not fail, in the parameter's unit. CRLB: Cramér-Rao "
             "SD at the truth with the simulation noise; ratio = RMSE of the observable part / CRLB. Parameters "
             "marked * have weight in an unobservable direction: their ratio scores only their observable part.",
             ""]
    for (model, scheme), gs in cs.items():
        units = parameter_units(spec, model)
        for g in gs:
            lines.append(f"## {model}, {scheme_phrase(scheme)}: `{label_of(g)}`")
            lines.append("")
            rows = [[p["name"] + ("" if p["observable"] else "*"), units.get(p["name"], "–"), fmt(p["mean"], ".3e"),
                     fmt(p["rmse"], ".3e"), fmt(p["sd"], ".3e"), fmt(p["crlb"], ".3e"), fmt(p["ratio"], ".3g")]
                    for p in g.parameters()]
            lines += md_table(["parameter", "unit", "mean error", "RMSE", "SD", "CRLB", "RMSE/CRLB"], rows)
    return "\n".join(lines)


def _json_safe(v):
    if isinstance(v, dict):
        return {k: _json_safe(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_json_safe(x) for x in v]
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer | np.bool_):
        return v.item()
    return v


def headline(folder: str | Path, top: int = 8) -> str:
    """The ``top`` solvers of each model × scheme (the report's ranking: :func:`_rank`), as markdown tables."""
    with Store.open_existing(folder) as store:
        spec, rows = store.spec, store.rows()
    return "\n".join(headline_lines(spec, rows, top))


def headline_lines(spec: dict, rows: list[dict], top: int = 8) -> list[str]:
    """:func:`headline`'s tables from ``rows`` (any subset of a study's rows: the study so far)."""
    out = []
    for (model, scheme), cg in cells(finished_groups(rows, [s["label"] for s in spec["solvers"]])).items():
        ranked = _rank(cg)
        out.append(f"{model}, {scheme_phrase(scheme)} ({min(top, len(ranked))} best of {len(ranked)}):")
        wp, acc = _has_presets_bound(cg), accelerometer(spec)
        out += md_table(["solver", "at noise floor", "RMSE/CRLB"] + (["with presets"] if wp else [])
                      + (["verification µg"] if acc else []) + ["runtime s"],
                      [[f"`{label_of(g)}`", f"{100 * g.success_rate:.0f} %", fmt(g.accuracy, ".2f")]
                       + ([fmt(g.accuracy_presets, ".2f")] if wp else [])
                       + ([fmt(g.summary()["ver_mean_ug"], ".2f")] if acc else [])
                       + [fmt(g.summary()["runtime_median_s"], ".3g")]
                       for g in ranked[:top]])
    return out


# The columns of a row the headline reads (what a running study keeps of each finished trial for it).
HEADLINE_COLUMNS = (
    "trial_id", "model", "scheme", "solver", "solver_name", "run", "reference", "reference_error_arcsec", "status",
    "message", "success", "converged", "fun", "nfev", "runtime_s", "names", "err", "err_proj", "crlb", "crlb_presets",
    "observable", "ver_mean_ug", "ver_sd_ug", "ver_truth_mean_ug", "nav_max_nmi", "nav_mean_nmi")


def write_progress(folder: str | Path, spec: dict, rows: list[dict], expected: int, elapsed_s: float) -> Path:
    """``report.md`` while a study runs: how far it is and the headline tables of the trials finished so far
    (rows cut to :data:`HEADLINE_COLUMNS`); the full report replaces it when the study ends."""
    failed = sum(r["status"] != "ok" for r in rows)
    runs = len({(r["model"], r["scheme"], r["run"]) for r in rows})
    L = [f"# Study `{spec['name']}`: in progress", "",
         f"{len(rows)} of {expected} trials finished ({failed} failed; {runs} model × scheme × run data sets "
         f"begun), {elapsed_s:.0f} s into this session. The tables below rank what has finished so far; this "
         "page is rewritten while the study runs and replaced by the full report when it ends (a stopped study "
         "resumes where it stopped when run again).", ""]
    L += headline_lines(spec, rows)
    path = Path(folder) / "report.md"
    with atomic_write(path, overwrite=True) as fh:
        fh.write("\n".join(L) + "\n")
    return path


def overview(cs) -> list[str]:
    """One row per solver, one column per model × scheme: RMSE/CRLB, with presets also RMSE against the
    bound of data and presets (:attr:`Group.accuracy_presets`), and the success rate; plus the median
    runtime over all cells; solvers ordered by their mean rank over the cells."""
    keys = list(cs)
    by = {k: {g.solver: g for g in cg} for k, cg in cs.items()}
    names = list(dict.fromkeys(g.solver for cg in cs.values() for g in cg))
    rank = {n: [] for n in names}
    for k in keys:
        for i, g in enumerate(_rank(list(by[k].values()))):
            rank[g.solver].append(i)
    names.sort(key=lambda n: np.mean(rank[n]))
    rows = []
    for n in names:
        cellv = []
        for k in keys:
            g = by[k].get(n)
            if g is None:
                cellv.append("–")
                continue
            bp = g.accuracy_presets
            both = fmt(g.accuracy, ".2f") + (f" / {fmt(bp, '.2f')}" if np.isfinite(bp) else "")
            cellv.append(f"{both} ({100 * g.success_rate:.0f} %)")
        rts = [by[k][n].summary()["runtime_median_s"] for k in keys if n in by[k]]
        rates = [by[k][n].summary()["evals_per_s"] for k in keys if n in by[k]]
        first = next(by[k][n] for k in keys if n in by[k])
        rows.append([f"`{label_of(first)}`"] + cellv + [fmt(float(np.median(rts)), ".3g"),
                                                      fmt(float(np.median(rates)), ",.0f")])
    return md_table(["solver"] + [f"{m}, {s}" for m, s in keys] + ["runtime s", "evaluations/s"], rows)


def busy_share(session: dict) -> float | None:
    """The share of the session's worker time spent inside trials: the rest is start-up, scheduling,
    writing results and idle workers at the end."""
    t = session.get("trials_wall_s")
    if t is None or not session.get("wall_s") or not session.get("trials"):
        return None
    return t / (session["wall_s"] * session["workers"])


def _busy(session: dict) -> str:
    b = busy_share(session)
    return "" if b is None else f", workers in trials {100 * b:.1f} % of the time"


def provenance(sessions: list[dict]) -> dict:
    """Where and with what the results were computed: the commits of the code that ran the trials (from the
    sessions), this machine, Python and the versions of the libraries the results depend on."""
    import os
    import platform
    from importlib import metadata

    libs = {}
    for name in ("optcal", "numpy", "scipy", "numba", "cma", "nlopt", "casadi", "nevergrad", "pandas", "matplotlib"):
        try:
            libs[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    commits = list(dict.fromkeys(s.get("code", "") for s in sessions if s.get("code")))
    return {"commit": commits[-1] if commits else None, "commits": commits,
            "machine": {"node": platform.node(), "system": platform.platform(), "processor": platform.machine(),
                        "cpus": os.cpu_count()},
            "python": platform.python_version(), "libraries": libs}


def settings(spec: dict, rows: list[dict]) -> list[dict]:
    """Per solver configuration: its registry name, every option as it ran (defaults filled in), its budget,
    and the median iterations and evaluations its trials used (the iteration count a solver derives from the
    budget, as run), with the share of trials the final target stopped (optcal.studies.trial.FINAL_GAP) and the share
    of trials each reason ended (``stop_reasons``: optcal.solvers.base.STOP_REASONS, e.g. the stagnation rule,
    optcal.studies.trial.STAGNATION)."""
    from optcal import solvers

    out = []
    for c in spec["solvers"]:
        label = c.get("label") or c["name"]
        try:
            config = dict(solvers.get(c["name"], **c.get("options", {})).config)
        except Exception:  # noqa: BLE001 - an old store may name a solver this installation lacks
            config = dict(c.get("options", {}))
        mine = [r for r in rows if r["solver"] == label and r["status"] == "ok"]
        # A trial the final target stopped inside a solver that reports its iterations only at its end has
        # none to report (0): its iteration count is not known, and is left out.
        nit = [r["nit"] for r in mine if r.get("nit") is not None and not (r.get("at_target") and not r["nit"])]
        nfev = [r["nfev"] for r in mine if r.get("nfev") is not None]
        stopped = [r.get("at_target") for r in mine if r.get("at_target") is not None]
        reasons = [r["stop_reason"] for r in mine if r.get("stop_reason")]
        out.append({"solver": label, "name": c["name"], "options": config, "budget": c.get("budget", {}),
                    "reference": bool(c.get("reference")),
                    "iterations_median": float(np.median(nit)) if nit else None,
                    "evaluations_median": float(np.median(nfev)) if nfev else None,
                    "stopped_at_target": float(np.mean(stopped)) if stopped else None,
                    "stop_reasons": {k: reasons.count(k) / len(reasons) for k in sorted(set(reasons),
                                                                                   key=STOP_ORDER.index)}})
    return out


def _options_text(o: dict) -> str:
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in o.items()) or "–"


# The order of the stop reasons in the tables (optcal.solvers.base.STOP_REASONS), and how the tables name them.
STOP_ORDER = ("target", "own", "stagnation", "budget", "time", "callback", "error")
STOP_TEXT = {"target": "final target", "own": "own criteria", "stagnation": "stagnation", "budget": "budget",
             "time": "time budget", "callback": "callback", "error": "error"}


def stop_text(reasons: dict) -> str:
    """``{"budget": 0.6, "stagnation": 0.4}`` as "budget 60 %, stagnation 40 %" (most frequent first)."""
    parts = sorted(reasons.items(), key=lambda kv: (-kv[1], STOP_ORDER.index(kv[0])))
    return ", ".join(f"{STOP_TEXT[k]} {100 * v:.0f} %" for k, v in parts) or "–"


def settings_section(st: list[dict]) -> list[str]:
    rule = _stagnation()
    L = ["## Solver settings", "",
         "Every option as the trials ran it (defaults filled in), the budget, and the median iterations and "
         "evaluations per calibration; *stopped at target*: share of trials that stopped once their cost was "
         f"within {_final_gap():g} of the data's optimum (COCO's final target; the anytime record is flat beyond "
         "it, so no table changes); *ended by*: why the trials ended, as shares: the *final target*, the solver's "
         "*own criteria* (its tolerances, pycma's criteria, its iteration count), the *budget*, or "
         + (f"the *stagnation* rule (solvers that take it: the best cost improved by no more than {rule.rtol:g} of "
            f"itself over the last {100 * rule.share:g} % of the evaluation budget, of each stage's inside staged:)."
            if rule is not None else "the stagnation rule (off in this study's code).") + "", ""]
    L += md_table(["solver", "options", "budget", "iterations (median)", "evaluations (median)", "stopped at target",
                   "ended by"],
                  [[f"`{x['solver']}`", _options_text(x["options"]),
                    ", ".join(f"{k} {v:,}" if isinstance(v, int) else f"{k} {v}" for k, v in x["budget"].items())
                    or "solver's default",
                    fmt(x["iterations_median"], ",.0f"), fmt(x["evaluations_median"], ",.0f"),
                    "–" if x["stopped_at_target"] is None else f"{100 * x['stopped_at_target']:.0f} %",
                    stop_text(x.get("stop_reasons") or {})] for x in st])
    return L


def _stagnation():
    from optcal.studies.trial import STAGNATION

    return STAGNATION


def _final_gap() -> float:
    from optcal.studies.trial import FINAL_GAP

    return FINAL_GAP or 0.0


def paired_section(cs, presets: bool) -> tuple[list[str], list[dict]]:
    """The paired comparisons of every cell (:mod:`optcal.studies.paired`) as one compact table, and their records."""
    recs = []
    by_cell = {}
    for (model, scheme), cg in cs.items():
        ranked = [g for g in _rank(cg) if not g.reference]
        rr = paired.compare_to_best(ranked, presets)
        for x in rr:
            x.update(model=model, scheme=scheme)
        recs += rr
        by_cell[model, scheme] = ({x["solver"]: x for x in rr}, ranked[0].solver if ranked else None)
    if not recs:
        return [], []
    what = "RMSE/CRLB with presets" if presets else "RMSE/CRLB"
    L = ["## Paired comparisons", "",
         f"Each solver against the best of its model × scheme (named in the header), over the same runs: Wilcoxon "
         f"signed-rank test on the per-run differences of the accuracy ranked on ({what} of each run), p-values "
         f"Holm-adjusted within the column (family-wise level {paired.LEVEL:g}); r = matched-pairs rank-biserial "
         "correlation (+1: worse than the best in every run, 0: neither ahead), Δ = median paired difference. "
         "*≈*: no significant difference.", ""]
    names = list(dict.fromkeys(x["solver"] for x in recs))
    keys = list(by_cell)
    rows = []
    for n in names:
        r = [f"`{n}`"]
        for k in keys:
            x = by_cell[k][0].get(n)
            if x is None:
                r.append("best" if by_cell[k][1] == n else "–")
            elif x["verdict"] == "no difference":
                r.append(f"≈ (p {x['p_holm']:.2g})")
            elif x["verdict"] == "–":
                r.append("–")
            else:
                r.append(f"{x['verdict']}: Δ {x['median_diff']:+.2f}, r {x['rank_biserial']:+.2f}, p {x['p_holm']:.1e}")
        rows.append(r)
    L += md_table(["solver"] + [f"{m}, {s} (best: `{by_cell[m, s][1]}`)" for m, s in keys], rows)
    return L, recs


def write_report(folder: str | Path, workers: int | None = None) -> Path:
    """Write ``report.md``, ``parameters.md``, ``summary.json`` and ``figures/*.png`` into ``folder``.

    ``workers``: processes that draw the figures beside the report's own work (0: none, every figure drawn
    here; default: :func:`optcal.studies.figures.figure_workers`); the files are the same either way."""
    import time

    t_report = time.perf_counter()
    folder = Path(folder)
    with Store.open_existing(folder) as store:
        spec = store.spec
        n_groups = len(spec["solvers"]) * len(spec["models"]) * len(spec["schemes"])
        # the workers start (Python, NumPy, matplotlib) while this process reads the trials
        render = figures.Renderer(figures.figure_workers(n_groups) if workers is None else workers,
                                  prepare=FigureInputs(), start=True)
        try:
            rows = store.rows()
            sessions = json.loads(store.meta("sessions") or "[]")
            wall = float(store.meta("wall_s") or 0)
            spec_hash = store.meta("spec_hash")
        except BaseException:
            render.close()
            raise
    figdir = folder / "figures"
    figdir.mkdir(exist_ok=True)
    order = [s["label"] for s in spec["solvers"]]
    gs = finished_groups(rows, order)
    cs = cells(gs)
    presets = any(_has_presets_bound(cg) for cg in cs.values())
    has_nav = any(r.get("nav_max_nmi") is not None for r in rows)
    with render:
        cis = {id(g): anytime.group_ci(g, spec["seed"]) for g in gs}
        L = preamble(spec, rows, spec_hash, presets, _final_gap(), _stagnation())
        if len(cs) > 1:
            L += _overview_section(cs, presets)
        paired_lines, paired_recs = paired_section(cs, presets)
        L += paired_lines
        summary = []
        for (model, scheme), cg in cs.items():
            lines, records = _cell_section(spec, model, scheme, cg, has_nav, cis, figdir, render)
            L += lines
            summary += records
        if len(cs):
            p = render.draw(figures.accuracy_runtime, figdir / "accuracy_runtime.png", cs,
                            f"{spec['name']}: accuracy against runtime",
                            names={k: f"{k[0]}, {scheme_phrase(k[1])}" for k in cs})
            L += ["## Accuracy against runtime", "", f"![accuracy against runtime](figures/{p.name})", ""]
        L += anytime_section(rows, order, spec, figdir, render)
        st = settings(spec, rows)
        L += settings_section(st)
        L += ["Per-parameter mean error, RMSE, SD and CRLB: [parameters.md](parameters.md). "
              "Every trial: `trials.csv` / `trials.parquet` / `study.sqlite`.", ""]
        prov = provenance(sessions)
        L += [f"Computed by commit `{prov['commit'] or 'unknown'}` on {prov['machine']['system']} "
              f"({prov['machine']['cpus']} CPUs), Python {prov['python']}; "
              + ", ".join(f"{k} {v}" for k, v in prov["libraries"].items()) + ".", ""]
        render.finish()
    parameters_md = _parameters_md(cs, spec)
    t_rep = time.perf_counter() - t_report
    L[L.index("@@WALL@@")] = (
        f"- Wall time {wall + t_rep:.1f} s: the study {wall:.1f} s over {len(sessions)} session(s) ("
        + "; ".join(f"{s['executor']} ×{s['workers']}: {s['trials']} trials in {s['wall_s']:.1f} s"
                    + _busy(s) + (f", code {s['code']}" if s.get("code") else "") for s in sessions)
        + f") and this report {t_rep:.1f} s.")
    expected = spec["runs"] * len(spec["models"]) * len(spec["schemes"]) * len(spec["solvers"])
    doc = {"format": SUMMARY_FORMAT,
           "study": {"name": spec["name"], "spec_hash": spec_hash, "runs": spec["runs"], "seed": spec["seed"],
                     "trials": len(rows), "expected": expected, "failed": sum(r["status"] != "ok" for r in rows),
                     "wall_s": wall, "report_s": t_rep, "ranked_on": "accuracy_presets" if presets else "accuracy",
                     "final_gap": _final_gap(),
                     "stagnation": None if _stagnation() is None else {"share": _stagnation().share,
                                                                       "rtol": _stagnation().rtol}},
           "provenance": prov, "records": summary, "paired": paired_recs, "settings": st}
    # strict JSON: a value that could not be computed (no presets, no navigation) is null, not NaN
    files = {"report.md": "\n".join(L), "summary.json": json.dumps(_json_safe(doc), indent=1, allow_nan=False),
             "parameters.md": parameters_md}
    # each through a temporary file beside it, all three complete before any is renamed (report.md last)
    with contextlib.ExitStack() as stack:
        for name, text in files.items():
            stack.enter_context(atomic_write(folder / name, overwrite=True)).write(text)
    return folder / "report.md"


def _overview_section(cs, presets: bool) -> list[str]:
    return ["## Overview", "", ("RMSE/CRLB / RMSE/CRLB with presets" if presets else "RMSE/CRLB")
            + f" (share at the noise floor) of every solver in every model × scheme, ranked on {ranked_on(presets)}, "
            "most accurate first (mean rank over the columns); runtime: median over the columns of the median "
            "solver time.", ""] + overview(cs)


def _cell_section(spec: dict, model: str, scheme: str, cg: list[FinishedGroup], has_nav: bool, cis: dict,
                  figdir: Path, render: figures.Renderer) -> tuple[list[str], list[dict]]:
    """One model × scheme's section of the report (its table, figures, per-parameter ratios, unobservable
    directions, navigation, traditional calibration and failures) and its summary.json records; ``has_nav``:
    whether the study computed navigation (a column of the table)."""
    slug = f"{model}_{scheme}".replace(":", "-")
    L = [f"## {model}, {scheme_phrase(scheme)}", ""]
    vt = [v for v in (g.summary()["ver_truth_ug"] for g in cg if g.ok) if np.isfinite(v)]
    truth_ver = float(np.mean(vt)) if vt else np.nan  # none without a verification set (the gyroscope's)
    n = positions_of(scheme)
    acc = accelerometer(spec)
    head = f"Truth calibration on the verification set: {fmt(truth_ver, '.2f')} µg (the noise floor)." if acc else ""
    per_pos, bound = None, float("nan")
    if acc:  # σ is the accelerometer's noise per reading, the parameters its
        sigma = spec["noise_ug"] * 1e-6
        per_pos = {id(g): accuracy_per_position(g, n, sigma) for g in cg}
        bound = crlb_per_position(cg, n, sigma)
        head += (f" Cramér-Rao bound per position (CRLB·√N/σ, N = {n or '–'}, σ = {spec['noise_ug']:g} µg): "
                 f"{fmt(bound, '.3g')}.")
    L += [head, ""] if head else []
    rest = SUMMARY_HEADER[3:] if acc else [GYRO_COST_HEADER] + SUMMARY_HEADER[5:]
    header = (SUMMARY_HEADER[:3] + (["RMSE/CRLB with presets"] if _has_presets_bound(cg) else [])
              + ([PER_POSITION_HEADER] if per_pos is not None else []) + rest
              + ([NAV_HEADER] if has_nav else []) + ["failed"])
    L += md_table(header, _summary_rows(cg, has_nav, cis, per_pos, verification=acc))
    records = [{**g.summary(), **{f"{k}_ci": list(v) for k, v in cis[id(g)].items()}, "positions": n,
                "accuracy_per_position": per_pos[id(g)] if per_pos is not None else float("nan"),
                "crlb_per_position": bound,
                "reference": g.reference, "reference_error_arcsec": g.reference_error_arcsec} for g in cg]
    ttl = f"{spec['name']}: {model}, {scheme_phrase(scheme)}"
    # the turntable fit minimises another cost (3-D residuals): not on the cost figures
    norm = [g for g in cg if not g.reference] or cg
    f1 = render.draw(figures.cost_per_run, figdir / f"cost_{slug}.png", norm, f"{ttl}: final cost per run")
    f2 = render.draw(figures.convergence, figdir / f"convergence_{slug}.png", norm, f"{ttl}: convergence")
    f3 = render.draw(figures.error_vs_crlb, figdir / f"crlb_{slug}.png", cg,
                     f"{ttl}: error against the Cramér-Rao bound")
    f4 = (render.draw(figures.verification, figdir / f"verification_{slug}.png", cg,
                      f"{ttl}: verification error per position") if acc else None)
    f0 = render.draw(figures.ranking, figdir / f"ranking_{slug}.png", cg, f"{ttl}: accuracy of every solver")
    L += [f"![ranking](figures/{f0.name})", "",
          f"![final cost per run](figures/{f1.name})", "", f"![convergence](figures/{f2.name})", "",
          f"![error against CRLB](figures/{f3.name})", ""]
    L += [f"![verification](figures/{f4.name})", ""] if f4 is not None else []
    # per-parameter ratios
    names = cg[0].names
    obs = cg[0].ok[0]["observable"] if cg[0].ok else [1] * len(names)
    L += ["RMSE / CRLB per parameter (\\* = observable part only):", ""]
    L += md_table(["solver"] + [n + ("" if o else "\\*") for n, o in zip(names, obs)],
                  [[f"`{label_of(g)}`"] + [fmt(p["ratio"], ".2g") for p in g.parameters()] for g in _rank(cg)])
    un = [(g, g.unobservable()) for g in _rank(cg) if g.unobservable()]
    if un:
        dirs = [d["direction"] for d in un[0][1]]
        L += ["Unobservable directions (natural units; set by the presets, not by the data, so not scored): "
              "RMS error along each, over runs.", ""]
        L += md_table(["solver"] + [f"`{d}`" for d in dirs],
                      [[f"`{label_of(g)}`"] + [fmt(d["rms"], ".2e") for d in u] for g, u in un])
    L += navigation_section((model, scheme), cg, spec["navigation"], figdir, slug, render)
    L += traditional_section((model, scheme), cg, figdir, slug, render)
    fails = [(g, g.failures) for g in cg if g.failures]
    if fails:
        L += ["Failures:", ""] + [f"- `{g.solver}` ({g.n_failed}): " + "; ".join(m[:200] for m in f[:3])
                                  for g, f in fails] + [""]
    return L, records


def read_summary(folder: str | Path) -> dict:
    """A study folder's summary.json (written by :func:`write_report`)."""
    path = Path(folder) / "summary.json"
    if not path.is_file():
        raise InputError(f"{folder} has no summary.json; write it with `optcal study report {folder}`")
    doc = json.loads(path.read_text())
    if not isinstance(doc, dict) or doc.get("format") != SUMMARY_FORMAT:
        raise InputError(f"{path} is from an older optcal; write it again with `optcal study report {folder}`")
    return doc
