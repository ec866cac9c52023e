"""optcal.study, the studies' Python API (optcal/studies/api.py, docs/api.md): the doc's study block runs as written
and prints what the doc shows; the tables hold what the store and the report hold; bad arguments are one-line
InputErrors."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest
from golden import check as golden

import optcal
from optcal.core.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "api.md"


def _block():
    text = DOC.read_text()
    code = re.findall(r"^```python study\n(.*?)^```", text, re.S | re.M)
    assert len(code) == 1
    shown = text.split(code[0], 1)[1].split("```\n\n```\n", 1)[1].split("```", 1)[0]
    return code[0], shown


@pytest.fixture(scope="module")
def session():
    code, shown = _block()
    ns: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/api.md study block", "exec"), ns)
    return ns, out.getvalue(), shown


def test_the_doc_block_prints_what_the_doc_shows(session):
    _, printed, shown = session
    assert printed == shown


def test_the_tables_hold_the_trials_and_the_report_numbers(session):
    ns, _, _ = session
    res = ns["res"]
    assert res.folder is None and res.run.ran == 20 and res.run.skipped == 0
    t = res.trials
    assert len(t) == 20 and set(t["run"]) == {0, 1, 2, 3} and (t["status"] == "ok").all()
    assert {"trial_id", "solver", "accuracy", "fun", "nfev", "runtime_s", "err_proj", "crlb"} <= set(t.columns)
    # the trials' numbers, value for value, as before the layers' move (tests/golden.py)
    cols = ["solver", "run", "accuracy", "fun", "nfev", "err_proj", "crlb"]
    golden("study:ci:4", t.sort_values(["solver", "run"])[cols].to_dict("list"))
    s = res.summary
    assert list(s["solver"]) == [c.label for c in res.spec.solvers]
    # the summary's numbers are the report's groups over the same trials
    from optcal.studies.metrics import groups

    g = {x.solver: x for x in groups(t.to_dict("records"))}
    for _, r in s.iterrows():
        assert r["accuracy"] == pytest.approx(g[r["solver"]].accuracy, rel=1e-12)
        assert r["success_rate"] == g[r["solver"]].success_rate


def test_a_folder_keeps_the_study_and_a_second_call_only_reads(tmp_path):
    a = optcal.study("ci", runs=2, out=tmp_path, report=True)
    b = optcal.study("ci", runs=2, out=tmp_path)
    assert a.run.ran == 10 and b.run.ran == 0 and b.run.skipped == 10 and a.folder == tmp_path
    assert (tmp_path / "report.md").is_file() and (tmp_path / "summary.json").is_file()
    cols = ["trial_id", "accuracy", "fun"]
    assert a.trials[cols].equals(b.trials[cols])


@pytest.mark.parametrize("kwargs, message", [
    (dict(spec=3), "`spec` must be a spec's name, a path to a spec file or a Spec, not int"),
    (dict(spec="ci", runs=0), "`runs` must be a whole number of at least 1, got 0"),
    (dict(spec="ci", runs=2.5), "`runs` must be a whole number of at least 1, got 2.5"),
    (dict(spec="ci", report=True), "`report` writes into the study folder: give `out` as well"),
    (dict(spec="no-such-spec"), "spec no-such-spec: no such file (shipped specs: "),
    (dict(spec="ci", executor="threads"), "unknown executor 'threads'"),
])
def test_bad_arguments_are_one_line_input_errors(kwargs, message):
    spec = kwargs.pop("spec")
    with pytest.raises(InputError) as e:
        optcal.study(spec, **kwargs)
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_simulate_draws_a_truth_as_the_command_does():
    """optcal.simulate(model, None, rng) draws the truth from rng first, as `optcal simulate` without --truth."""
    import numpy as np

    from optcal.core.model import get_model
    from optcal.core.presets import draw_truth

    sim = optcal.simulate("nonlinear12", None, 11)
    assert sim.truth == pytest.approx(draw_truth(get_model("nonlinear12"), np.random.default_rng(11)))
    again = optcal.simulate("nonlinear12", None, np.random.default_rng(11))
    assert np.array_equal(sim.data.N, again.data.N)
    for truth, rng, message in [([1.0], 1, "`truth` must be a mapping"), (None, "x", "`rng` must be a numpy")]:
        with pytest.raises(InputError, match=message):
            optcal.simulate("nonlinear12", truth, rng)
