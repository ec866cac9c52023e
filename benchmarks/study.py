"""``track_*``: a study's results per commit. The study is the CI spec (optcal/studies/specs/ci.toml) unless the
environment names another: ``OPTCAL_ASV_SPEC`` (a shipped spec's name or a path to a user's spec file) and
``OPTCAL_ASV_RUNS`` (its number of Monte-Carlo runs; the spec's own by default). The spec runs once per
commit (``setup_cache``, serial, fixed seeds), so every track below reads the same results.

Each value is deterministic for a given commit (the study's seeds are fixed): asv's comparison then flags
any change past its factor, which for an accuracy is a regression of the solver, not Monte-Carlo noise.
"""

from __future__ import annotations

import os
import tempfile

from benchmarks._paths import module

load = module("optcal.studies.spec").load

SPEC = os.environ.get("OPTCAL_ASV_SPEC", "ci")
RUNS = os.environ.get("OPTCAL_ASV_RUNS")


def _spec():
    spec = load(SPEC)
    return spec.with_runs(int(RUNS)) if RUNS else spec


_S = _spec()
CELLS = [f"{m}|{s}|{c.label}" for m in _S.models for s in _S.schemes for c in _S.solvers if not c.reference]
SOLVERS = [c.label for c in _S.solvers if not c.reference]


def setup_cache():
    """Run the study once (this commit's code) and keep each cell's summary and each solver's ECDF areas."""
    anytime = module("optcal.studies.anytime")
    run_study = module("optcal.studies.execute").run_study
    groups = module("optcal.studies.metrics").groups
    Store = module("optcal.studies.store").Store

    with tempfile.TemporaryDirectory() as folder:
        run_study(_spec(), folder, executor="serial", progress=False)
        with Store.open_existing(folder) as st:
            rows = st.rows()
    out = {"cells": {}, "anytime": {}}
    for g in groups(rows):
        s = g.summary()
        out["cells"][f"{g.model}|{g.scheme}|{g.solver}"] = {"accuracy": s["accuracy"],
                                                           "success_rate": s["success_rate"]}
    for rec in anytime.collect(rows).table(_S.seed, resamples=10):
        out["anytime"][rec["solver"]] = {"cost": rec["cost_area"], "accuracy": rec["accuracy_area"]}
    return out


setup_cache.timeout = 1800


def track_accuracy(cache, cell):
    """RMSE/CRLB of one solver on one model × scheme over the study's runs (1 = efficient; lower is better)."""
    return cache["cells"][cell]["accuracy"]


track_accuracy.params = CELLS
track_accuracy.param_names = ["model|scheme|solver"]
track_accuracy.unit = "RMSE/CRLB"


def track_success_rate(cache, cell):
    """Share of runs whose final cost reached the noise floor (the χ² 99.9 % quantile); higher is better."""
    return cache["cells"][cell]["success_rate"]


track_success_rate.params = CELLS
track_success_rate.param_names = ["model|scheme|solver"]
track_success_rate.unit = "fraction of runs"


def track_anytime_area(cache, solver, kind):
    """The area under the solver's runtime ECDF (cost or accuracy targets, optcal.studies.anytime), 0 to 1; higher is
    better."""
    return cache["anytime"][solver][kind]


track_anytime_area.params = (SOLVERS, ["cost", "accuracy"])
track_anytime_area.param_names = ["solver", "targets"]
track_anytime_area.unit = "ECDF area"


class TimeStudy:
    """The wall time of the study's quick variant (quick_runs runs), serial."""

    timeout = 1800
    number = 1
    repeat = 3
    warmup_time = 0

    def setup_cache(self):
        module("optcal.core.warmup").warm()  # the kernel compiles once per commit here, not inside the timing

    def time_study_quick(self, _):
        run_study = module("optcal.studies.execute").run_study
        with tempfile.TemporaryDirectory() as folder:
            run_study(_spec().quick(), folder, executor="serial", progress=False)
