"""The asv suite looks each module up where the benchmarked commit keeps it (benchmarks/_paths.py): today's
path, else the path before the layers' move (issue #30), so asv still runs over commits of either layout."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks._paths import module  # noqa: E402


def test_todays_paths_are_found():
    assert module("optcal.studies.spec").load is not None
    assert module("optcal.core.problem").CalibrationProblem.__module__ == "optcal.core.problem"
    assert module("optcal.solvers").get("scipy-lm").name == "scipy-lm"


@pytest.mark.parametrize("now, before", [("optcal.core.fakemod", "optcal.fakemod"),
                                         ("optcal.studies.fakemod", "studies.fakemod"),
                                         ("optcal.solvers", "solvers")])
def test_a_commit_before_the_move_is_read_at_its_old_path(monkeypatch, now, before):
    old = types.ModuleType(before)
    monkeypatch.setitem(sys.modules, before, old)
    if now == "optcal.solvers":  # today's exists: hide it as a commit before the move would not have it
        monkeypatch.setitem(sys.modules, now, None)
    assert module(now) is old


def test_a_module_missing_everywhere_is_an_error():
    with pytest.raises(ModuleNotFoundError):
        module("optcal.core.no_such_module_anywhere")
