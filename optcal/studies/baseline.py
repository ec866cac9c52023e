"""Checking a study against a committed baseline with the study's own intervals (the library of
:mod:`optcal.app.study_ci`, which runs it from the command line, and of ``optcal study export --format junit``).

The baseline holds, per solver (per model × scheme × solver when the spec has several cells), the values the
committed code measured: RMSE/CRLB (``accuracy``), the share of runs at the noise floor (``success_rate``), the
verification error (``ver_mean_ug``, µg) and the median solver time (``runtime_median_s``, s), with the machine
they were measured on. A metric regresses when the baseline lies outside the new run's 95 % bootstrap interval
over the Monte-Carlo runs (:mod:`optcal.studies.anytime`) on the bad side: the change is larger than the study can
tell from run-to-run scatter. The study's seeds are fixed, so the same code reproduces the baseline exactly
and every interval contains it. The run time is reported; it is checked the same way only when asked
(``runtime=True``) and on the machine that measured the baseline: times from another machine, or from a
machine shared with other work, say nothing about the code (the asv suite, docs/tracking.md, times the code
with repeated samples instead).
"""

from __future__ import annotations

import math
import platform
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.studies.anytime import group_ci, mean_ci
from optcal.studies.metrics import groups

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TOLERANCES = Path(__file__).parent / "ci_tolerances.toml"
# (metric, unit, better): the metrics a baseline holds and which way is better
METRICS = (("accuracy", "RMSE/CRLB", "lower"), ("success_rate", "fraction of runs", "higher"),
           ("ver_mean_ug", "µg", "lower"), ("runtime_median_s", "s", "lower"))


def machine() -> str:
    """This machine, as a baseline records it (host name and CPU count)."""
    import os

    return f"{platform.node()} ({os.cpu_count()} CPUs, {platform.machine()})"


def measure(rows: list[dict], seed: int) -> dict[str, dict[str, tuple[float, float, float]]]:
    """Per solver (``model|scheme|solver`` when the study has several cells): each metric of :data:`METRICS`
    as (value, 95 % interval low, high), the interval a percentile bootstrap over the runs."""
    gs = groups(rows)
    several = len({(g.model, g.scheme) for g in gs}) > 1
    out = {}
    for g in gs:
        s, ci = g.summary(), group_ci(g, seed)
        ver = [r.get("ver_mean_ug") if r["status"] == "ok" else np.nan for r in g.rows]
        ci["ver_mean_ug"] = mean_ci(np.asarray([np.nan if v is None else v for v in ver], float), seed)
        name = f"{g.model}|{g.scheme}|{g.solver}" if several else g.solver
        out[name] = {m: (float(s[m]), *map(float, ci[m])) for m, _, _ in METRICS}
    return out


def load_baseline(path: str | Path = TOLERANCES) -> dict:
    """A baseline file: ``{"machine": str, "solvers": {name: {metric: value}}}``."""
    p = Path(path)
    try:
        doc = tomllib.loads(p.read_text())
    except OSError as exc:
        raise InputError(f"baseline {p}: cannot read it ({exc.strerror}); write one with "
                         "`python -m optcal.app.study_ci --propose`") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"baseline {p}: not valid TOML ({exc})") from None
    if "solvers" not in doc or any(m not in v for v in doc["solvers"].values() for m, _, _ in METRICS[:3]):
        raise InputError(f"baseline {p} lacks [solvers.NAME] tables with accuracy, success_rate and ver_mean_ug; "
                         "write one with `python -m optcal.app.study_ci --propose`")
    return doc


@dataclass
class Result:
    """One metric of one solver against its baseline."""

    solver: str
    metric: str
    value: float
    interval: tuple[float, float]
    baseline: float | None
    status: str  # "ok", "regression", "reported" (not checked here), "missing"
    message: str


def check(measured: dict, baseline: dict, here: str | None = None, runtime: bool = False) -> list[Result]:
    """Every metric of every solver against the baseline (see the module docstring); the run time only with
    ``runtime`` and on the baseline's machine."""
    here = machine() if here is None else here
    same_machine = runtime and baseline.get("machine") == here
    base = baseline["solvers"]
    out = []
    for name in sorted(set(base) - set(measured)):
        out.append(Result(name, "-", math.nan, (math.nan, math.nan), None, "missing",
                          f"the baseline names a solver the study lacks: {name}"))
    for name in measured:
        if name not in base:
            out.append(Result(name, "-", math.nan, (math.nan, math.nan), None, "missing",
                              f"the baseline has no values for {name}"))
            continue
        for metric, unit, better in METRICS:
            v, lo, hi = measured[name][metric]
            b = base[name].get(metric)
            iv = f"{v:.4g} [{lo:.4g}, {hi:.4g}] {unit}"
            if b is None:
                out.append(Result(name, metric, v, (lo, hi), None, "reported", f"{name}: {metric} = {iv}, no baseline"))
                continue
            if metric == "runtime_median_s" and not same_machine:
                why = "from another machine" if runtime else "reported, not checked"
                out.append(Result(name, metric, v, (lo, hi), b, "reported",
                                  f"{name}: {metric} = {iv}; baseline {b:.4g} {why}"))
                continue
            if not math.isfinite(v):
                bad = True
            elif math.isfinite(lo) and math.isfinite(hi):
                bad = b < lo if better == "lower" else b > hi
            else:  # fewer than two runs: no interval, the values themselves
                bad = v > b if better == "lower" else v < b
            verdict = "worse than the baseline" if bad else "within"
            out.append(Result(name, metric, v, (lo, hi), b, "regression" if bad else "ok",
                              f"{name}: {metric} = {iv}, baseline {b:.4g} ({verdict}; {better} is better)"))
    return out


def regressions(results: list[Result]) -> list[str]:
    return [r.message for r in results if r.status in ("regression", "missing")]


def propose(measured: dict, spec_name: str) -> str:
    """A baseline file of the values just measured."""
    lines = [f"# Baseline of the study `{spec_name}`: the values the committed code measured, checked by",
             "# `python -m optcal.app.study_ci` and `optcal study export DIR --format junit` "
             "(optcal/app/study_ci.py): a metric",
             "# regresses when this value lies outside the new run's 95 % bootstrap interval on the bad side. The",
             "# run time is checked only with --check-runtime, on the machine named here. Written by",
             "# `python -m optcal.app.study_ci --propose` after a deliberate change.",
             f'machine = "{machine()}"', ""]
    for name, m in measured.items():
        lines.append(f'[solvers."{name}"]')
        lines += [f"{k} = {m[k][0]:.6g}" for k, _, _ in METRICS if math.isfinite(m[k][0])]
        lines.append("")
    return "\n".join(lines)


def junit_xml(results: list[Result], suite: str) -> str:
    """The check as JUnit XML (one test case per solver and metric; a regression is a failure, a metric not
    checked here is skipped), for CI services that show test reports."""
    import xml.etree.ElementTree as ET

    bad = sum(r.status in ("regression", "missing") for r in results)
    skipped = sum(r.status == "reported" for r in results)
    ts = ET.Element("testsuite", name=f"optcal study {suite}", tests=str(len(results)), failures=str(bad),
                    errors="0", skipped=str(skipped))
    for r in results:
        tc = ET.SubElement(ts, "testcase", classname=f"optcal.study.{suite}.{r.solver}", name=r.metric)
        if r.status in ("regression", "missing"):
            ET.SubElement(tc, "failure", message=r.message, type=r.status).text = r.message
        elif r.status == "reported":
            ET.SubElement(tc, "skipped", message=r.message)
        ET.SubElement(tc, "system-out").text = r.message
    root = ET.Element("testsuites", name="optcal", tests=str(len(results)), failures=str(bad))
    root.append(ts)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


