"""Issue #32: `make run` is the headline study with every configuration, on the runs the README states.

The time itself is measured end to end on a fresh clone (docs/performance.md, "The time of `make run`"); what
a test can hold is that the command keeps every configuration of the spec, runs the number of Monte-Carlo
runs the README and the docs give, and installs what those configurations need.
"""

from __future__ import annotations

import re
from pathlib import Path

from optcal.studies.spec import load

ROOT = Path(__file__).resolve().parents[1]


def _makefile() -> str:
    return (ROOT / "Makefile").read_text(encoding="utf-8")


def _target(name: str) -> str:
    """The recipe of one Makefile target (its lines up to the next blank line)."""
    text = _makefile()
    m = re.search(rf"^{re.escape(name)}:(.*?)(?:\n\n|\Z)", text, re.S | re.M)
    assert m, f"no target {name} in the Makefile"
    return m.group(0)


def _runs() -> int:
    m = re.search(r"^RUNS\s*\?=\s*(\d+)\s*$", _makefile(), re.M)
    assert m, "the Makefile sets no RUNS"
    return int(m.group(1))


def test_make_run_keeps_every_configuration_on_fewer_runs():
    spec = load("compare")
    runs = _runs()
    run = " ".join(_target("run").split())
    # the shipped spec, whole: no solver filter, no other spec, the Makefile's run count
    assert "optcal study run compare --runs $(RUNS)" in run
    assert "--solvers" not in run and "--limit" not in run and "--quick" not in run
    assert 1 < runs < spec.runs == 50
    labels = [c.label for c in spec.solvers]
    # every registered solver jointly and staged, and nevergrad's three (the test extra has them all)
    assert len(labels) == 41 and {"ng:NGOpt", "ng:TwoPointsDE", "ng:OnePlusOne", "cmaes", "staged:cmaes"} <= set(labels)
    full = " ".join(_target("run-full").split())
    assert "optcal study run compare --executor" in full and "--runs" not in full
    # the trial count the Makefile's comment states
    assert f"({runs * len(labels) * len(spec.models) * len(spec.schemes):,} trials)" in _makefile()


def test_readme_and_docs_state_the_runs_of_make_run():
    runs = _runs()
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    perf = " ".join((ROOT / "docs" / "performance.md").read_text(encoding="utf-8").split())
    assert f"{runs} of its 50 Monte-Carlo runs" in readme
    assert f"{runs} of its 50 Monte-Carlo runs" in perf


def test_make_run_installs_what_the_study_runs():
    """The run's install has nevergrad (the three ng: configurations) and mealpy; the tests' tools come on top."""
    stamp = _makefile().split("$(RUN_STAMP): pyproject.toml", 1)[1].split("\n\n", 1)[0]
    assert '-e ".[nevergrad]"' in stamp and "install-without-deps" in stamp and "optcal.core.warmup" in stamp
    assert "$(STAMP): $(RUN_STAMP)" in _makefile()
    assert _target("run").split("\n", 1)[0] == "run: $(RUN_STAMP)"
