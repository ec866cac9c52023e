"""The README is a front door (issue #30, item 4): at most ~150 lines, install and the first calibration before
anything else, and its headline table generated from the headline study's summary.json by
docs/scripts/headline_table.py, never edited by hand (the marker's hash is the table's)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from conftest import doc_script

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _script():
    return doc_script("headline_table")


def test_the_readme_is_short_and_starts_with_what_a_user_needs():
    """At most 150 lines besides the generated table (a row per configuration of the headline study)."""
    text = README.read_text()
    lines = text.splitlines()
    match, table = _script().readme_table(text)
    assert len(lines) - table.count("\n") <= 150, len(lines)
    heads = [ln for ln in lines if ln.startswith("## ")]
    assert heads[:3] == ["## Install", "## Your first calibration", "## Your first study"], heads
    first = text.index("## Your first calibration")
    assert "optcal calibrate" in text[first:first + 600] and "make test" in text[:first]


def test_the_headline_table_is_the_generated_one():
    hl = _script()
    found = hl.readme_table(README.read_text())
    assert found is not None, "README.md has no headline table markers"
    match, table = found
    assert hashlib.sha256(table.encode()).hexdigest() == match["sha"], "the headline table was edited by hand"
    assert "study compare" in match["meta"] and table.count("\n") >= 30  # every configuration, a row each


def test_the_table_from_a_summary():
    """Rows in the order of the mean bound-with-presets score; cells accuracy / with presets (share reaching
    the floor); runtime and evaluations per second the median over the cells."""
    hl = _script()

    def rec(solver, model, scheme, acc, pre, ok, rt, ev):
        return {"solver": solver, "model": model, "scheme": scheme, "accuracy": acc, "accuracy_presets": pre,
                "success_rate": ok, "runtime_median_s": rt, "evals_per_s": ev}

    summary = {"study": {"name": "x", "spec_hash": "abc", "trials": 400, "runs": 50},
               "records": [rec("b", "seed15", "24", 2.0, 3.0, 0.5, 0.1, 1000.0),
                           rec("b", "nonlinear12", "24", 1.0, 1.5, 1.0, 0.3, 3000.0),
                           rec("a", "nonlinear12", "24", 0.9, 1.2, 1.0, 0.001, 8000.0),
                           rec("a", "seed15", "24", None, 1.3, 0.98, 0.003, 9000.0)]}
    table = hl.table(summary).splitlines()
    assert table[0] == "| solver | nonlinear12, 24 | seed15, 24 | runtime s | evaluations/s |"
    assert table[2] == "| `a` | 0.90 / 1.20 (100 %) | – / 1.30 (98 %) | 0.002 | 8,500 |"
    assert table[3] == "| `b` | 1.00 / 1.50 (100 %) | 2.00 / 3.00 (50 %) | 0.2 | 2,000 |"
    block = hl.block(summary)
    assert block.startswith("<!-- headline table: study x, spec abc, 400 trials, 50 runs; sha256 ")
    m, t = hl.readme_table("before\n" + block + "\nafter")
    assert hashlib.sha256(t.encode()).hexdigest() == m["sha"]
