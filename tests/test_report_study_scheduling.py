"""The order in which a study's trials go to the workers (optcal.studies.execute.schedule, issue #22): the last runs'
trials one by one, longest expected first, so that no worker waits at the end for another's chunk of
CMA-ES and nevergrad trials; and the order changes no result (trials.csv the same, column for column)."""

from __future__ import annotations

import csv

import pytest

from optcal.studies import execute
from optcal.studies.execute import chunks, expected_seconds, run_study, schedule
from optcal.studies.spec import load, parse, tomllib
from optcal.studies.store import TIMING
from optcal.studies.trial import trials

SPEC = """
name = "order"
runs = 3
seed = 5
models = ["nonlinear12"]
schemes = ["24"]
tilt_deg = 1.0
budget = 1500
[navigation]
enabled = false
[[solvers]]
name = "scipy-lm"
[[solvers]]
name = "cmaes"
[[solvers]]
name = "pso"
[[solvers]]
name = "staged:scipy-lm"
"""


def test_the_expected_time_follows_the_budget_and_the_solver_s_own_python():
    ts = {t.config.label: t for t in trials(load("compare")) if t.run == 0 and t.scheme == "24"
          and t.model == "nonlinear12"}
    # nevergrad: 2,000 evaluations at about 1 ms; CMA-ES (and staged:cmaes): 20,000 at 0.05 ms
    assert expected_seconds(ts["ng:NGOpt"]) == pytest.approx(2.0)
    assert expected_seconds(ts["staged:cmaes"]) == expected_seconds(ts["cmaes"]) == pytest.approx(1.0)
    assert expected_seconds(ts["scipy-lm"]) == pytest.approx(0.06)
    longest = sorted(ts, key=lambda k: -expected_seconds(ts[k]))[:5]
    assert set(longest) == {"ng:NGOpt", "ng:TwoPointsDE", "ng:OnePlusOne", "cmaes", "staged:cmaes"}


def test_the_last_two_runs_go_one_by_one_longest_first_after_chunks_of_consecutive_trials():
    tasks = trials(load("compare").quick())  # 41 configurations × 2 models × 2 schemes × 10 runs
    cs = schedule(tasks, 2)
    assert sorted(t.id for c in cs for t in c) == sorted(t.id for t in tasks)  # every trial once
    head, tail = tasks[:-82], tasks[-82:]  # the last two data sets (trials go run by run): run 9, seed15, 24 and 36
    assert {(t.model, t.scheme, t.run) for t in tail} == {("seed15", "24", 9), ("seed15", "36", 9)}
    assert cs[:-82] == chunks(head, 2)
    single = [c[0] for c in cs[-82:]]
    assert all(len(c) == 1 for c in cs[-82:])
    cost = [expected_seconds(t) for t in single]
    assert cost == sorted(cost, reverse=True)
    # nevergrad's three of both runs first, equal ones in trial order, then cmaes and staged:cmaes
    assert [t.id for t in single[:6]] == [tasks[i].id for i in (-44, -43, -42, -3, -2, -1)]
    assert {t.config.label for t in single[6:10]} == {"cmaes", "staged:cmaes"}
    # one worker, or one run: the chunks as they were
    assert schedule(tasks, 1) == chunks(tasks, 1)
    assert schedule(tasks[-41:], 2)[0] == [max(tasks[-41:], key=expected_seconds)]


def _trials_csv(folder) -> list[dict]:
    with open(folder / "trials.csv", newline="") as fh:
        return [{k: v for k, v in r.items() if k not in TIMING} for r in csv.DictReader(fh)]


def test_the_order_of_the_work_changes_no_result(tmp_path, monkeypatch):
    spec = parse(tomllib.loads(SPEC), "order.toml")
    cs = schedule(trials(spec), 2)
    assert cs != chunks(trials(spec), 2) and cs[-8][0].config.label == "cmaes"  # the last two runs: cmaes first
    ordered = run_study(spec, tmp_path / "ordered", executor="processes", workers=2, progress=False)
    monkeypatch.setattr(execute, "TAIL_RUNS", 0)  # every trial in chunks of consecutive trials, in order
    assert schedule(trials(spec), 2) == chunks(trials(spec), 2)
    plain = run_study(spec, tmp_path / "plain", executor="processes", workers=2, progress=False)
    assert ordered.ran == plain.ran == 12 and ordered.failed == plain.failed == 0
    a, b = _trials_csv(tmp_path / "ordered"), _trials_csv(tmp_path / "plain")
    assert len(a) == 12 and a == b
    for column in ("accuracy", "fun", "x_est", "err", "converged", "ver_mean_ug", "nfev"):
        assert [r[column] for r in a] == [r[column] for r in b] and all(r[column] != "" for r in a)
