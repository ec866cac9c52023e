"""The study report's speed-ups change nothing (issue #22): each group's statistics computed once
(optcal.studies.report.FinishedGroup) are those of a plain group, and the figures drawn by worker processes
(optcal.studies.figures.Renderer) are the files drawn in the report's own process, pixel for pixel, with the same
report.md, parameters.md and summary.json."""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from optcal.studies import figures
from optcal.studies.execute import run_study
from optcal.studies.metrics import groups
from optcal.studies.report import FinishedGroup, finished_groups, write_report
from optcal.studies.spec import load
from optcal.studies.store import Store


@pytest.fixture(scope="module")
def ci_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ci")
    run_study(load("ci"), folder, progress=False)
    return folder


def _close(a, b) -> bool:
    """Equal, NaN equal to NaN, through dicts, lists and arrays."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b, equal_nan=True)
    if isinstance(a, float):
        return (np.isnan(a) and np.isnan(b)) or a == b
    return a == b


def test_a_finished_group_gives_the_numbers_of_a_plain_group_and_copies_of_them(ci_study):
    with Store.open_existing(ci_study) as st:
        rows = st.rows()
    plain, done = groups(rows), finished_groups(rows)
    assert [g.solver for g in plain] == [g.solver for g in done] and len(done) == 5
    for p, f in zip(plain, done):
        assert isinstance(f, FinishedGroup)
        for name in ("summary", "parameters", "unobservable", "convergence"):
            assert _close(getattr(p, name)(), getattr(f, name)()), name
        for name in ("ok", "success_rate", "failures", "accuracy", "accuracy_presets", "n", "n_failed"):
            assert _close(getattr(p, name), getattr(f, name)), name
        assert np.isfinite(f.accuracy) and np.isfinite(f.accuracy_presets)
        # what one caller does with its copy, no other caller sees
        f.summary()["accuracy"] = -1.0
        f.parameters()[0]["ratio"] = -1.0
        assert f.summary()["accuracy"] == p.summary()["accuracy"]
        assert f.parameters()[0]["ratio"] == p.parameters()[0]["ratio"]


def _pixels(path: Path) -> np.ndarray:
    import matplotlib.image

    return matplotlib.image.imread(path)


def test_figures_drawn_by_workers_are_the_files_drawn_here(ci_study, tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    for d in (here, there):
        shutil.copytree(ci_study, d)
    write_report(here, workers=0)
    write_report(there, workers=2)
    wall = re.compile(r"^- Wall time .*$", re.M)
    a, b = (here / "report.md").read_text(), (there / "report.md").read_text()
    assert wall.sub("", a) == wall.sub("", b) and a.count("![") >= 10
    assert (here / "parameters.md").read_bytes() == (there / "parameters.md").read_bytes()
    ja, jb = (json.loads((d / "summary.json").read_text()) for d in (here, there))
    assert ja["study"].pop("report_s") > 0 and jb["study"].pop("report_s") > 0
    assert ja == jb
    names = sorted(p.name for p in (here / "figures").glob("*.png"))
    assert names == sorted(p.name for p in (there / "figures").glob("*.png")) and len(names) >= 10
    for n in names:
        assert np.array_equal(_pixels(here / "figures" / n), _pixels(there / "figures" / n)), n


def _dies_in_a_worker(path: Path) -> Path:
    """A figure whose worker process dies (out of memory, killed); drawn in the report's process it works."""
    if multiprocessing.parent_process() is not None:
        os._exit(3)
    Path(path).write_text("drawn here")
    return path


def _writes(text: str, path: Path) -> Path:
    Path(path).write_text(text)
    return path


def test_a_figure_whose_worker_dies_is_drawn_here_and_the_others_still_are(tmp_path):
    with figures.Renderer(1) as render:
        first = render.draw(_writes, tmp_path / "a.txt", "drawn by a worker")
        dead = render.draw(_dies_in_a_worker, tmp_path / "b.txt")
        after = render.draw(_writes, tmp_path / "c.txt", "drawn after")
        assert (first, dead, after) == (tmp_path / "a.txt", tmp_path / "b.txt", tmp_path / "c.txt")
        render.finish()
    assert (tmp_path / "b.txt").read_text() == "drawn here"
    assert (tmp_path / "c.txt").read_text() == "drawn after"
    assert (tmp_path / "a.txt").read_text() == "drawn by a worker"


def test_a_figure_that_fails_in_a_worker_fails_the_report(tmp_path):
    with pytest.raises(TypeError), figures.Renderer(1) as render:
        render.draw(_writes, tmp_path / "a.txt")  # no text: TypeError in the worker
        render.finish()


def test_workers_only_for_a_study_large_enough_to_repay_them(monkeypatch):
    monkeypatch.setattr(figures, "usable_cpus", lambda: 2)
    assert figures.figure_workers(figures.PARALLEL_MIN_GROUPS - 1) == 0
    assert figures.figure_workers(164) == 2
    monkeypatch.setattr(figures, "usable_cpus", lambda: 1)
    assert figures.figure_workers(164) == 0
    monkeypatch.setattr(figures, "usable_cpus", lambda: 64)
    assert figures.figure_workers(164) == figures.MAX_WORKERS
