"""The Python API of studies: ``optcal.study(spec)`` runs a study and returns its results as pandas tables
(docs/api.md, "optcal.study").

It is ``optcal study run`` without the command line: the same trials, seeds and store (a study folder holds
the same ``study.sqlite`` whichever started it, so a study begun here resumes from the command and back), and
it returns what the command leaves in files: one row per trial and one row per solver × model × scheme.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from optcal.core.errors import InputError
from optcal.studies.execute import RunSummary, run_study
from optcal.studies.metrics import groups
from optcal.studies.spec import Spec, load
from optcal.studies.store import Store


@dataclass
class StudyResult:
    """A study's results.

    ``trials``: one row per trial, the store's columns (docs/studies.md): the scalars as numbers or text
    (``accuracy`` is the trial's RMS over parameters of |error| / CRLB; ``fun`` its final cost, g² for the
    accelerometer and a χ² of whitened residuals, no unit, for the gyroscope; ``runtime_s`` its solver time
    in s), the per-parameter and anytime records as lists. ``summary``: one row per
    model × scheme × solver configuration, the numbers of the report's tables (``success_rate``, ``accuracy``
    and ``accuracy_presets`` as RMSE/CRLB, ``ver_mean_ug`` in µg, ``runtime_median_s`` in s, ...). ``run``:
    what this call ran (trials run, skipped as already stored, failed; wall time). ``folder``: the study
    folder, or None when the study ran in a temporary one."""

    spec: Spec
    trials: object  # pandas.DataFrame
    summary: object  # pandas.DataFrame
    run: RunSummary
    folder: Path | None


def study(spec: str | Path | Spec, *, out: str | Path | None = None, runs: int | None = None, quick: bool = False,
          executor: str | None = None, workers: int | None = None, progress: bool = False,
          report: bool = False) -> StudyResult:
    """Run the study ``spec`` (a shipped spec's name such as ``"ci"``, a path to a TOML spec, or a loaded
    :class:`optcal.studies.spec.Spec`) and return its results.

    ``out``: the study folder (trials already stored there are not run again, so calling again with the same
    folder only reads the results); without it the study runs in a temporary folder that is removed after
    reading. ``runs`` overrides the number of Monte-Carlo runs, ``quick`` takes the spec's quick variant;
    ``executor`` (serial, processes, dask) and ``workers`` override the spec's; ``progress`` shows the progress
    bar; ``report`` writes report.md, summary.json and the figures into ``out`` as ``optcal study report``
    does.
    """
    import pandas as pd

    if isinstance(spec, str | Path):
        sp = load(spec)
    elif isinstance(spec, Spec):
        sp = spec
    else:
        raise InputError(f"`spec` must be a spec's name, a path to a spec file or a Spec, not {type(spec).__name__}")
    if quick:
        sp = sp.quick()
    if runs is not None:
        if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
            raise InputError(f"`runs` must be a whole number of at least 1, got {runs!r}")
        sp = sp.with_runs(runs)
    if report and out is None:
        raise InputError("`report` writes into the study folder: give `out` as well")
    with tempfile.TemporaryDirectory(prefix="optcal-study-") as tmp:
        folder = Path(out) if out is not None else Path(tmp)
        summary = run_study(sp, folder, executor=executor, workers=workers, progress=progress)
        with Store.open_existing(folder) as st:
            rows = st.rows()
        if report:
            from optcal.studies.report import write_report

            write_report(folder)
    order = [c.label for c in sp.solvers]
    trials = pd.DataFrame(rows)
    table = pd.DataFrame([g.summary() for g in groups(rows, order)])
    return StudyResult(sp, trials, table, summary, folder if out is not None else None)
