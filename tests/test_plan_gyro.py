"""optcal.core.gyro.plan*: the rotations between rests for the gyroscope (docs/planning.md, "Planning the rotations").

The candidates' information against the problem's own Jacobian on a recording that follows a plan; a turn about
the gravity direction is blind to the rate sensed along it; turns about one axis leave the other axes' scale
factors and misalignments undetermined, named; the planned order and rotations against the habitual plan of the
24-position scheme; a Monte-Carlo check of the predicted SDs; the command, its file and its refusals."""

import json

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.gyro import GyroProblem, draw_truth, get_gyro_model
from optcal.core.gyro.plan import GyroNoise, MotionPlan, Timing, criterion, model_spec
from optcal.core.gyro.plan_candidates import candidates
from optcal.core.gyro.plan_follow import plan_csv, read_plan, simulate_plan, verdict
from optcal.core.gyro.plan_search import habitual, neighbours, search
from optcal.core.schemes import scheme
from optcal.solvers.registry import get

NOISE = GyroNoise()  # 1e-4 rad/s/√Hz, 10 µg per rest mean, rests of 3 s
ONE_AXIS = scheme("24")[:8]  # the 24-position scheme's first group: gravity turns about the sensor's x axis


@pytest.fixture(scope="module")
def c24():
    return candidates(scheme("24"), "gyro12", rng=np.random.default_rng(0))


def _run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def _recording_information(data, model: str, noise: GyroNoise) -> np.ndarray:
    """F (natural units) from the gyroscope problem of a recording of a nominal sensor: its Jacobian rows,
    unwhitened by the problem's noise estimates and whitened again by the stated noise."""
    g_sens, bias = model_spec(model)
    p = GyroProblem(data, g_sensitivity=g_sens, bias=bias, scale=1.0)
    J = p.jacobian_full(p.from_sensor(get_gyro_model(g_sens).default_vector(1.0)))
    d = p.data
    m = d.n_motions
    window = d.t[d.stop] - d.t[d.start]
    rows = [J[:2 * m].reshape(m, 2, -1) * (p.sd_motion / noise.motion_sd(window))[:, None, None]]
    if p.model.bias:
        rows.append(J[2 * m:].reshape(d.n_rests, 3, -1) * p.sd_rest[:, :, None] / noise.rest_sd())
    return sum(np.einsum("krp,krq->pq", R, R) for R in rows)


@pytest.mark.parametrize("model", ["gyro9", "gyro21"])
def test_candidate_information_is_the_problems_on_a_recording_that_follows_the_plan(model):
    """The search adds up candidates simulated once at 1 s; the plan's own recording (each motion at its own
    duration, 3 to 4 s, 100 Hz, noise-free) gives the same information through GyroProblem's Jacobian: measured
    to 3e-9 of the largest entry with gyro9 (the scale and misalignment columns do not depend on the duration),
    to 1.9e-5 with gyro21 (the bias and g-sensitivity columns scale with it up to the integrator's steps); the
    SDs to 3e-9 and 6e-6."""
    c = candidates(scheme("6"), model, timing=Timing(rate_limit_dps=60.0), rng=np.random.default_rng(1))
    order = search(c, rng=np.random.default_rng(2)).order
    rng = np.random.default_rng(2)
    v = c.vertex[order]
    choice = [rng.choice(o[o >= 0]) for o in c.options[v[:-1], v[1:]]]  # any rotation each, of any duration
    plan = MotionPlan(c, order, choice)
    assert len(set(np.round(plan.duration, 3))) > 2
    data = simulate_plan(plan.directions, plan.rotvec, plan.duration, model,
                         get_gyro_model(model == "gyro21").default_vector(1.0), GyroNoise(1e-12, 1e-12, 3.0),
                         np.random.default_rng(3))
    np.testing.assert_allclose(data.t[data.stop] - data.t[data.start], plan.duration, atol=1e-9)
    F = _recording_information(data, model, NOISE)
    assert np.max(np.abs(F - plan.F)) < 1e-4 * np.max(np.abs(F))
    np.testing.assert_allclose(plan.sd, np.sqrt(np.diag(np.linalg.inv(F))), rtol=1e-4)


def test_a_turn_about_the_gravity_direction_is_blind_to_the_rate_along_it():
    """Two poses with z up and one with x up: the 90° turn about z (the vertical) between the z-up poses moves the
    carried gravity direction by nothing for an error of K_z (its column of the problem's Jacobian is zero to
    rounding) but sees T_xz and T_yz; the 90° turn about the horizontal y axis, z up to x up, sees K_y."""
    c = candidates(np.array([[0, 0, 1.0], [0, 0, 1], [1, 0, 0]]), "gyro12", rng=np.random.default_rng(0))
    names = list(c.names)
    about_z = np.flatnonzero((c.a == c.b) & np.all(np.abs(c.rotvec - [0, 0, np.pi / 2]) < 1e-9, axis=1))
    about_y = np.flatnonzero(np.all(np.abs(c.rotvec - [0, np.pi / 2, 0]) < 1e-9, axis=1))
    assert len(about_z) == 1 and len(about_y) == 1
    R = c.rows[about_z[0]]
    scale = np.max(np.abs(R))
    assert np.max(np.abs(R[:, names.index("K_z")])) < 1e-9 * scale
    assert np.min([np.max(np.abs(R[:, names.index(n)])) for n in ("T_xz", "T_yz")]) > 0.5 * scale
    Ry = c.rows[about_y[0]]
    assert np.max(np.abs(Ry[:, names.index("K_y")])) > 0.5 * np.max(np.abs(Ry))


@pytest.mark.parametrize("model, undetermined", [
    ("gyro12", "K_y, K_z, T_xy, T_xz, T_yz, T_zy (rank 6 of 12)"),
    ("gyro21", "K_y, K_z, T_xy, T_xz, T_yz, T_zy, G_xx, G_yx, G_zx (rank 12 of 21)"),
])
def test_turns_about_one_axis_leave_the_others_undetermined_and_planned_turns_do_not(model, undetermined):
    """The first group of the 24-position scheme in its order with the shortest turns: every motion turns about
    x, which determines x's scale factor and the two misalignments that sense x's rate, not the other six
    (nor, with gravity always in the y-z plane, the g-sensitivity to x's specific force). Planned turns
    between the same eight poses determine every parameter."""
    c = candidates(ONE_AXIS, model, rng=np.random.default_rng(0))
    h = habitual(c)
    assert np.all(c.about_axis[h.choice]) and np.allclose(np.abs(h.rotvec[:, 0]), np.deg2rad(45.0))
    assert not np.isfinite(h.value)
    with pytest.raises(InputError, match="rotate the sensor about all three axes") as e:
        verdict(h.directions, h.rotvec, h.duration, model, NOISE, np.random.default_rng(1))
    assert f"parameter(s) {undetermined}" in str(e.value)
    plan = search(c, rng=np.random.default_rng(2))
    assert np.isfinite(plan.value)
    assert verdict(plan.directions, plan.rotvec, plan.duration, model, NOISE, np.random.default_rng(3)) == \
        get_gyro_model(model == "gyro21").n_params


def test_planned_order_and_rotations_beat_the_habitual_24(c24):
    """The 24-position scheme in its order with the shortest turns (45° about x, y, z in turn; 25 s of motion at
    90 °/s) against planned plans, D criterion, measured with seed 0:

    - order and rotations planned: 2.03 times lower (80 s of motion: larger turns carry more information and
      take longer, at the same peak rate); turns about the sensor's axes only: 1.90; the order planned with
      the shortest turns: 1.87;
    - within 50 s of motion: 1.67; within the habitual plan's own 25 s: 1.01 (its 45° turns are the quickest
      there are, and at a rate limit every turned degree costs the same time: what a plan gains is in the time
      it turns for, and in the axes it turns about)."""
    h = habitual(c24)
    assert h.motion_s == pytest.approx(25.0)
    measured = {(): 2.035, (("rotations", "axes"),): 1.899, (("rotations", "shortest"),): 1.869,
                (("budget_s", 50.0),): 1.672, (("budget_s", 25.0),): 1.009}
    for kw, factor in measured.items():
        plan = search(c24, restarts=8, rng=np.random.default_rng(0), **dict(kw))
        assert h.value / plan.value == pytest.approx(factor, abs=0.01), kw
        if kw and kw[0][0] == "budget_s":
            assert plan.motion_s <= kw[0][1] + 1e-9
        if kw == (("rotations", "axes"),):
            assert np.all(c24.about_axis[plan.choice])
    full = search(c24, restarts=8, rng=np.random.default_rng(0))
    assert full.motion_s == pytest.approx(79.9) and np.all(full.peak_dps <= 90.0 + 1e-9)
    # the worst SD of each family falls too: scale factors 48 -> 37 ppm, misalignments 71 -> 42 µrad
    hw, pw = h.family_sd(), full.family_sd()
    assert hw["K"] == pytest.approx(48.2, abs=0.1) and pw["K"] == pytest.approx(36.7, abs=0.1)
    assert hw["T"] == pytest.approx(71.3, abs=0.1) and pw["T"] == pytest.approx(42.4, abs=0.1)


def test_criteria_fast_path_equals_the_eigen_decomposition(c24):
    """The search scores with Cholesky and LU (with a ridge); the report with eigenvalues: the same values."""
    plan = habitual(c24)
    F = plan.F[None]
    for kind in ("D", "A", "E", "worst"):
        np.testing.assert_allclose(criterion(F, kind, ridge=1e-30), criterion(F, kind), rtol=1e-9)
    assert criterion(F, "worst")[0] == pytest.approx(np.max(plan.sd) ** 2, rel=1e-9)
    assert criterion(np.zeros((1, 12, 12)), "D")[0] == np.inf


def test_neighbours_are_every_swap_reversal_and_move():
    order = np.array([4, 0, 3, 1, 2])
    P = neighbours(order)
    assert P.shape == (10 + 10 + 20, 5)
    assert all(sorted(r) == sorted(order) for r in P.tolist())
    assert [2, 1, 3, 0, 4] in P.tolist()  # the whole path reversed
    assert [0, 3, 1, 4, 2] in P.tolist()  # the first pose moved to the fourth place


@pytest.mark.slow
@pytest.mark.parametrize("which", ["planned", "habitual"])
def test_monte_carlo_errors_follow_the_predicted_sds(which, tmp_path):
    """100 recordings (seeds 0-99) that follow a plan of the 24-position scheme read back from its file, a
    navigation-grade truth drawn for each, fitted by scipy-lm: every parameter's RMSE over its predicted SD (at
    nominal parameters, stated noise) lies within 0.8-1.25 and its mean error within 3 SD/√100 of zero. Measured:
    0.93-1.19 for the planned plan (0.95-1.05 over 400 other seeds), 0.89-1.07 for the habitual one."""
    c = candidates(scheme("24"), "gyro12", rng=np.random.default_rng(0))
    plan = search(c, rng=np.random.default_rng(0)) if which == "planned" else habitual(c)
    ratio = _monte_carlo(plan, tmp_path)
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio


def _monte_carlo(plan: MotionPlan, tmp_path, runs: int = 100) -> np.ndarray:
    """RMSE/predicted SD (p,) over ``runs`` scipy-lm fits of recordings that follow ``plan``'s file."""
    f = tmp_path / "plan.csv"
    f.write_text(plan_csv(plan), encoding="utf-8")
    pf = read_plan(f)
    model = get_gyro_model(False)
    Z = []
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        x = draw_truth(model, rng, 1.0)
        data = simulate_plan(pf.directions, pf.rotvec, pf.duration, "gyro12", x, NOISE, rng)
        p = GyroProblem(data, scale=1.0)
        res = get("scipy-lm").solve(p, rng=0, budget=2000)
        assert res.success
        sd = plan.sd * np.r_[x[:3], np.ones(9)]  # natural units: relative for the scale factors
        Z.append((res.x_full - p.from_sensor(x)) / sd)
    Z = np.array(Z)
    assert np.all(np.abs(Z.mean(axis=0)) < 3 / np.sqrt(runs)), Z.mean(axis=0)
    return np.sqrt(np.mean(Z**2, axis=0))


def test_simulated_recording_follows_the_plan(c24):
    """The rests' gravity directions are the plan's poses (to the noise) and no motion turns faster than the
    rate limit."""
    plan = search(c24, restarts=2, rng=np.random.default_rng(0))
    data = simulate_plan(plan.directions, plan.rotvec, plan.duration, "gyro12",
                         get_gyro_model(False).default_vector(1.0), NOISE, np.random.default_rng(1))
    assert data.n_rests == 24
    assert np.max(np.arccos(np.clip(np.sum(data.u * plan.directions, axis=1), -1, 1))) < 1e-4
    peak = np.rad2deg(np.max(np.linalg.norm(data.W, axis=1)))
    assert 85.0 < peak < 90.5  # rate noise 0.06 °/s per sample on top of a peak rate of at most 90 °/s


def test_cli_prints_the_plan_and_writes_a_file_others_read(tmp_path, capsys):
    out = tmp_path / "g.csv"
    code, text, err = _run(capsys, "plan", "--sensor", "gyroscope", "--scheme", "6", "--gyro-model", "gyro21",
                           "-o", str(out))
    assert code == 0, err
    assert "then turn about axis" in text and "angle °" in text and "time s" in text
    for unit in ("ppm", "µrad", "°/h", "(°/h)/g"):
        assert f"  {unit}" in text
    assert "observability: all 21 parameters determined (rank 21 of 21)" in text
    pf = read_plan(out)
    assert pf.directions.shape == (6, 3) and pf.rotvec.shape == (5, 3) and np.all(pf.duration >= 0.5)
    # the plan file is a scheme file: the accelerometer's simulation reads its poses
    code, _, err = _run(capsys, "simulate", "--scheme", str(out), "-o", str(tmp_path / "sim.csv"))
    assert code == 0, err
    code, text, err = _run(capsys, "plan", "--sensor", "gyroscope", "--scheme", "24", "--rotations", "axes",
                           "--json", "--rate-limit", "60", "--gyro-noise", "0.01", "--noise-ug", "20")
    assert code == 0, err
    rec = json.loads(text)
    assert rec["rank"] == 12 and rec["habitual"]["factor"] > 1.5
    assert rec["family_worst_sd"]["T"]["unit"] == "µrad" and rec["habitual"]["family_worst_sd"]["b"]["unit"] == "°/h"
    assert rec["family_worst_sd"]["K"]["sd"] < rec["habitual"]["family_worst_sd"]["K"]["sd"]
    assert all(m["about"] in ("+x", "-x", "+y", "-y", "+z", "-z") for m in rec["motions"])
    assert max(m["peak_dps"] for m in rec["motions"]) <= 60.0 + 1e-9
    assert rec["noise"]["rest_mean_ug"] == pytest.approx(20.0)
    assert [r["unit"] for r in rec["crlb"]][::3] == ["ppm", "µrad", "µrad", "°/h"]


@pytest.mark.parametrize("argv, fragment", [
    (["--gyro-model", "gyro13"], "unknown gyroscope model 'gyro13'"),
    (["--scheme", "6", "--order", "given", "--rotations", "shortest"], "poses 1 and 2 of the given order are opposite"),
    (["--scheme", "ONE_AXIS", "--order", "given", "--rotations", "shortest"],
     "do not determine gyroscope parameter(s) K_y, K_z, T_xy, T_xz, T_yz, T_zy"),
    (["--scheme", "THREE", "--gyro-model", "gyro21"], "3 pose(s) give 13 residuals, fewer than the 21 parameters"),
    (["--scheme", "UP"], "the poses all have one gravity direction"),
    (["--scheme", "UPDOWN"], "the pose with direction [0.0, 0.0, 1.0] joins no other by a turn of less than 180°"),
    (["--criterion", "targets"], "is the accelerometer's"),
    (["--n", "12"], "--n plans the accelerometer's positions"),
    (["--rate-limit", "-5"], "rate limit must be a positive"),
    (["--gyro-noise", "0"], "noise density must be a positive"),
    (["--rest-s", "0.01"], "rests of 0.01 s are too short to take a mean of"),
    (["--scheme", "random:30", "--rotations", "axes"], "no order of these poses joins every two consecutive ones by "
     "a turn about a sensor axis"),
    (["--scheme", "24", "--motion-budget", "10"], "no plan of these poses fits the motion budget of 10 s"),
])
def test_bad_gyroscope_plans_are_one_line_and_exit_2(argv, fragment, tmp_path, capsys):
    from optcal.core.plan.schemefile import scheme_csv

    up, down = np.array([[0, 0, 1.0]]), np.array([[0, 0, -1.0]])
    files = {"ONE_AXIS": ONE_AXIS, "THREE": np.eye(3), "UP": np.repeat(up, 5, 0),
             "UPDOWN": np.vstack([up, up, up, down, down])}
    argv = [str(tmp_path / f"{a}.csv") if a in files else a for a in argv]
    for name, d in files.items():
        (tmp_path / f"{name}.csv").write_text(scheme_csv(d), encoding="utf-8")
    out = tmp_path / "never.csv"
    code, _, err = _run(capsys, "plan", "--sensor", "gyroscope", *argv, "-o", str(out))
    assert code == 2
    assert fragment in err and len(err.strip().splitlines()) == 1
    assert not out.exists()  # nothing written before the command has succeeded


def test_the_plan_file_is_not_written_over_its_own_scheme(tmp_path, capsys):
    f = tmp_path / "g.csv"
    assert _run(capsys, "plan", "--sensor", "gyroscope", "--scheme", "6", "-o", str(f))[0] == 0
    before = f.read_text()
    code, _, err = _run(capsys, "plan", "--sensor", "gyroscope", "--scheme", str(f), "-o", str(f), "--force")
    assert code == 2 and "is also an input of this command" in err and f.read_text() == before


def test_gyroscope_options_without_the_sensor_are_refused(capsys):
    code, _, err = _run(capsys, "plan", "--n", "12", "--scheme", "24")
    assert code == 2 and "--scheme plan the gyroscope's rotations; add --sensor gyroscope" in err
    code, _, err = _run(capsys, "plan", "--n", "12", "--criterion", "worst")
    assert code == 2 and "--criterion worst is the gyroscope's" in err


def test_a_plan_file_whose_motion_misses_the_next_pose_is_one_line(tmp_path, c24, capsys):
    plan = habitual(c24)
    f = tmp_path / "p.csv"
    lines = plan_csv(plan).splitlines()
    row = lines[3].split(",")  # the first pose's row (after two comment lines and the header): 45° about x
    assert row[0] == "1" and float(row[11]) == pytest.approx(45.0)
    row[11] = "50.0"
    lines[3] = ",".join(row)
    f.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(InputError, match=r"data row 1: the motion does not take pose 1 to pose 2 \(it misses by 5°\)"):
        read_plan(f)
