"""``optcal study export DIR --format ioh -o OUT``: a study's runs in the IOHprofiler format, read back with
iohinspector (a real consumer of the format): one problem per model × scheme, one algorithm per solver
configuration, one run per trial, each run's final best-so-far value the store's final cost."""

from __future__ import annotations

import json

import pytest
from test_studies import BASE, spec_of

from optcal.app.cli import main
from optcal.studies.execute import run_study
from optcal.studies.store import Store

iohinspector = pytest.importorskip("iohinspector")
pl = pytest.importorskip("polars")

SOLVERS = """
[[solvers]]
name = "scipy-lm"
[[solvers]]
name = "pso"
options = {n_particles = 10, iterations = 20}
[[solvers]]
name = "staged:scipy-lm"
[[solvers]]
name = "scipy-lm"
label = "turntable"
reference = true
"""


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    sp = spec_of(base=BASE.replace('["nonlinear12"]', '["nonlinear12", "seed15"]'), solvers_toml=SOLVERS)
    run_study(sp, folder, progress=False)
    with Store.open_existing(folder) as st:
        rows = st.rows()
    return folder, rows


def test_export_is_read_by_iohinspector_with_every_run_and_its_final_value(study, tmp_path, capsys):
    folder, rows = study
    out = tmp_path / "ioh"
    assert main(["study", "export", str(folder), "--format", "ioh", "-o", str(out)]) == 0
    assert "exported 18 runs of 3 algorithm(s) on 2 problem(s)" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["pso", "scipy-lm", "staged-scipy-lm"]
    assert (out / "staged-scipy-lm" / "data_f2_seed15_24" / "IOHprofiler_f2_DIM15.dat").is_file()

    dm = iohinspector.DataManager()
    dm.add_folder(str(out))
    ov = dm.overview
    functions = {1: ("nonlinear12", "24"), 2: ("seed15", "24")}
    assert {(f.id, f.name) for f in dm.functions} == {(1, "nonlinear12_24"), (2, "seed15_24")}
    assert sorted(set(ov["algorithm_name"])) == ["pso", "scipy-lm", "staged:scipy-lm"]  # no turntable
    assert set(ov["dimension"]) == {12, 15}
    stored = {(r["solver"], r["model"], r["scheme"], r["run"]): r for r in rows if not r["reference"]}
    # the number of runs per (algorithm, function): every trial of the study
    n = ov.group_by(["algorithm_name", "function_id"]).len()
    assert len(n) == 6 and set(n["len"]) == {3}
    # each run's final best-so-far value (meta file and data file) is the store's final cost
    data = dm.load(monotonic=True, include_meta_data=True)
    last = {d: float(y) for d, y in data.group_by("data_id").agg(pl.col("raw_y").last()).iter_rows()}
    first = data.group_by("data_id").agg(pl.col("evaluations").first())
    assert set(first["evaluations"]) == {1}  # every run starts at evaluation 1
    seen = set()
    for rec in ov.iter_rows(named=True):
        model, scheme = functions[rec["function_id"]]
        r = stored[rec["algorithm_name"], model, scheme, rec["instance"] - 1]
        seen.add(r["trial_id"])
        assert rec["best_y"] == r["fun"] and last[rec["data_id"]] == r["fun"]
        assert rec["evals"] == r["nfev"]
    assert seen == {r["trial_id"] for r in stored.values()}
    # improvements only, in order
    d = data.sort(["data_id", "evaluations"])
    for _, g in d.group_by("data_id"):
        assert g["raw_y"].is_sorted(descending=True) and g["evaluations"].is_sorted()


def test_export_refuses_a_non_empty_folder_and_writes_nothing_on_failure(study, tmp_path, capsys, monkeypatch):
    folder, _ = study
    out = tmp_path / "taken"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["study", "export", str(folder), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not an empty folder" in err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    # an empty folder is fine
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["study", "export", str(folder), "-o", str(empty)]) == 0
    assert len(list(empty.glob("*/IOHprofiler_f*.json"))) == 6
    # a failure half-way leaves neither the folder nor a temporary one behind
    import optcal.studies.export as E

    def broken(rows, spec, spec_hash, dest):
        (dest / "partial").mkdir()
        raise OSError("disk full")

    monkeypatch.setattr(E, "write_ioh", broken)
    target = tmp_path / "new" / "ioh"
    with pytest.raises(OSError, match="disk full"):
        E.export(folder, target)
    assert not target.exists() and not (tmp_path / "new").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "taken"]
    # not a study; an unknown format
    assert main(["study", "export", str(tmp_path / "taken"), "-o", str(tmp_path / "x")]) == 2
    assert "holds no study" in capsys.readouterr().err and not (tmp_path / "x").exists()
    with pytest.raises(SystemExit):
        main(["study", "export", str(folder), "--format", "csv", "-o", str(tmp_path / "y")])


def test_export_of_an_old_store_uses_its_trace(study, tmp_path):
    """A store written before anytime records exports its trace column (the same grid)."""
    import shutil
    import sqlite3

    from optcal.studies.export import export
    from optcal.studies.store import COLUMNS

    folder, rows = study
    old = tmp_path / "old"
    shutil.copytree(folder, old)
    con = sqlite3.connect(old / "study.sqlite")
    keep = ", ".join(c for c in COLUMNS if c not in ("f_opt", "anytime"))
    con.executescript(f"CREATE TABLE o AS SELECT {keep} FROM trials; DROP TABLE trials; "
                      "ALTER TABLE o RENAME TO trials;")
    con.close()
    a, b = export(folder, tmp_path / "new"), export(old, tmp_path / "from_old")
    assert a["runs"] == b["runs"] == 18
    for p in (tmp_path / "new").rglob("*.dat"):
        assert p.read_text() == (tmp_path / "from_old" / p.relative_to(tmp_path / "new")).read_text()
    meta = json.loads(next((tmp_path / "from_old" / "pso").glob("*.json")).read_text())
    assert meta["maximization"] is False and meta["attributes"] == ["evaluations", "raw_y"]


def test_github_action_benchmark_files_carry_every_solver_with_its_interval(study, tmp_path, capsys):
    """customSmallerIsBetter / customBiggerIsBetter: a list of {name, unit, value, range, extra}, the values the
    baseline check measures (optcal.app.study_ci.measure), each with its 95 % bootstrap interval over the runs."""
    from optcal.app.study_ci import measure

    folder, rows = study
    out = tmp_path / "gab"
    assert main(["study", "export", str(folder), "--format", "github-action-benchmark", "-o", str(out)]) == 0
    small = json.loads((out / "smaller_is_better.json").read_text())
    big = json.loads((out / "bigger_is_better.json").read_text())
    with Store.open_existing(folder) as st:
        seed = st.spec["seed"]
    m = measure(rows, seed)
    # the in-field and turntable configurations of both cells, three smaller-is-better metrics each
    assert len(m) == 8 and len(small) == 3 * 8
    assert all(set(e) >= {"name", "unit", "value", "extra"} for e in small + big)
    e = next(e for e in small if e["name"] == "nonlinear12|24|scipy-lm: RMSE/CRLB")
    v, lo, hi = m["nonlinear12|24|scipy-lm"]["accuracy"]
    assert e["value"] == v and e["unit"] == "RMSE/CRLB" and e["range"] == f"95 % CI [{lo:.4g}, {hi:.4g}]"
    assert lo < v < hi
    # bigger is better: the noise-floor share of every configuration, the ECDF areas of the in-field ones
    assert sum(e["name"].endswith("share of runs at the noise floor") for e in big) == 8
    assert {e["name"] for e in big if "ECDF area (cost" in e["name"]} == {
        f"{s}: anytime ECDF area (cost targets)" for s in ("scipy-lm", "pso", "staged:scipy-lm")}


def test_junit_export_checks_a_baseline_and_fails_on_a_regression(study, tmp_path, capsys):
    import xml.etree.ElementTree as ET

    from optcal.app.study_ci import measure, propose

    folder, rows = study
    with Store.open_existing(folder) as st:
        seed = st.spec["seed"]
    m = measure(rows, seed)
    good = tmp_path / "base.toml"
    good.write_text(propose(m, "t"))
    out = tmp_path / "ok"
    assert main(["study", "export", str(folder), "--format", "junit", "--baseline", str(good), "-o", str(out)]) == 0
    suite = ET.parse(out / "tolerances.xml").getroot().find("testsuite")
    assert suite.get("tests") == str(4 * 8) and suite.get("failures") == "0" and suite.get("skipped") == "8"
    # pso claimed far more accurate than it is: its accuracy fails, nothing else does
    bad = tmp_path / "bad.toml"
    text = propose(m, "t")
    block = '[solvers."nonlinear12|24|pso"]\naccuracy = '
    i = text.index(block) + len(block)
    bad.write_text(text[:i] + "0.01" + text[text.index("\n", i):])
    out = tmp_path / "bad"
    assert main(["study", "export", str(folder), "--format", "junit", "--baseline", str(bad), "-o", str(out)]) == 1
    assert "REGRESSION: nonlinear12|24|pso: accuracy" in capsys.readouterr().out
    suite = ET.parse(out / "tolerances.xml").getroot().find("testsuite")
    failed = [(c.get("classname"), c.get("name")) for c in suite.iter("testcase") if c.find("failure") is not None]
    assert failed == [("optcal.study.t.nonlinear12|24|pso", "accuracy")]
    # a spec other than the CI one needs its baseline; --baseline belongs to junit alone
    assert main(["study", "export", str(folder), "--format", "junit", "-o", str(tmp_path / "x")]) == 2
    assert "give its --baseline file" in capsys.readouterr().err
    assert main(["study", "export", str(folder), "--baseline", str(good), "-o", str(tmp_path / "y")]) == 2
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
