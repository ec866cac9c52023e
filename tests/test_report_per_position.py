"""Schemes of different sizes in a study's report (issues #21, #22): planned schemes named with their size
("plan:D15 (15 positions)"), and the accuracy per position, RMSE·√N/σ, with the Cramér-Rao bound per
position, checked against the trials by hand and against the geometry: the 24- and 36-position rotation
schemes have the same bound per position (docs/planning.md), a planned scheme a smaller one."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from optcal.studies.execute import run_study
from optcal.studies.report import PER_POSITION_HEADER, write_report
from optcal.studies.report_sections import per_position, positions_of, scheme_phrase, schemes_phrase
from optcal.studies.spec import parse, tomllib
from optcal.studies.store import Store

SPEC = """
name = "sizes"
runs = 6
seed = 21
models = ["nonlinear12"]
schemes = ["24", "36", "plan:D15"]
tilt_deg = 1.0
noise_ug = 10.0
presets = "manufacturer"
budget = 2000
[navigation]
enabled = false
[[solvers]]
name = "scipy-lm"
[[solvers]]
name = "pso"
"""


def test_scheme_sizes_and_names():
    assert [positions_of(s) for s in ("6", "24", "36", "plan:D15", "plan:A18:seed15", "random:30")] == \
        [6, 24, 36, 15, 18, 30]
    assert positions_of("nothing/here.csv") is None and positions_of("plan:Dx") is None
    assert scheme_phrase("24") == "24 positions"
    assert scheme_phrase("plan:D15") == "plan:D15 (15 positions)"
    assert scheme_phrase("plan:A18:seed15") == "plan:A18:seed15 (18 positions)"
    assert schemes_phrase(["24", "36"]) == "24, 36 positions"
    assert schemes_phrase(["24", "plan:D15"]) == "24 positions, plan:D15 (15 positions)"


def test_a_scheme_file_has_as_many_positions_as_rows(tmp_path):
    from optcal.core.plan.schemefile import scheme_csv
    from optcal.core.schemes import rotation_groups

    path = tmp_path / "mine.csv"
    path.write_text(scheme_csv(rotation_groups(60.0)))
    assert positions_of(str(path)) == len(rotation_groups(60.0))
    assert scheme_phrase(str(path)) == f"{path} ({len(rotation_groups(60.0))} positions)"


def test_per_position_by_hand():
    # RMS of (3, 4) µg-sized errors = √12.5; × √16 / 10 µg
    assert per_position([3e-6, 4e-6], 16, 10e-6) == pytest.approx(math.sqrt(12.5) * 4 / 10)
    assert per_position([3e-6, None, float("nan")], 4, 1e-6) == pytest.approx(6.0)
    assert math.isnan(per_position([3e-6], None, 1e-6)) and math.isnan(per_position([], 4, 1e-6))


def _sizes_study(folder):
    run_study(parse(tomllib.loads(SPEC), "sizes.toml"), folder, progress=False)
    write_report(folder)


@pytest.fixture(scope="module")
def sizes(computed_once):
    folder = computed_once("sizes", _sizes_study)  # once for every xdist worker; the tests only read it
    with Store.open_existing(folder) as st:
        rows = st.rows()
    return folder, (folder / "report.md").read_text(), json.loads((folder / "summary.json").read_text()), rows


def _by_hand(rows, scheme, solver, key, n):
    """RMS over parameters of the per-parameter RMS over runs of ``key`` (err_proj: the RMSE of the
    observable part; crlb: the bound), × √n / 10 µg."""
    E = np.array([r[key] for r in rows if r["scheme"] == scheme and r["solver"] == solver and r["status"] == "ok"])
    assert len(E) == 6
    return float(np.sqrt(np.mean(np.mean(E**2, axis=0))) * math.sqrt(n) / 10e-6)


def test_planned_schemes_are_named_with_their_size(sizes):
    _, text, _, _ = sizes
    assert "## nonlinear12, plan:D15 (15 positions)\n" in text
    assert "## nonlinear12, 24 positions\n" in text and "## nonlinear12, 36 positions\n" in text
    assert "plan:D15 positions" not in text
    assert "schemes 24 positions, 36 positions, plan:D15 (15 positions);" in text
    assert "- Verification: 36 positions, 10 µg noise." in text


def test_the_accuracy_per_position_column_is_rmse_times_root_n_over_sigma(sizes):
    _, text, doc, rows = sizes
    assert "*RMSE·√N/σ (per position)*" in text  # defined in How to read
    recs = {(r["scheme"], r["solver"]): r for r in doc["records"]}
    for scheme, n in (("24", 24), ("36", 36), ("plan:D15", 15)):
        cell = text.split(f"## nonlinear12, {scheme_phrase(scheme)}\n")[1].split("\n## ")[0]
        header = next(line for line in cell.splitlines() if line.startswith("| solver |"))
        col = header.split(" | ").index(PER_POSITION_HEADER)
        for solver in ("scipy-lm", "pso"):
            want = _by_hand(rows, scheme, solver, "err_proj", n)
            rec = recs[scheme, solver]
            assert rec["positions"] == n and rec["accuracy_per_position"] == pytest.approx(want, rel=1e-12)
            row = next(line for line in cell.splitlines() if line.startswith(f"| `{solver}` |"))
            assert row.split(" | ")[col] == format(want, ".3g")
        bound = _by_hand(rows, scheme, "scipy-lm", "crlb", n)
        assert recs[scheme, "scipy-lm"]["crlb_per_position"] == pytest.approx(bound, rel=1e-12)
        assert f"(CRLB·√N/σ, N = {n}, σ = 10 µg): {bound:.3g}." in cell
    # scipy-lm attains the bound on every scheme, so its RMSE per position follows the bound per position
    for scheme in ("24", "36", "plan:D15"):
        r = recs[scheme, "scipy-lm"]
        assert 0.6 < r["accuracy_per_position"] / r["crlb_per_position"] < 1.4


def test_the_bound_per_position_is_the_geometry_s(sizes):
    """The 24- and 36-position rotation schemes carry the same information per position (their bounds are
    in the ratio √(36/24) for every parameter), so their bounds per position agree although their bounds
    differ by 22 %; the planned 15 positions, D-optimal, differ from both."""
    _, _, doc, _ = sizes
    b = {r["scheme"]: r["crlb_per_position"] for r in doc["records"] if r["solver"] == "scipy-lm"}
    assert b["24"] == pytest.approx(b["36"], rel=0.01)
    assert abs(b["plan:D15"] / b["24"] - 1) > 0.03


def test_a_gyroscope_study_has_no_accuracy_per_position(tmp_path):
    """The gyroscope's problem has no noise per reading in the spec's units (noise_ug is the accelerometer's
    on each rest), so its report leaves the column, its definition and the bound per position out."""
    sp = parse({**tomllib.loads((Path(__file__).parents[1] / "optcal/studies/specs/gyro_compare.toml").read_text()),
                "runs": 2, "models": ["gyro9"], "schemes": ["24"], "solvers": [{"name": "scipy-lm"}],
                "executor": {"kind": "serial"}}, "gyro_compare.toml")
    run_study(sp, tmp_path, progress=False)
    text = write_report(tmp_path).read_text()
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert "## gyro9, 24 positions" in text and "| `scipy-lm` |" in text
    assert "RMSE·√N/σ" not in text and "bound per position" not in text
    rec = doc["records"][0]
    assert rec["positions"] == 24 and rec["accuracy_per_position"] is None and rec["crlb_per_position"] is None
