"""The same spec gives identical per-trial results under the serial, processes and Dask executors
(Dask: a real two-worker LocalCluster, reached by its address as a user reaches a cluster, and the
executor's own default LocalCluster). Only the timing columns may differ."""

from __future__ import annotations

import textwrap

import pytest

from optcal.studies import spec as S
from optcal.studies.execute import run_study
from optcal.studies.spec import tomllib  # tomllib, or tomli on Python 3.10
from optcal.studies.store import TIMING, Store

SPEC = textwrap.dedent("""
    name = "executors"
    runs = 3
    seed = 99
    models = ["nonlinear12", "seed15"]
    schemes = ["24"]
    tilt_deg = 1.0
    budget = 400
    [navigation]
    enabled = true
    [[solvers]]
    name = "scipy-lm"
    [[solvers]]
    name = "pso"
    options = {n_particles = 10, iterations = 30}
    [[solvers]]
    name = "staged:pso"
    options = {"inner.n_particles" = 8}
""")


def _rows(folder):
    with Store.open_existing(folder) as st:
        return [{k: v for k, v in r.items() if k not in TIMING} for r in st.rows()]


def _diff(a, b) -> list:
    """(trial, column) pairs that differ; empty when the two stores hold the same results."""
    assert [r["trial_id"] for r in a] == [r["trial_id"] for r in b]
    return [(x["trial_id"], k, x[k], y[k]) for x, y in zip(a, b) for k in x if x[k] != y[k]][:5]


@pytest.fixture(scope="module")
def spec():
    return S.parse(tomllib.loads(SPEC), "executors.toml")


@pytest.fixture(scope="module")
def serial_rows(spec, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    s = run_study(spec, out, executor="serial", progress=False)
    assert s.ran == 18 and s.failed == 0
    return _rows(out)


def test_processes_match_serial(spec, serial_rows, tmp_path):
    s = run_study(spec, tmp_path, executor="processes", workers=2, progress=False)
    assert (s.ran, s.workers) == (18, 2)
    assert _diff(_rows(tmp_path), serial_rows) == []
    # the session records the trials' own wall time, from which the report gives the workers' busy share
    import json

    from optcal.studies.report import busy_share

    with Store.open_existing(tmp_path) as st:
        session = json.loads(st.meta("sessions"))[-1]
        trials_wall = sum(r["wall_s"] for r in st.rows())
    assert session["trials_wall_s"] == pytest.approx(trials_wall, rel=1e-9)
    assert 0 < busy_share(session) <= 1


def test_trials_go_to_workers_in_chunks_of_consecutive_trials():
    from optcal.studies.execute import CHUNKS_PER_WORKER, MAX_CHUNK, chunks

    tasks = list(range(7200))
    cs = chunks(tasks, 2)
    assert [t for c in cs for t in c] == tasks  # every trial once, in order
    assert {len(c) for c in cs[:-1]} == {MAX_CHUNK}
    few = chunks(list(range(50)), 2)
    assert len(few) >= 2 * CHUNKS_PER_WORKER - 2 and max(map(len, few)) == 3
    assert chunks(list(range(5)), 4) == [[0], [1], [2], [3], [4]]


def test_dask_cluster_by_address_matches_serial(spec, serial_rows, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        s = run_study(spec, tmp_path, executor="dask", scheduler=cl.scheduler_address, progress=False)
    assert s.ran == 18 and s.executor == "dask"
    assert _diff(_rows(tmp_path), serial_rows) == []


def test_dask_default_local_cluster_matches_serial_and_resumes(spec, serial_rows, tmp_path):
    pytest.importorskip("dask.distributed")
    run_study(spec, tmp_path, executor="serial", limit=7, progress=False)  # a study half done by another executor
    s = run_study(spec, tmp_path, executor="dask", workers=2, progress=False)
    assert (s.ran, s.skipped) == (11, 7)
    assert _diff(_rows(tmp_path), serial_rows) == []


def test_scheduler_needs_dask(spec, tmp_path):
    from optcal.core.errors import InputError

    with pytest.raises(InputError, match="`scheduler` is for the dask `executor`"):
        run_study(spec, tmp_path, executor="processes", scheduler="tcp://127.0.0.1:1", progress=False)
