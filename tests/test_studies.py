"""Studies: spec validation, seeds, the store (resume, changed spec, failed trials, export), metrics
against hand computation and against the Cramér-Rao bound, reports, and the traditional calibration."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from optcal import solvers
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.solvers.base import Solver
from optcal.studies import spec as S
from optcal.studies.execute import run_study
from optcal.studies.metrics import Group, groups
from optcal.studies.report import write_report
from optcal.studies.spec import tomllib  # tomllib, or tomli on Python 3.10
from optcal.studies.store import TIMING, Store
from optcal.studies.trial import infield_data, run_trial, stream, trace_on_grid, trials, truth_of

BASE = """
name = "t"
runs = 3
seed = 11
models = ["nonlinear12"]
schemes = ["24"]
tilt_deg = 1.0
budget = 300
[navigation]
enabled = false
"""


def spec_of(extra: str = "", solvers_toml: str = '[[solvers]]\nname = "scipy-lm"\n', base: str = BASE):
    """A spec from BASE (its [navigation] table kept last) with top-level keys or tables added."""
    top, nav = base.split("[navigation]")
    text = top + textwrap.dedent(extra) + "[navigation]" + nav + solvers_toml
    return S.parse(tomllib.loads(text), "test.toml")


def _strip(rows):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


# -- spec validation --------------------------------------------------------------------------

def test_a_run_count_that_would_exhaust_memory_is_refused_in_one_line():
    from optcal.core.errors import InputError

    with pytest.raises(InputError, match="key 'runs' must be above 0 and at most 10000, got 100000000"):
        S.parse(tomllib.loads('runs = 100000000\n[[solvers]]\nname = "scipy-lm"\n'), "x.toml")


@pytest.mark.parametrize("name", ["compare", "bsas2020", "nafsa2015", "traditional", "ci"])
def test_shipped_specs_validate(name):
    sp = S.load(name)
    assert sp.runs >= 1 and sp.solvers
    if name == "compare":
        labels = {c.label for c in sp.solvers}
        assert sp.runs >= 50 and set(sp.schemes) == {"24", "36"} and set(sp.models) == {"nonlinear12", "seed15"}
        assert {"scipy-lm", "staged:scipy-lm", "cmaes", "staged:cmaes", "bsas", "pso"} <= labels
        assert sp.noise_ug == 10.0
        # nevergrad's three run under 2,000 evaluations (their own Python per candidate; docs/performance.md)
        ng = {c.label: c.budget for c in sp.solvers if c.label.startswith("ng:")}
        assert ng == {n: {"max_evals": 2000} for n in ("ng:NGOpt", "ng:TwoPointsDE", "ng:OnePlusOne")}
        assert all(c.budget == {"max_evals": 20000} for c in sp.solvers if not c.label.startswith("ng:"))


BAD = [
    ("frobnicate = 1\n", "", "'frobnicate'"),
    ("", '[[solvers]]\nname = "no-such-solver"\n', "no-such-solver"),
    ("", '[[solvers]]\nname = "scipy-lm"\noptions = {bogus = 1}\n', "solvers[0].options"),
    ("", '[[solvers]]\nname = "scipy-lm"\noptions = {ftol = "abc"}\n', "ftol"),
    ("", '[[solvers]]\nname = "scipy-lm"\ncolour = "red"\n', "solvers[0].colour"),
    ("", '[[solvers]]\nname = "scipy-lm"\ngrid = {ftol = 1e-9}\n', "solvers[0].grid.ftol"),
    ("", '[[solvers]]\nname = "scipy-lm"\nreference_error_arcsec = 10\n', "reference_error_arcsec"),
    ("", '[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "scipy-lm"\n', "appears twice"),
    ("", '[[solvers]]\nname = "all"\noptions = {ftol = 1e-9}\n', "solvers[0].options"),
    ("[verification]\nschemes = '36'\n", "", "verification.schemes"),
    ("[executor]\nkind = 'mpi'\n", "", "executor.kind"),
    ("[navigation]\nhours = 'five'\n", "", "navigation.hours"),
    ("[navigation]\nattitude_deg = [20, 30]\n", "", "navigation.attitude_deg"),
    ("[navigation]\nlatitude_deg = 90\n", "", "navigation.latitude_deg"),
    ("[navigation]\nhours = 1000\n", "", "navigation.hours"),
    ("[executor]\nkind = 'processes'\nscheduler = 'tcp://h:8786'\n", "", "executor.scheduler"),
]


@pytest.mark.parametrize("extra,solvers_toml,key", BAD)
def test_bad_spec_is_refused_naming_the_key(extra, solvers_toml, key):
    text = BASE.replace("[navigation]\nenabled = false\n", "") + extra
    if "[navigation]" not in extra:
        text += "[navigation]\nenabled = false\n"
    with pytest.raises(InputError) as exc:
        S.parse(tomllib.loads(text + (solvers_toml or '[[solvers]]\nname = "scipy-lm"\n')), "bad.toml")
    msg = str(exc.value)
    assert key in msg and "\n" not in msg and msg.startswith("spec bad.toml:")


@pytest.mark.parametrize("line,key", [
    ('runs = "many"', "'runs'"), ("runs = 0", "'runs'"), ('schemes = ["25"]', "schemes[0]"),
    ('models = ["linear99"]', "'models'"), ("noise_ug = -1", "noise_ug"), ('truth = "random"', "'truth'"),
    ('presets = "factory"', "'presets'"), ("budget = 2.5", "'budget'"), ("seed = true", "'seed'"),
    ('schemes = ["24", 24]', "schemes[1]"), ('models = ["seed15", "scale+bias+misalignment6+quadratic"]', "models[1]"),
    ("truth = {K_x = 1.0, K_q = 2.0}", "truth.K_q"),
])
def test_bad_top_level_values(line, key):
    lines = [x for x in BASE.splitlines() if not x.startswith(line.split(" ")[0] + " ")]
    with pytest.raises(InputError, match=key.replace("[", r"\[").replace("]", r"\]")):
        S.parse(tomllib.loads("\n".join([line] + lines) + '\n[[solvers]]\nname = "scipy-lm"\n'), "bad.toml")


@pytest.mark.parametrize("line,message", [
    # the whole line for a few cases: the key as the file writes it, what it takes, and what it got (TOML terms)
    ('runs = "many"', "spec bad.toml: key 'runs' must be an integer number of Monte-Carlo runs, got string 'many'"),
    ("seed = true", "spec bad.toml: key 'seed' must be a non-negative integer, got boolean true"),
    ("noise_ug = nan", "spec bad.toml: key 'noise_ug' must be positive, got nan"),
    # exact presets leave the bound with presets undefined (it divided by zero in the report)
    ("presets_error_scale = 0", "spec bad.toml: key 'presets_error_scale' must be positive, got 0"),
    ("truth = {K_x = 'a'}", "spec bad.toml: key 'truth.K_x' must be a number, got string 'a'"),
    ("budget = {max_time = 'x'}", "spec bad.toml: key 'budget.max_time' must be a number of seconds, got string 'x'"),
    ("budget = {max_evals = 10, tries = 3}",
     "spec bad.toml: unknown key 'budget.tries'; known keys here: max_evals, max_time, target"),
    ("solvers = [1]", "spec bad.toml: key 'solvers[0]' must be a table, got integer 1"),
    ("solvers = [{name = 'scipy-trf', reference = true, reference_error_arcsec = [10, -1]}]",
     "spec bad.toml: key 'solvers[0].reference_error_arcsec[1]' must be non-negative, got -1"),
    ("navigation = {hours = 0}", "spec bad.toml: key 'navigation.hours' must be above 0 and at most 720, got 0"),
    ("navigation = {latitude_deg = -90}", "spec bad.toml: key 'navigation.latitude_deg' must be within [-89, 89], "
     "got -90"),
    ("executor = {kind = 'mpi'}", "spec bad.toml: key 'executor.kind' must be 'serial', 'processes' or 'dask', got "
     "string 'mpi'"),
    ("models = ['nonlinear12', 'nonlinear12']", "spec bad.toml: key 'models[1]' lists 'nonlinear12' a second time; "
     "give each once"),
])
def test_bad_spec_message_in_full(line, message):
    key = line.split(" ")[0]
    nav = ("[navigation]", "enabled = false")  # the line's inline table takes its place
    lines = [x for x in BASE.splitlines() if not x.startswith(key + " ") and x not in nav]
    text = "\n".join([line] + lines) + ("" if key == "solvers" else '\n[[solvers]]\nname = "scipy-lm"\n')
    with pytest.raises(InputError) as exc:
        S.parse(tomllib.loads(text), "bad.toml")
    assert str(exc.value) == message


def test_bad_spec_from_the_command_line_is_one_line_exit_2(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(BASE + '[[solvers]]\nname = "bsas"\noptions = {m = -3}\n')
    code = main(["study", "run", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "solvers[0].options" in err and "m=-3" in err
    assert not (tmp_path / "o").exists()  # refused before anything ran
    assert main(["study", "run", str(tmp_path / "missing.toml")]) == 2
    assert main(["study", "report", str(tmp_path)]) == 2
    assert "holds no study" in capsys.readouterr().err


def test_all_expands_to_every_available_solver_and_its_staged_version():
    sp = spec_of(solvers_toml='[[solvers]]\nname = "all"\nexclude = ["pso"]\n')
    labels = [c.label for c in sp.solvers]
    from optcal.solvers import registry

    avail = [n for n in registry.names() if n != "pso" and registry.solver_class(n)[0].is_available()]
    assert labels == avail + [f"staged:{n}" for n in avail]
    assert "pso" not in labels and all(c.budget == {"max_evals": 300} for c in sp.solvers)


def test_option_grid_and_reference_levels_expand():
    sp = spec_of(solvers_toml=textwrap.dedent("""
        [[solvers]]
        name = "scipy-lm"
        grid = {ftol = [1e-10, 1e-12], xtol = [1e-10, 1e-12]}
        [[solvers]]
        name = "scipy-trf"
        label = "turntable"
        reference = true
        reference_error_arcsec = [0, 60]
    """))
    labels = [c.label for c in sp.solvers]
    assert labels[:4] == ["scipy-lm[ftol=1e-10,xtol=1e-10]", "scipy-lm[ftol=1e-10,xtol=1e-12]",
                          "scipy-lm[ftol=1e-12,xtol=1e-10]", "scipy-lm[ftol=1e-12,xtol=1e-12]"]
    assert labels[4:] == ["turntable@0as", "turntable@60as"]
    assert sp.solvers[5].reference and sp.solvers[5].reference_error_arcsec == 60.0
    assert len(trials(sp)) == 6 * 3


def test_spec_hash_tracks_what_determines_results():
    a = spec_of()
    assert a.hash == spec_of().hash
    assert a.hash != spec_of("noise_ug = 20.0\n").hash
    assert a.hash != a.with_runs(4).hash
    assert a.quick().runs == a.quick_runs and a.quick().hash != a.hash
    assert a.hash == spec_of("[executor]\nkind = 'dask'\nworkers = 7\n").hash  # the executor is not part of it


# -- seeds ------------------------------------------------------------------------------------

def test_every_solver_of_a_run_sees_the_same_data_and_runs_differ():
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "pso"\n')
    ts = trials(sp)
    by = {(t.run, t.config.label): t for t in ts}
    d0 = infield_data(by[0, "scipy-lm"], truth_of(by[0, "scipy-lm"])).data.N
    assert np.array_equal(d0, infield_data(by[0, "pso"], truth_of(by[0, "pso"])).data.N)
    d1 = infield_data(by[1, "pso"], truth_of(by[1, "pso"])).data.N
    assert not np.allclose(d0, d1)
    # solver streams depend on the label, not on the position in the spec
    assert stream(11, 5, 0, 1, 2, 3).random() == stream(11, 5, 0, 1, 2, 3).random()


def test_a_solver_result_does_not_depend_on_the_other_solvers_in_the_spec():
    one = spec_of(solvers_toml='[[solvers]]\nname = "pso"\noptions = {n_particles = 10, iterations = 20}\n')
    two = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "pso"\n'
                               'options = {n_particles = 10, iterations = 20}\n')
    t1 = [t for t in trials(one) if t.run == 1][0]
    t2 = [t for t in trials(two) if t.run == 1 and t.config.label == "pso"][0]
    r1, r2 = run_trial(t1), run_trial(t2)
    assert r1["x_est"] == r2["x_est"] and r1["fun"] == r2["fun"] and r1["nfev"] == 210


def test_drawn_truth_differs_per_run_and_is_reproducible():
    sp = spec_of(base=BASE.replace("tilt_deg", 'truth = "draw"\ntilt_deg'))
    ts = trials(sp)
    a, b = truth_of(ts[0]), truth_of(ts[1])
    assert (ts[0].run, ts[1].run) == (0, 1)
    assert a != b and a == truth_of(ts[0])
    assert abs(a["K_x"] - 1) < 5e-3 and len(a) == 12


# -- store: resume, changed spec, failures, export --------------------------------------------

def test_resume_skips_finished_trials_and_a_changed_spec_is_refused(tmp_path):
    sp = spec_of()
    s1 = run_study(sp, tmp_path, limit=2, progress=False)
    assert (s1.ran, s1.skipped, s1.total) == (2, 0, 3)
    s2 = run_study(sp, tmp_path, progress=False)
    assert (s2.ran, s2.skipped) == (1, 2)
    s3 = run_study(sp, tmp_path, progress=False)
    assert s3.ran == 0
    with Store.open_existing(tmp_path) as st:
        assert st.count() == (3, 0)
        assert len(json.loads(st.meta("sessions"))) == 3
    with pytest.raises(InputError, match="different spec"):
        run_study(spec_of("noise_ug = 5.0\n"), tmp_path, progress=False)
    other = tmp_path.parent / (tmp_path.name + "_other")
    run_study(sp, other, progress=False)
    with Store.open_existing(tmp_path) as a, Store.open_existing(other) as b:
        assert _strip(a.rows()) == _strip(b.rows())


class _Raises(Solver):
    name = "raises"

    def _solve(self, problem, x0, rng, callback):
        raise RuntimeError("deliberate failure in the test solver")


class _NoCost(Solver):
    name = "nocost"

    def _solve(self, problem, x0, rng, callback):
        return {"message": "evaluated nothing"}


def test_a_failing_or_nan_solver_is_stored_as_failed_and_the_study_goes_on(tmp_path, monkeypatch):
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "scipy-trf"\n'
                              '[[solvers]]\nname = "pso"\n')
    real = solvers.get
    fake = {"scipy-trf": _Raises, "pso": _NoCost}
    monkeypatch.setattr(solvers, "get", lambda name, **o: fake[name]() if name in fake else real(name, **o))
    s = run_study(sp, tmp_path, progress=False)
    assert (s.ran, s.failed) == (9, 6)
    with Store.open_existing(tmp_path) as st:
        rows = {r["trial_id"]: r for r in st.rows()}
    assert rows["nonlinear12|24|scipy-lm|0"]["status"] == "ok"
    assert rows["nonlinear12|24|scipy-trf|0"]["status"] == "failed"
    assert "RuntimeError: deliberate failure in the test solver" in rows["nonlinear12|24|scipy-trf|0"]["message"]
    assert "non-finite" in rows["nonlinear12|24|pso|2"]["message"]
    report = write_report(tmp_path).read_text()
    assert "Failures:" in report and "deliberate failure" in report
    g = {x.solver: x for x in groups(list(rows.values()))}
    assert g["scipy-trf"].success_rate == 0 and g["scipy-lm"].success_rate == 1 and g["pso"].n_failed == 3


def test_export_csv_and_parquet(tmp_path):
    run_study(spec_of(), tmp_path, progress=False)
    import csv

    rows = list(csv.DictReader(open(tmp_path / "trials.csv")))
    assert len(rows) == 3 and rows[0]["trial_id"] == "nonlinear12|24|scipy-lm|0"
    assert len(json.loads(rows[0]["x_est"])) == 12
    pq = pytest.importorskip("pyarrow.parquet")
    t = pq.read_table(tmp_path / "trials.parquet")
    assert t.num_rows == 3 and t.column("fun").to_pylist() == [float(r["fun"]) for r in rows]


# -- metrics -----------------------------------------------------------------------------------

def test_group_metrics_match_a_hand_computation():
    errs = np.array([[1e-6, -2e-6], [3e-6, 0.0], [-1e-6, 2e-6]])
    rows = [{"model": "m", "scheme": "24", "solver": "s", "solver_name": "s", "run": i, "reference": 0,
             "reference_error_arcsec": 0.0, "status": "ok", "message": "", "success": 1, "converged": int(i < 2),
             "names": ["a", "b"], "err": list(e), "err_proj": list(e), "crlb": [2e-6, 1e-6], "observable": [1, 1],
             "fun": f, "runtime_s": t, "nfev": 10, "null_dirs": [], "null_err": []}
            for i, (e, f, t) in enumerate(zip(errs, [1.0, 3.0, 2.0], [0.1, 0.3, 0.2]))]
    g = groups(rows)[0]
    p = g.parameters()
    assert p[0]["mean"] == pytest.approx(1e-6) and p[0]["rmse"] == pytest.approx(np.sqrt(11 / 3) * 1e-6)
    assert p[0]["sd"] == pytest.approx(np.std(errs[:, 0], ddof=1))
    assert p[1]["ratio"] == pytest.approx(np.sqrt(8 / 3))
    assert g.accuracy == pytest.approx(np.sqrt((11 / 12 + 8 / 3) / 2))
    s = g.summary()
    assert (s["cost_min"], s["cost_median"], s["cost_max"], s["runtime_median_s"]) == (1.0, 2.0, 3.0, 0.2)
    assert g.success_rate == pytest.approx(2 / 3)


def test_trace_on_grid_is_the_best_so_far_at_ten_points_per_decade():
    tr = [(1, 5.0, 0.0), (3, 4.0, 0.0), (12, 1.0, 0.0), (100, 0.5, 0.0)]
    g = trace_on_grid(tr)
    assert g[0] == [1, 5.0] and [3, 4.0] in g and [10, 4.0] in g and [13, 1.0] in g and g[-1] == [100, 0.5]
    assert len(g) == 18 and [x[0] for x in g[:8]] == [1, 2, 3, 4, 5, 6, 8, 10]
    # an improvement between two grid points is still the curve's last value
    # (the grid's last point is at or past the last improvement)
    g = trace_on_grid([(1, 5.0, 0.0), (90, 0.25, 0.0)])
    assert g[-1] == [100, 0.25] and [79, 5.0] in g


def test_least_squares_reaches_the_cramer_rao_bound_and_seed15_reports_its_unobservable_directions(tmp_path):
    """scipy-lm is an efficient estimator here: RMSE/CRLB ≈ 1 over 40 runs on both models; seed15's
    three unobservable directions carry the presets' error (20 µrad SD), not the data's."""
    sp = spec_of(base=BASE.replace("runs = 3", "runs = 40").replace('["nonlinear12"]', '["nonlinear12", "seed15"]'))
    run_study(sp, tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        gs = {g.model: g for g in groups(st.rows())}
    for m in ("nonlinear12", "seed15"):
        assert 0.85 < gs[m].accuracy < 1.15, (m, gs[m].accuracy)
        assert gs[m].success_rate >= 0.95
        s = gs[m].summary()
        assert s["ver_truth_ug"] < s["ver_mean_ug"] < 1.3 * s["ver_truth_ug"]
    assert gs["nonlinear12"].unobservable() == []
    un = gs["seed15"].unobservable()
    assert len(un) == 3 and all(0.5 * 20e-6 < u["rms"] < 2 * 20e-6 for u in un)
    obs = {p["name"]: p["observable"] for p in gs["seed15"].parameters()}
    assert not obs["S_xz"] and obs["K_x"] and obs["K2_z"]


def test_traditional_calibration_beats_in_field_with_a_perfect_turntable_and_loses_with_a_poor_one(tmp_path):
    sp = spec_of(base=BASE.replace("runs = 3", "runs = 12"), solvers_toml=textwrap.dedent("""
        [[solvers]]
        name = "scipy-lm"
        [[solvers]]
        name = "scipy-lm"
        label = "turntable"
        reference = true
        reference_error_arcsec = [0, 300]
    """))
    run_study(sp, tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        g = {x.solver: x for x in groups(st.rows())}
    assert g["turntable@0as"].accuracy < 0.8 * g["scipy-lm"].accuracy
    assert g["turntable@300as"].accuracy > 3 * g["scipy-lm"].accuracy
    report = write_report(tmp_path).read_text()
    assert "Traditional against in-field" in report
    assert "once the orientation error exceeds about" in report
    assert (tmp_path / "figures" / "traditional_accuracy_nonlinear12_24.png").stat().st_size > 10_000


def test_report_writes_tables_figures_and_summary(tmp_path):
    sp = spec_of(solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "staged:scipy-lm"\n',
                 base=BASE.replace("enabled = false", "enabled = true"))
    run_study(sp, tmp_path, progress=False)
    out = write_report(tmp_path)
    text = out.read_text()
    assert "| solver | at noise floor | RMSE/CRLB |" in text and "`staged:scipy-lm`" in text
    figs = ["cost_nonlinear12_24", "convergence_nonlinear12_24", "crlb_nonlinear12_24",
            "verification_nonlinear12_24", "accuracy_runtime"]
    for f in figs:
        p = tmp_path / "figures" / f"{f}.png"
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
        assert f"figures/{f}.png" in text
    summary = json.loads((tmp_path / "summary.json").read_text())["records"]
    assert [s["solver"] for s in summary] == ["scipy-lm", "staged:scipy-lm"]
    # every solver's evaluation rate from the study's own records, as a column of the report; the cost's unit
    assert "| runtime s median [95 % CI] | evaluations (median) | evaluations/s |" in text
    assert "final cost (g²) median [min, max]" in text and "runtime s median [p10, p90]" not in text
    from optcal.studies.store import Store

    with Store.open_existing(tmp_path) as st:
        rows = [r for r in st.rows() if r["solver"] == "scipy-lm" and r["status"] == "ok"]
    rate = sum(r["nfev"] for r in rows) / sum(r["runtime_s"] for r in rows)
    assert summary[0]["evals_per_s"] == pytest.approx(rate, rel=1e-9) and rate > 0
    assert f"| {rate:,.0f} |" in text
    assert (tmp_path / "parameters.md").read_text().count("| K_x |") == 2
    try:
        import optcal.core.nav  # noqa: F401
    except ImportError:
        return
    assert "Static navigation" in text and (tmp_path / "figures" / "navigation_nonlinear12_24.png").is_file()
    assert all(s["nav_max_nmi"] > s["nav_mean_nmi"] > 0 for s in summary)


def test_group_without_rows_is_harmless():
    g = Group("m", "24", "s", "s", False, 0.0)
    assert g.n == 0 and g.success_rate == 0


def test_bsas2020_report_has_the_papers_navigation_table_and_figure(tmp_path):
    """Issue 6 / 2020 paper Table 6 and Figure 11: the 5-hour static position error of the truth
    calibration (zero), the traditional calibration (10″ turntable) and each solver, in one table and one
    figure of the bsas2020 report. 5 runs of the shipped spec (its --quick variant)."""
    pytest.importorskip("optcal.core.nav")
    sp = S.load("bsas2020").quick()
    run_study(sp, tmp_path, progress=False)
    text = write_report(tmp_path).read_text()
    section = text.split("### Static navigation (5 h): seed15, 24 positions")[1].split("###")[0]
    rows = {r.split("|")[1].strip(): [float(v) for v in r.split("|")[2:4]]
            for r in section.splitlines() if r.startswith("| ") and "nmi" not in r}
    assert rows["truth calibration"] == [0.0, 0.0]
    trad = rows["traditional (scipy-lm, 10″)"]
    for label in ("BSAS", "BAS"):
        mx, mean = rows[label]
        # in-field recalibration beats the 10″ turntable in navigation, as in the paper's Table 6
        assert 0.05 < mx < trad[0] and 0 < mean < mx
    assert "figures/navigation_seed15_24.png" in section
    png = tmp_path / "figures" / "navigation_seed15_24.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_navigation_attitude_reaches_the_metric():
    """[navigation] attitude_deg: a scale-factor error is invisible to a level static run (only the
    horizontal biases act there) and visible to a tilted one (docs/navigation.md)."""
    from optcal.core.model import get_model
    from optcal.studies.trial import _navigation

    m = get_model("nonlinear12")
    x_true = m.default_vector(1.0)
    x_est = x_true.copy()
    x_est[m.index("K_x")] += 1e-4
    base = {"enabled": True, "hours": 5.0, "latitude_deg": 45.0}
    level = _navigation(m, x_true, x_est, {**base, "attitude_deg": [0.0, 0.0, 0.0]})
    tilted = _navigation(m, x_true, x_est, {**base, "attitude_deg": [20.0, 30.0, 0.0]})
    assert level[0] < 1e-9 and tilted[0] > 0.01
    assert S.load("bsas2020").navigation["attitude_deg"] == [0.0, 0.0, 0.0]  # the paper's level test


def test_the_bound_with_presets_is_the_floor_the_staged_procedure_does_not_beat(tmp_path):
    """Staged least squares scores below the data-only bound (0.78 on nonlinear12) because it keeps the
    last stages near the presets; against the bound of data and presets together it is above 1, as every
    method must be. Plain least squares ignores the presets: ≈ 1 against the data bound, ≈ 2 against
    the joint one. 40 runs, seed 11 (measured: 0.78 / 1.19 staged, 1.02 / 2.12 plain on nonlinear12;
    0.82 / 1.10 and 1.02 / 1.95 on seed15)."""
    sp = spec_of(base=BASE.replace("runs = 3", "runs = 40").replace("budget = 300", "budget = 3000")
                 .replace('["nonlinear12"]', '["nonlinear12", "seed15"]'),
                 solvers_toml='[[solvers]]\nname = "scipy-lm"\n[[solvers]]\nname = "staged:scipy-lm"\n')
    run_study(sp, tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        gs = {(g.model, g.solver): g for g in groups(st.rows())}
    for m in ("nonlinear12", "seed15"):
        plain, staged = gs[m, "scipy-lm"], gs[m, "staged:scipy-lm"]
        assert 0.85 < plain.accuracy < 1.15 and plain.accuracy_presets > 1.6
        assert staged.accuracy < 0.9 and 1.0 < staged.accuracy_presets < 1.4
        # no parameter beats the joint bound by more than Monte-Carlo scatter (40 runs: ±11 % at 1σ)
        assert min(p["ratio_presets"] for g in (plain, staged) for p in g.parameters()) > 0.75
    text = write_report(tmp_path).read_text()
    assert "RMSE/CRLB with presets" in text and "the accuracy came from the presets" in text


def test_crlb_with_presets_tends_to_the_data_bound_and_to_the_presets():
    """Vague presets leave the data's bound; exact presets pin every parameter."""
    from optcal.core.problem import CalibrationProblem
    from optcal.studies.trial import crlb_with_presets, projected_crlb

    t = trials(spec_of())[0]
    sim = infield_data(t, truth_of(t))
    p = CalibrationProblem("nonlinear12", sim.data, noise_g=10e-6)
    x = sim.truth_vector(p.model)
    data_only = projected_crlb(p, x, 10e-6)[0]
    np.testing.assert_allclose(crlb_with_presets(p, x, 10e-6, np.full(x.size, 1e3)), data_only, rtol=1e-6)
    tiny = np.full(x.size, 1e-12)
    np.testing.assert_allclose(crlb_with_presets(p, x, 10e-6, tiny), tiny, rtol=1e-6)


def test_a_store_from_before_a_new_column_still_reports(tmp_path):
    """Stores written before `crlb_presets` existed gain the column (empty) when opened."""
    import sqlite3

    from optcal.studies.store import COLUMNS

    sp = spec_of()
    run_study(sp, tmp_path, progress=False, limit=2)
    con = sqlite3.connect(tmp_path / "study.sqlite")
    keep = ", ".join(c for c in COLUMNS if c != "crlb_presets")
    con.executescript(f"CREATE TABLE old AS SELECT {keep} FROM trials; DROP TABLE trials; "
                      "ALTER TABLE old RENAME TO trials;")
    con.close()
    s = run_study(sp, tmp_path, progress=False)  # resumes into the old store
    assert s.skipped == 2 and s.ran == s.total - 2
    with Store.open_existing(tmp_path) as st:
        rows = st.rows()
    assert sum(r["crlb_presets"] is None for r in rows) == 2
    assert "RMSE/CRLB" in write_report(tmp_path).read_text()


def test_a_scoring_error_fails_its_trial_not_the_study(tmp_path, monkeypatch):
    """Anything after the solve (metrics, verification, navigation) that raises is a failed trial."""
    import optcal.studies.trial as T

    def broken(*a, **k):
        raise ValueError("navigation blew up")

    monkeypatch.setattr(T, "_navigation", broken)
    s = run_study(spec_of(), tmp_path, progress=False)
    with Store.open_existing(tmp_path) as st:
        rows = st.rows()
    assert s.ran == s.total == len(rows) == s.failed
    assert all(r["status"] == "failed" and "scoring failed: ValueError: navigation blew up" in r["message"]
               for r in rows)


def test_a_second_writer_is_refused_while_a_study_runs(tmp_path):
    import fcntl

    sp = spec_of()
    run_study(sp, tmp_path, progress=False, limit=1)
    with open(tmp_path / ".lock", "w") as fh:  # what a running `optcal study run` holds
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(InputError, match="another `optcal study run` is writing"):
            run_study(sp, tmp_path, progress=False)
    assert run_study(sp, tmp_path, progress=False).skipped == 1  # free again once the first has ended


def test_summary_json_is_strict_json(tmp_path):
    sp = spec_of('presets = "none"\n')
    run_study(sp, tmp_path, progress=False)
    write_report(tmp_path)
    text = (tmp_path / "summary.json").read_text()
    assert "NaN" not in text and json.loads(text)["records"][0]["accuracy_presets"] is None


def test_progress_is_printed_as_lines_when_the_output_is_not_a_terminal(monkeypatch):
    """A CI log is not a terminal: tqdm would print nothing there, so the study prints progress lines (trials
    done, rate, time left) instead; off when progress is False."""
    import io

    from optcal.studies import execute

    out = io.StringIO()
    bar = execute._progress(40, None, "demo", out)
    assert isinstance(bar, execute.ProgressLines)
    clock = iter(range(0, 1000, 3))  # every update 3 s later
    monkeypatch.setattr(execute.time, "perf_counter", lambda: float(next(clock)))
    bar.t0 = bar.last_t = 0.0
    for _ in range(40):
        bar.update(1)
    lines = out.getvalue().splitlines()
    # every 10 % (4 trials: the 4th update reads the clock at 9 s) and at the end; the rate and the time left
    assert len(lines) == 10
    assert lines[0] == "study demo: 4/40 trials (10 %), 0.4 trials/s, 9 s elapsed, about 1.4 min left"
    assert lines[-1].startswith("study demo: 40/40 trials (100 %)")
    assert not isinstance(execute._progress(40, False, "demo", io.StringIO()), execute.ProgressLines)
