"""The gyroscope's problem in the study runner (issue #23): the spec's ``problem`` field and ``[gyroscope]``
table, the simulated recording a trial draws (rotation profiles, white rate noise, bias random walk), the
trials' rows through ``optcal.study``, least squares at the Cramér-Rao bound over 40 runs, and a solver
registered in the test that runs on the shipped spec with no change anywhere."""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

import optcal
from optcal import solvers
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.gyro import GyroProblem, draw_truth, get_gyro_model, simulate_imu
from optcal.core.gyro.simulate import PROFILES, RAMP
from optcal.solvers.base import Solver
from optcal.studies import spec as S
from optcal.studies.metrics import groups
from optcal.studies.trial import gyro_data, gyro_truth, run_trial, trials, world

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SOLVER = [{"name": "scipy-lm"}]


def gyro_spec(**kw) -> S.Spec:
    """A gyroscope spec from keys (``gyroscope`` a table), scipy-lm alone unless ``solvers`` is given."""
    return S.parse({"problem": "gyroscope", "solvers": SOLVER, **kw}, "g.toml")


def shipped(**kw) -> S.Spec:
    """The shipped gyro_compare spec with some keys replaced (fewer runs, solvers, models, schemes)."""
    obj = tomllib.loads(S.resolve_path("gyro_compare").read_text())
    obj.update(kw)
    obj["executor"] = {"kind": "serial"}
    return S.parse(obj, "gyro_compare.toml")


# -- the spec ------------------------------------------------------------------------------------------

def test_an_accelerometer_spec_keeps_its_hash():
    """The problem field is not in an accelerometer spec's canonical form: its hash is the one it had before the
    field existed (the values below are those of the commit before it), so its study folders still resume."""
    a = S.parse({"runs": 3, "seed": 7, "solvers": SOLVER})
    assert a.problem == "accelerometer" and "problem" not in a.canonical() and "gyroscope" not in a.canonical()
    assert a.hash == "06f16c94233068e1"
    b = S.parse({"runs": 3, "seed": 7, "models": ["seed15"], "noise_ug": 20.0,
                 "solvers": SOLVER + [{"name": "bsas", "budget": 500}]})
    assert b.hash == "26fcfe132ef9d43c"
    assert S.parse({"problem": "accelerometer", "runs": 3, "seed": 7, "solvers": SOLVER}).hash == a.hash


def test_a_gyroscope_spec_takes_the_gyroscopes_defaults():
    sp = gyro_spec()
    assert sp.problem == "gyroscope" and sp.models == ("gyro12",) and sp.truth == "draw" and sp.presets == "none"
    assert sp.gyroscope == {"rate_hz": 100.0, "rest_s": 3.0, "motion_s": 2.0, "profile": "smooth",
                            "noise_rad_s_rthz": 1e-4, "bias_walk_rad_s2_rthz": 0.0, "scale": 1000.0}
    # no verification set, no navigation: the stored spec says so
    assert sp.verification["scheme"] == "none" and sp.navigation["enabled"] is False
    c = sp.canonical()
    assert c["problem"] == "gyroscope" and c["gyroscope"] == sp.gyroscope
    # every number of the recording is part of what determines the results
    assert gyro_spec(gyroscope={"bias_walk_rad_s2_rthz": 1e-6}).hash != sp.hash
    assert gyro_spec(gyroscope={"profile": "trapezoid"}).hash != sp.hash
    assert gyro_spec(noise_ug=20.0).hash != sp.hash


@pytest.mark.parametrize("keys,message", [
    ({"problem": "gyro"}, "key 'problem' must be \"accelerometer\" or \"gyroscope\", got string 'gyro'"),
    ({"problem": 2}, "key 'problem' must be \"accelerometer\" or \"gyroscope\", got integer 2"),
    ({"problem": "gyroscope", "models": ["gyro12", "nonlinear12"]},
     "key 'models[1]' is 'nonlinear12', not a gyroscope model; use gyro9, gyro12, gyro21"),
    ({"models": ["gyro12"]}, "key 'models': unknown model or term 'gyro12'"),
    ({"problem": "gyroscope", "truth": "paper"},
     "key 'truth' cannot be \"paper\" for the gyroscope (the papers calibrate accelerometers); use truth = "
     "\"draw\" or a table of values"),
    ({"problem": "gyroscope", "presets": "manufacturer"},
     "key 'presets' cannot be \"manufacturer\" for the gyroscope: its search starts at the nominal scale and the "
     "rests' mean bias; leave presets out"),
    ({"problem": "gyroscope", "tilt_deg": 1.0},
     "key 'tilt_deg' is for the accelerometer's problem; a gyroscope study describes its recording in [gyroscope]"),
    ({"problem": "gyroscope", "navigation": {"hours": 1.0}}, "key 'navigation' is for the accelerometer's problem"),
    ({"gyroscope": {"rate_hz": 50.0}}, "key 'gyroscope' is for problem = \"gyroscope\""),
    ({"problem": "gyroscope", "gyroscope": {"profile": "jerky"}},
     "key 'gyroscope.profile' must be a rotation profile: 'smooth' or 'trapezoid', got string 'jerky'"),
    ({"problem": "gyroscope", "gyroscope": {"noise_rad_s_rthz": 0.0}},
     "key 'gyroscope.noise_rad_s_rthz' must be positive, got 0.0"),
    ({"problem": "gyroscope", "gyroscope": {"bias_walk_rad_s2_rthz": "4e-6"}},
     "key 'gyroscope.bias_walk_rad_s2_rthz' must be a number of rad/s²/√Hz (rad/s per √s), got string '4e-6'"),
    ({"problem": "gyroscope", "gyroscope": {"motion_s": 0.05}},
     "key 'gyroscope.motion_s' holds fewer than 10 samples at rate_hz; lengthen the motions"),
    ({"problem": "gyroscope", "gyroscope": {"noise": 1.0}}, "unknown key 'gyroscope.noise'; known keys here: "),
    ({"problem": "gyroscope", "models": ["gyro9"], "truth": {"K_x": 1000.0}},
     "key 'truth' lacks K_y of the sensor simulated for model gyro9"),
    ({"problem": "gyroscope", "solvers": [{"name": "scipy-lm", "reference": True}]},
     "key 'solvers[0].reference' is the accelerometer's turntable calibration; a gyroscope study has none"),
])
def test_bad_gyroscope_keys_are_one_line_naming_the_key(keys, message):
    with pytest.raises(InputError) as exc:
        S.parse({"solvers": SOLVER, **keys}, "bad.toml")
    text = str(exc.value)
    assert text.startswith(f"spec bad.toml: {message}") and "\n" not in text


def test_an_unknown_problem_from_the_command_line_is_one_line_exit_2(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text('problem = "magnetometer"\n[[solvers]]\nname = "scipy-lm"\n')
    assert main(["study", "run", str(p), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "key 'problem' must be \"accelerometer\" or \"gyroscope\"" in err
    assert not (tmp_path / "o").exists()


def test_the_shipped_spec_compares_the_headline_solvers_on_every_gyro_model_and_scheme():
    sp = S.load("gyro_compare")
    assert sp.problem == "gyroscope" and sp.runs == 10 and sp.models == ("gyro9", "gyro12", "gyro21")
    assert sp.schemes == ("24", "36") and sp.gyroscope["bias_walk_rad_s2_rthz"] > 0
    labels = {c.label for c in sp.solvers}
    assert {"scipy-lm", "scipy-trf", "casadi-ipopt", "nlopt-lbfgs", "nlopt-slsqp", "nlopt-bobyqa", "nlopt-neldermead",
            "nlopt-sbplx", "cmaes", "pso", "bsas", "bas", "nafsa"} <= labels
    assert all(c.budget == {"max_evals": 3000} for c in sp.solvers)


# -- the simulated recording ---------------------------------------------------------------------------

@pytest.mark.parametrize("profile", list(PROFILES))
def test_rotation_profiles_turn_the_whole_angle_and_the_integrator_follows_them(profile):
    tau = np.linspace(0.0, 1.0, 100_001)
    s, ds = PROFILES[profile](tau, 100_000)
    assert s[0] == pytest.approx(0.0, abs=1e-15) and s[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(s) >= 0) and ds[0] == pytest.approx(0.0, abs=1e-12)
    # ds/dτ is the derivative of s (trapezoid rule over the grid)
    assert np.max(np.abs(np.cumsum((ds[1:] + ds[:-1]) / 2 * np.diff(tau)) - s[1:])) < 1e-9
    peak = {"smooth": 2.0, "trapezoid": 1.0 / (1.0 - RAMP)}[profile]
    assert np.max(ds) == pytest.approx(peak, rel=1e-6)
    # a nearly noise-free recording: at the truth every motion's residual is the integrator's error alone
    rng = np.random.default_rng(4)
    model = get_gyro_model(True)
    x = draw_truth(model, rng, 1000.0)
    sim = simulate_imu(model, x, poses=24, noise_rate=1e-12, noise_acc_g=1e-12, profile=profile, rng=rng)
    p = GyroProblem(sim.data, g_sensitivity=True, scale=1000.0)
    assert np.max(p.motion_angles(p.from_sensor(x))) < 1e-9


def test_an_unknown_profile_is_refused_in_one_line():
    with pytest.raises(InputError, match="unknown rotation profile 'jerky'; use one of smooth, trapezoid"):
        simulate_imu(get_gyro_model(), np.r_[np.full(3, 1000.0), np.zeros(9)], profile="jerky",
                     rng=np.random.default_rng(0))


def test_a_trial_simulates_the_spec_noise_in_its_units():
    """White rate noise density × √rate per sample (rad/s), the accelerometer's noise_ug on a rest's mean."""
    sp = gyro_spec(noise_ug=100.0, gyroscope={"noise_rad_s_rthz": 2e-4, "rate_hz": 200.0, "rest_s": 4.0})
    t = trials(sp)[0]
    truth = gyro_truth(t)
    d = gyro_data(t, truth).data
    per_sample = np.sqrt(np.mean((d.rest_sd_W / truth[:3]) ** 2))
    assert per_sample == pytest.approx(2e-4 * np.sqrt(200.0), rel=0.02)
    acc_mean = np.sqrt(np.mean([d.F[a:b].std(axis=0, ddof=1) ** 2 / (b - a) for a, b in d.rests]))
    assert acc_mean == pytest.approx(100e-6, rel=0.05)
    assert d.n_rests == 24 and np.median(np.diff(d.t)) == pytest.approx(1 / 200.0)


def test_every_solver_of_a_run_sees_one_world_and_runs_differ():
    sp = gyro_spec(runs=2, models=["gyro9", "gyro21"], solvers=SOLVER + [{"name": "nlopt-bobyqa"}])
    ts = {(t.run, t.model, t.config.label): t for t in trials(sp)}
    a, b = world(ts[0, "gyro21", "scipy-lm"]), world(ts[0, "gyro21", "nlopt-bobyqa"])
    assert a is b and a.yard.model.name == "gyro21" and a.sigma == 1.0
    c = world(ts[1, "gyro21", "scipy-lm"])
    assert not np.array_equal(a.yard.data.W, c.yard.data.W) and a.truth != c.truth
    assert np.array_equal(gyro_truth(ts[1, "gyro21", "scipy-lm"]), gyro_truth(ts[1, "gyro21", "scipy-lm"]))
    # gyro9 takes the bias from the rests: its problem has no bias parameters, its simulated sensor has one
    g9 = world(ts[0, "gyro9", "scipy-lm"])
    assert len(g9.x_true) == 9 and {"b_x", "b_y", "b_z"} <= set(g9.truth)


# -- trials through the API ----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The shipped spec cut to 2 runs, 3 solvers, gyro9 and gyro21 on 24 poses, through optcal.study with its
    report."""
    sp = shipped(runs=2, models=["gyro9", "gyro21"], schemes=["24"],
                 solvers=[{"name": "scipy-lm"}, {"name": "nlopt-bobyqa"}, {"name": "bsas", "budget": 1500}])
    out = tmp_path_factory.mktemp("gyro_study")
    return optcal.study(sp, out=out, report=True), out


def test_a_tiny_gyro_study_runs_through_the_api_with_the_accelerometers_columns(tiny):
    res, _ = tiny
    t = res.trials
    assert res.run.ran == 12 and len(t) == 12 and (t["status"] == "ok").all()
    n = {"gyro9": 9, "gyro21": 21}
    # 24 rests, 23 motions: two residuals per motion, three per rest when the bias is fitted (gyro21)
    dof = {"gyro9": 2 * 23 - 9, "gyro21": 2 * 23 + 3 * 24 - 21}
    for _, r in t.iterrows():
        k = n[r["model"]]
        assert len(r["names"]) == len(r["x_true"]) == len(r["x_est"]) == len(r["crlb"]) == k
        assert np.allclose(r["err"], np.subtract(r["x_est"], r["x_true"]), rtol=0, atol=1e-12)
        assert np.all(np.isfinite(r["crlb"])) and min(r["crlb"]) > 0 and all(r["observable"])
        assert r["null_dirs"] == [] and r["err_proj"] == pytest.approx(r["err"], rel=1e-9, abs=1e-15)
        # the accuracy column: RMS over the parameters of |error| / CRLB
        acc = np.sqrt(np.mean((np.array(r["err_proj"]) / np.array(r["crlb"])) ** 2))
        assert r["accuracy"] == pytest.approx(acc, rel=1e-12)
        assert r["dof"] == dof[r["model"]] and r["chi2"] == pytest.approx(r["fun"], rel=1e-12)  # whitened: σ = 1
        # no verification set, no navigation, no presets
        assert r["ver_mean_ug"] is None and r["ver_err"] == [] and r["nav_max_nmi"] is None
        assert r["crlb_presets"] is None and r["f_opt"] > 0
    # scipy-lm and BOBYQA reach the same optimum in every run; the summary holds the groups' numbers
    lm, bob = (t[t["solver"] == s].sort_values(["model", "run"]) for s in ("scipy-lm", "nlopt-bobyqa"))
    assert np.allclose(lm["fun"].to_numpy(), bob["fun"].to_numpy(), rtol=1e-6)
    assert (lm["converged"] == 1).all() and (lm["nfev"] < 20).all()
    g = {(x.model, x.solver): x for x in groups(t.to_dict("records"))}
    for _, r in res.summary.iterrows():
        assert r["accuracy"] == pytest.approx(g[r["model"], r["solver"]].accuracy, rel=1e-12)
    assert set(res.summary["model"]) == {"gyro9", "gyro21"}


def test_the_report_and_exports_take_a_gyro_study_unchanged(tiny):
    import json

    from optcal.studies.export import export

    res, out = tiny
    text = (out / "report.md").read_text()
    assert "## gyro21, 24 positions" in text and "| G_zz |" in text and "0 failed" in text
    # the report speaks of the gyroscope's recording and cost, not of the accelerometer's verification set
    assert "the gyroscope's problem: 100 Hz, rests of 3 s, smooth turns of 2 s" in text
    assert "Verification and navigation: none" in text and "final χ² median [min, max]" in text
    assert "verification" not in text.lower().replace("verification and navigation: none", "")
    assert "g²" not in text and "Truth calibration" not in text
    params = (out / "parameters.md").read_text()
    assert "| K_x | counts/(rad/s) |" in params and "| G_zz | (rad/s)/g |" in params
    assert "| T_xy | rad |" in params and "| b_x | rad/s |" in params
    summary = json.loads((out / "summary.json").read_text())
    rec = {(r["model"], r["solver"]): r for r in summary["records"]}
    for _, r in res.summary.iterrows():
        assert rec[r["model"], r["solver"]]["accuracy"] == pytest.approx(r["accuracy"], rel=1e-12)
    assert (out / "trials.csv").read_text().count("\n") == 13
    ioh = export(out, out / "ioh", "ioh")
    assert ioh["runs"] == 12 and ioh["problems"] == 2 and ioh["algorithms"] == 3
    gab = export(out, out / "gab", "github-action-benchmark")
    assert gab["runs"] > 0


# -- accuracy over enough runs -------------------------------------------------------------------------

def _scipy_lm_groups(runs: int, models: list[str], walk: float) -> dict:
    sp = gyro_spec(runs=runs, seed=23, models=models, gyroscope={"bias_walk_rad_s2_rthz": walk})
    return {g.model: g for g in groups([run_trial(t) for t in trials(sp)])}


def test_least_squares_reaches_the_gyroscopes_cramer_rao_bound_over_40_runs():
    """scipy-lm on gyro12 and gyro21, 24 poses, white noise only (the bound's assumption), 40 runs, seed 23.

    RMSE/CRLB over 12 or 21 parameters of 40 runs each: an efficient estimator gives 1 with an SD of about
    0.03-0.05 (each parameter's ratio² is χ²₄₀/40); the tolerance ±0.15 is three to five of them. Each
    scale, misalignment and g-sensitivity ratio lies within the 0.01 % and 99.99 % quantiles of √(χ²₄₀/40),
    0.61 and 1.43 (rounded out to 0.6-1.45), and its mean error within 3.5 standard errors. The bias
    parameters are scored as the problem defines them, the rate bias beyond the rests' mean output, whose
    truth moves with the rests' noise: they are in the RMS but not held to the quantiles."""
    gs = _scipy_lm_groups(40, ["gyro12", "gyro21"], 0.0)
    for model, g in gs.items():
        assert g.n == 40 and g.success_rate == 1.0
        assert abs(g.accuracy - 1.0) < 0.15, (model, g.accuracy)
        ps = [p for p in g.parameters() if p["name"][0] in "KTG"]
        assert all(0.6 < p["ratio"] < 1.45 for p in ps), (model, [(p["name"], round(p["ratio"], 2)) for p in ps])
        Z = g.matrix("err") / g.matrix("crlb")
        keep = [i for i, n in enumerate(g.names) if n[0] in "KTG"]
        assert np.max(np.abs(Z[:, keep].mean(axis=0))) * np.sqrt(40) < 3.5
        # χ²/dof of the optimum: 1 for white noise
        assert abs(np.mean(g.column("chi2") / g.column("dof")) - 1.0) < 0.05


def test_bias_instability_costs_a_constant_bias_and_not_the_rests_bias():
    """With a bias random walk of 4e-6 rad/s²/√Hz (the shipped spec's), a bias fitted as one constant (gyro12)
    misses the walk: its bias ratios rise far above 1 (2.1-2.6 over these 30 runs of 24 poses, 0.9-1.2 without
    the walk), while gyro9, whose bias follows the rests, stays near its bound (1.03 with and without). The
    thresholds sit about four standard deviations of an RMS over 90 errors (0.08) from what was measured."""
    white, walk = _scipy_lm_groups(30, ["gyro9", "gyro12"], 0.0), _scipy_lm_groups(30, ["gyro9", "gyro12"], 4e-6)

    def bias_ratio(g):
        return float(np.sqrt(np.mean([p["ratio"] ** 2 for p in g.parameters() if p["name"][0] == "b"])))

    assert bias_ratio(white["gyro12"]) < 1.35 and bias_ratio(walk["gyro12"]) > 1.8
    assert walk["gyro9"].accuracy < 1.2 and walk["gyro12"].accuracy > walk["gyro9"].accuracy + 0.3


# -- a new solver needs no change ----------------------------------------------------------------------

class GaussNewton(Solver):
    """A throw-away solver for this test: plain Gauss-Newton steps on the problem's residuals and Jacobian."""

    name = "test-gauss-newton"
    family = "local"
    default_budget = 200

    def _solve(self, problem, x0, rng, callback):
        x = np.asarray(x0, float)
        for it in range(1, 51):
            step = np.linalg.lstsq(problem.jacobian(x), -problem.residuals(x), rcond=None)[0]
            x = x + step
            callback(it)
            if np.linalg.norm(step) <= 1e-12 * (1.0 + np.linalg.norm(x)):
                break
        problem.cost(x)
        return {"nit": it, "message": "step below 1e-12"}


def test_a_solver_registered_here_runs_on_the_shipped_gyro_spec_unchanged(monkeypatch):
    monkeypatch.setitem(solvers.registry._SOLVERS, GaussNewton.name, (GaussNewton, {}))
    sp = shipped(runs=2, models=["gyro12", "gyro21"], schemes=["24"],
                 solvers=[{"name": GaussNewton.name}, {"name": "scipy-lm"}])
    res = optcal.study(replace(sp, executor={**sp.executor, "kind": "serial"}))
    t = res.trials
    assert len(t) == 8 and (t["status"] == "ok").all() and (t["converged"] == 1).all()
    mine, lm = (t[t["solver"] == s].sort_values(["model", "run"]) for s in (GaussNewton.name, "scipy-lm"))
    # the same optimum as scipy-lm's (the trials stop within 1e-8 of it), so the same accuracy
    assert np.allclose(mine["fun"].to_numpy(), lm["fun"].to_numpy(), rtol=1e-7)
    assert np.allclose(mine["accuracy"].to_numpy(), lm["accuracy"].to_numpy(), rtol=1e-3)
    assert (mine["nfev"] < 40).all() and list(mine["solver_name"].unique()) == [GaussNewton.name]
