"""CI tracking from the command line: run a study (the CI spec, optcal/studies/specs/ci.toml, or any other) and check
it against a committed baseline (``optcal/studies/ci_tolerances.toml`` for the CI spec) with the study's own
intervals (:mod:`optcal.studies.baseline` says how).

``python -m optcal.app.study_ci [--spec SPEC] [--baseline FILE] [--out DIR] [--junit FILE] [--propose]
[--check-runtime]`` runs the study, prints each metric beside its baseline and interval, writes a JUnit XML report with
one test case per solver and metric, and with ``--propose`` prints a baseline of the values just measured (to commit
after a deliberate change). ``optcal study export DIR --format junit`` checks a study folder already run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from optcal.core.atomicfile import write_atomic
from optcal.core.errors import InputError
from optcal.studies.baseline import METRICS as METRICS
from optcal.studies.baseline import (
    TOLERANCES,
    Result,
    check,
    junit_xml,
    load_baseline,
    machine,
    measure,
    propose,
    regressions,
)
from optcal.studies.execute import run_study
from optcal.studies.spec import load
from optcal.studies.store import Store

__all__ = ["METRICS", "TOLERANCES", "Result", "check", "junit_xml", "load_baseline", "machine", "measure", "propose",
           "regressions", "run_ci", "main"]


def run_ci(folder: str | Path, spec: str | Path = "ci", runs: int | None = None) -> tuple[dict, float, int]:
    """Run ``spec`` into ``folder``; its measured metrics, the wall time and the seed."""
    sp = load(spec)
    if runs is not None:
        sp = sp.with_runs(runs)
    s = run_study(sp, folder, progress=False)
    with Store.open_existing(folder) as st:
        return measure(st.rows(), sp.seed), s.wall_s, sp.seed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m optcal.app.study_ci", description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="ci", help="the study spec (default: the CI spec)")
    ap.add_argument("--baseline", help="baseline file (default: optcal/studies/ci_tolerances.toml for the CI spec)")
    ap.add_argument("--out", help="study folder (default: a temporary one)")
    ap.add_argument("--junit", metavar="FILE", help="write the check as JUnit XML")
    ap.add_argument("--propose", action="store_true", help="print a baseline of the measured values")
    ap.add_argument("--check-runtime", action="store_true",
                    help="check the median run time too (only on the baseline's machine)")
    a = ap.parse_args(argv)
    try:
        base_path = a.baseline or (TOLERANCES if a.spec == "ci" else None)
        if base_path is None and not a.propose:
            raise InputError(f"spec {a.spec}: give its baseline with --baseline (write one with --propose)")
        with tempfile.TemporaryDirectory() as tmp:
            measured, wall, _ = run_ci(a.out or tmp, a.spec)
        if a.propose:
            print(propose(measured, load(a.spec).name))
            if base_path is None:
                return 0
        results = check(measured, load_baseline(base_path), runtime=a.check_runtime)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for r in results:
        print(("REGRESSION: " if r.status in ("regression", "missing") else "  ") + r.message)
    print(f"wall time {wall:.1f} s")
    if a.junit:
        write_atomic(a.junit, junit_xml(results, load(a.spec).name), overwrite=True)
    return 1 if regressions(results) else 0


if __name__ == "__main__":
    sys.exit(main())
