"""Static navigation (optcal.core.nav, docs/design.md, "Static navigation"): closed-form Schuler checks, Eq. 23,
Foucault modulation, self-alignment, the calibration error at a fixed attitude, and the `optcal nav` command."""

import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.ndimage import uniform_filter1d
from scipy.signal import hilbert

from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.gravity import G0, normal_gravity
from optcal.core.model import get_model
from optcal.core.nav import (
    OMEGA_E,
    calibration_error_body,
    error_dynamics,
    navigation_error,
    propagate,
    static_navigation,
)
from optcal.core.presets import PAPER_TRUTH

NMI = 1852.0
LAT = 45.0
DF = 100e-6 * G0  # a 100 µg accelerometer error, m/s²


def wgs84_radii(lat_deg):
    """Meridian and prime-vertical radii written out here, independently of optcal.core.nav."""
    a, e2 = 6378137.0, 6.69437999014e-3
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return a * (1 - e2) / (1 - e2 * s2) ** 1.5, a / math.sqrt(1 - e2 * s2)


G = normal_gravity(LAT)
RN, RE = wgs84_radii(LAT)
W_S = math.sqrt(G / RN)


# -- closed-form Schuler checks --------------------------------------------------------------------
def test_north_accelerometer_bias_gives_schuler_oscillation_of_closed_form():
    r = static_navigation([DF, 0, 0], hours=5, latitude_deg=LAT, earth_rate_coupling=False)
    closed = (DF / G) * (1 - np.cos(W_S * r.t_s))  # δv_N = (δf/ω_s) sin ω_s t, δL = ∫δv_N/R_N
    peak = 2 * DF / G
    assert np.max(np.abs(r.dlat_rad - closed)) < 0.01 * peak
    assert np.max(np.abs(r.dlat_rad - closed)) < 1e-8 * peak  # exact solution: rounding only
    assert np.max(np.abs(r.dlon_rad)) == 0.0
    assert r.max_error_nmi == pytest.approx(RN * peak / NMI, rel=0.01)
    assert r.max_error_nmi == pytest.approx(6371e3 * peak / NMI, rel=0.01)  # the R·2δf/g
    assert 2 * math.pi / W_S / 60 == pytest.approx(84.4, abs=0.05)


def test_schuler_period_with_earth_rate_coupling_on():
    r = static_navigation([DF, 0, 0], hours=5, latitude_deg=LAT, dt_s=1.0)
    d = r.dlat_rad
    peaks = np.flatnonzero((d[1:-1] > d[:-2]) & (d[1:-1] >= d[2:])) + 1
    period_min = np.diff(r.t_s[peaks]) / 60
    assert len(period_min) == 3
    assert np.all(np.abs(period_min / 84.4 - 1) < 0.01)
    assert r.max_error_nmi == pytest.approx(RN * 2 * DF / G / NMI, rel=0.01)


def test_east_gyro_bias_gives_schuler_loop_closed_form_over_first_hour():
    eps_dph = 0.01
    eps = math.radians(eps_dph) / 3600
    r = static_navigation([0, 0, 0], hours=1, latitude_deg=LAT, gyro_bias_dph=(0, eps_dph, 0),
                          earth_rate_coupling=False)
    closed = eps * (r.t_s - np.sin(W_S * r.t_s) / W_S)
    assert np.all(r.dlat_rad <= 0)  # a positive east gyro bias drives the computed latitude south
    assert np.max(np.abs(np.abs(r.dlat_rad) - closed)) < 0.01 * closed.max()
    assert abs(r.dlat_rad[-1]) == pytest.approx(closed[-1], rel=0.01)
    assert abs(r.dlat_rad[-1]) == pytest.approx(closed[-1], rel=1e-8)


def test_radial_error_is_eq23_in_nautical_miles_with_max_and_mean():
    r = static_navigation([DF, -0.5 * DF, 0], hours=5, latitude_deg=LAT, earth_rate_coupling=False)
    cos_l = math.cos(math.radians(LAT))
    w_e = math.sqrt(G / RE)
    # east channel: δλ·cosL = −(δf_E/g)(1 − cos ω_E t) with the prime-vertical Schuler frequency
    closed_lon = (-0.5 * DF / G) * (1 - np.cos(w_e * r.t_s)) / cos_l
    assert np.max(np.abs(r.dlon_rad - closed_lon)) < 1e-8 * np.max(np.abs(closed_lon))
    eq23 = np.hypot(RN * r.dlat_rad, RE * cos_l * r.dlon_rad) / NMI
    np.testing.assert_allclose(r.error_nmi, eq23, rtol=1e-12, atol=1e-15)
    assert r.max_error_nmi == pytest.approx(eq23.max(), rel=1e-12)
    assert r.mean_error_nmi == pytest.approx(eq23.mean(), rel=1e-12)
    assert r.hours == 5.0 and r.latitude_deg == LAT and r.t_s[-1] == 5 * 3600.0
    assert r.to_dict() == {"max_error_nmi": r.max_error_nmi, "mean_error_nmi": r.mean_error_nmi,
                           "hours": 5.0, "latitude_deg": LAT}


def test_exact_propagation_matches_numerical_integration():
    rng = np.random.default_rng(7)
    F, _ = error_dynamics(30.0, 500.0, earth_rate_coupling=True)
    b = np.concatenate([rng.normal(0, 1e-8, 3), rng.normal(0, 1e-3, 2), [0, 0]])
    x0 = np.concatenate([rng.normal(0, 1e-5, 3), rng.normal(0, 1e-2, 2), rng.normal(0, 1e-7, 2)])
    X = propagate(F, b, x0, 60.0, 180)
    t = np.arange(181) * 60.0
    ref = solve_ivp(lambda _, x: F @ x + b, (0, t[-1]), x0, t_eval=t, method="DOP853", rtol=1e-12, atol=1e-20)
    scale = np.max(np.abs(ref.y), axis=1)
    assert np.max(np.abs(X.T - ref.y) / scale[:, None]) < 1e-7


# -- Earth-rate coupling: Foucault modulation ------------------------------------------------------
def test_schuler_envelope_is_modulated_with_the_foucault_period():
    r = static_navigation([DF, 0, 0], hours=24, latitude_deg=LAT)
    t = r.t_s
    t_s = 2 * math.pi / W_S
    osc = r.dlat_rad - uniform_filter1d(r.dlat_rad, int(round(t_s / 10.0)), mode="nearest")
    env = np.abs(hilbert(osc))
    sel = (t > t_s) & (t < t[-1] - t_s)  # away from the filters' edges
    w_f = OMEGA_E * math.sin(math.radians(LAT))  # Foucault rate; period 33.8 h at 45°
    cands = np.linspace(0.5, 1.5, 401) * w_f
    basis = np.abs(np.cos(np.outer(cands, t[sel])))
    amp = basis @ env[sel] / np.sum(basis**2, axis=1)
    resid = np.sum((env[sel] - amp[:, None] * basis) ** 2, axis=1)
    k = int(np.argmin(resid))
    assert 2 * math.pi / cands[k] == pytest.approx(2 * math.pi / w_f, rel=0.03)
    assert amp[k] == pytest.approx(DF / G, rel=0.03)  # half the peak-to-peak 2δf/g
    # the envelope vanishes near a quarter Foucault period (8.46 h) and is back to full after a half
    assert env[sel][np.argmin(env[sel])] < 0.05 * DF / G
    assert t[sel][np.argmin(env[sel])] / 3600 == pytest.approx(math.pi / (2 * w_f) / 3600, rel=0.03)
    # and the plane of oscillation turns like Foucault's pendulum: clockwise seen from above in the
    # northern hemisphere (north to east), so a quarter period later the east error swings as −cos ω_s t
    near = np.abs(t - math.pi / (2 * w_f)) < 2 * 3600
    east = r.dlon_rad[near] - np.polyval(np.polyfit(t[near], r.dlon_rad[near], 3), t[near])
    assert np.corrcoef(east, -np.cos(W_S * t[near]))[0, 1] > 0.99


# -- self-alignment -------------------------------------------------------------------------------
def schuler_amplitude(r, lat_deg=LAT):
    """Amplitude (rad) of the horizontal error's component at ω_s, by least squares next to a degree-6
    polynomial that takes the slow (Earth-rate) part."""
    u = r.t_s / r.t_s[-1]
    basis = np.column_stack([u**k for k in range(7)] + [np.cos(W_S * r.t_s), np.sin(W_S * r.t_s)])
    amps = []
    for y in (r.dlat_rad, r.dlon_rad * math.cos(math.radians(lat_deg))):
        coef = np.linalg.lstsq(basis, y, rcond=None)[0]
        amps.append(math.hypot(*coef[-2:]))
    return math.hypot(*amps)


@pytest.mark.parametrize("coupling", [False, True])
def test_self_alignment_absorbs_horizontal_accelerometer_bias(coupling):
    kw = dict(hours=5, latitude_deg=LAT, earth_rate_coupling=coupling)
    plain = static_navigation([0, DF, 0], **kw)
    aligned = static_navigation([0, DF, 0], self_alignment=True, **kw)
    assert plain.max_error_nmi == pytest.approx(RE * 2 * DF / G / NMI, rel=0.01)  # the Schuler peak
    assert aligned.max_error_nmi < 1e-9 * plain.max_error_nmi  # ≈ 0: the tilt is about the polar axis
    north_plain = static_navigation([DF, 0, 0], **kw)
    north = static_navigation([DF, 0, 0], self_alignment=True, **kw)
    assert schuler_amplitude(north_plain) == pytest.approx(DF / G, rel=0.03 if coupling else 1e-6)
    if not coupling:
        assert north.max_error_nmi < 1e-9 * plain.max_error_nmi
    else:
        # the absorbed tilt about east turns with the Earth at Ω·sinL: a rate step that leaves a Schuler
        # residual of (Ω sinL/ω_s)·δf/g (4 % at 45°) and a slow drift of about half the Schuler peak in 5 h
        ratio = schuler_amplitude(north) / schuler_amplitude(north_plain)
        assert ratio == pytest.approx(OMEGA_E * math.sin(math.radians(LAT)) / W_S, rel=0.05)
        assert 0.3 * plain.max_error_nmi < north.max_error_nmi < 0.7 * plain.max_error_nmi


def test_aligned_north_bias_acts_as_a_gyro_drift_normal_to_the_polar_axis():
    """After alignment δf_N is the negative of a drift Ω·δf_N/g about (sinL, 0, cosL) from rest."""
    lat = math.radians(LAT)
    drift_dph = -np.degrees(OMEGA_E * DF / G * np.array([math.sin(lat), 0, math.cos(lat)])) * 3600
    a = static_navigation([DF, 0, 0], hours=5, latitude_deg=LAT, self_alignment=True)
    b = static_navigation([0, 0, 0], hours=5, latitude_deg=LAT, gyro_bias_dph=drift_dph)
    np.testing.assert_allclose(a.dlat_rad, b.dlat_rad, atol=1e-9 * np.abs(b.dlat_rad).max())
    np.testing.assert_allclose(a.dlon_rad, b.dlon_rad, atol=1e-9 * np.abs(b.dlon_rad).max())


def test_gyrocompassing_absorbs_the_east_gyro_bias():
    kw = dict(hours=5, latitude_deg=LAT, gyro_bias_dph=(0, 0.01, 0))
    assert static_navigation([0, 0, 0], **kw).max_error_nmi > 1.0
    assert static_navigation([0, 0, 0], self_alignment=True, **kw).max_error_nmi < 1e-9


# -- the calibration's residual specific-force error ----------------------------------------------
def _x(model, **changes):
    m = get_model(model)
    return m.from_dict({**{k: v for k, v in PAPER_TRUTH.items() if k in m.names}, **changes})


def test_calibration_error_is_zero_for_the_true_parameters():
    m = get_model("nonlinear12")
    x = _x(m)
    for att in [(0, 0, 0), (10, -20, 135), (180, 0, 0)]:
        assert np.max(np.abs(calibration_error_body(m, x, x, attitude_deg=att))) < 1e-14
    r = navigation_error(m, x, x, hours=5)
    assert r.max_error_nmi < 1e-9


def test_calibration_error_of_a_bias_error_is_minus_the_bias_in_g0():
    m = get_model("diag6")
    db = 50e-6
    xt, xe = _x(m), _x(m, b_x=PAPER_TRUTH["b_x"] + db)
    e = calibration_error_body(m, xt, xe, attitude_deg=(0, 0, 0), latitude_deg=LAT)
    np.testing.assert_allclose(e, [-db * G0, 0, 0], atol=1e-12)
    # dicts work too
    assert np.allclose(calibration_error_body(m, m.to_dict(xt), m.to_dict(xe)), e, atol=1e-15)


def test_calibration_error_of_a_scale_error_on_the_vertical_axis():
    m = get_model("diag6")
    k_est = PAPER_TRUTH["K_x"] * (1 + 100e-6)
    xt, xe = _x(m), _x(m, K_x=k_est)
    # pitch 90°: body x points up and reads +g
    e = calibration_error_body(m, xt, xe, attitude_deg=(0, 90, 0), latitude_deg=LAT)
    expected = (G / G0 + PAPER_TRUTH["b_x"]) * PAPER_TRUTH["K_x"] / k_est - PAPER_TRUTH["b_x"] - G / G0
    np.testing.assert_allclose(e, [expected * G0, 0, 0], atol=1e-12)
    assert e[0] == pytest.approx(-100e-6 * G, rel=0.01)


def test_navigation_error_combines_both_steps_and_routes_keywords():
    m = get_model("diag6")
    db = 50e-6
    xt, xe = _x(m), _x(m, b_x=PAPER_TRUTH["b_x"] + db)
    r = navigation_error(m, xt, xe, hours=5, latitude_deg=LAT, earth_rate_coupling=False)
    assert r.max_error_nmi == pytest.approx(RN * 2 * db * G0 / G / NMI, rel=0.01)
    # yaw 90°: body x points east, so the same bias moves longitude, not latitude
    r90 = navigation_error(m, xt, xe, hours=5, latitude_deg=LAT, attitude_deg=(0, 0, 90),
                           earth_rate_coupling=False)
    assert np.max(np.abs(r90.dlat_rad)) < 1e-12 and r90.max_error_nmi == pytest.approx(
        RE * 2 * db * G0 / G / NMI, rel=0.01)


@pytest.mark.parametrize(
    "kw",
    [dict(latitude_deg=90.0), dict(hours=0.0), dict(hours=float("nan")), dict(attitude_deg=(0, 0)),
     dict(dt_s=-1.0), dict(gyro_bias_dph=(0, 1)), dict(dt_s=1e-4)],
)
def test_static_navigation_rejects_bad_input(kw):
    with pytest.raises(InputError):
        static_navigation([0, 0, 0], **kw)


# -- the command ----------------------------------------------------------------------------------
def _calfile(path, model, params, units="g"):
    m = get_model(model)
    path.write_text(json.dumps({
        "format": "optcal-calibration", "format_version": 1, "model": m.name, "terms": list(m.terms),
        "parameters": params, "stderr": {n: None for n in m.names}, "units": {"input": "g", "output": units},
        "g_local": 1.0, "data": {"n_positions": 24, "rms_residual_g": 1e-5, "source": None},
        "solver": "test", "created": "2026-01-01T00:00:00Z",
    }))
    return path


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def files(tmp_path):
    m = get_model("nonlinear12")
    truth = {k: v for k, v in PAPER_TRUTH.items() if k in m.names}
    est = {**truth, "b_x": truth["b_x"] + 50e-6, "S_zx": truth["S_zx"] + 20e-6}
    (tmp_path / "truth.json").write_text(json.dumps(truth))
    return {
        "truth": tmp_path / "truth.json",
        "truth_cal": _calfile(tmp_path / "truth_cal.json", m, truth),
        "cal": _calfile(tmp_path / "cal.json", m, est),
        "m": m, "truth_d": truth, "est_d": est, "dir": tmp_path,
    }


def test_cli_json_contract_and_values(files, capsys):
    code, out, err = _run(capsys, "nav", files["cal"], "--truth", files["truth"], "--hours", 5, "--latitude", LAT,
                          "--json")
    assert code == 0, err
    res = json.loads(out)
    assert set(res) == {"max_error_nmi", "mean_error_nmi", "hours", "latitude_deg"}
    m = files["m"]
    direct = navigation_error(m, m.from_dict(files["truth_d"]), m.from_dict(files["est_d"]), hours=5,
                              latitude_deg=LAT)
    assert res["max_error_nmi"] == pytest.approx(direct.max_error_nmi, rel=1e-12)
    assert res["mean_error_nmi"] == pytest.approx(direct.mean_error_nmi, rel=1e-12)
    assert res["hours"] == 5.0 and res["latitude_deg"] == LAT
    # only the 50 µg bias acts at level attitude (x north): the Schuler peak R·2δf/g
    assert res["max_error_nmi"] == pytest.approx(RN * 2 * 50e-6 * G0 / G / NMI, rel=0.01)
    # the truth as a calibration file gives the same
    code, out2, _ = _run(capsys, "nav", files["cal"], "--truth", files["truth_cal"], "--json")
    assert code == 0 and json.loads(out2) == res
    # the truth against itself: zero
    code, out3, _ = _run(capsys, "nav", files["truth_cal"], "--truth", files["truth"], "--json")
    assert code == 0 and json.loads(out3)["max_error_nmi"] < 1e-9


def test_cli_attitude_self_alignment_and_plot(files, capsys):
    base = ["nav", files["cal"], "--truth", files["truth"], "--json", "--attitude", "0,0,90"]
    code, out, _ = _run(capsys, *base)
    plain = json.loads(out)["max_error_nmi"]
    code2, out2, _ = _run(capsys, *base, "--self-align")
    # yaw 90°: the x bias is an east error, which the alignment absorbs completely (tilt about the polar axis)
    # (what is left comes from the 4.5 ng north error that b_x leaks into y through the truth's S_yz)
    assert code == code2 == 0 and plain > 0.2 and json.loads(out2)["max_error_nmi"] < 1e-3 * plain
    png = files["dir"] / "nav.png"
    code, out, _ = _run(capsys, "nav", files["cal"], "--truth", files["truth"], "--json", "--attitude=-10,20,0")
    m = files["m"]
    direct = navigation_error(m, m.from_dict(files["truth_d"]), m.from_dict(files["est_d"]), attitude_deg=(-10, 20, 0))
    assert code == 0 and json.loads(out)["max_error_nmi"] == pytest.approx(direct.max_error_nmi, rel=1e-12)
    code, out, err = _run(capsys, "nav", files["cal"], "--truth", files["truth"], "--plot", png, "--hours", 2)
    assert code == 0, err
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert "position error: max" in out and "nmi" in out


def test_cli_uses_the_union_of_parameters_of_different_models(files, capsys):
    diag = {k: files["est_d"][k] for k in get_model("diag6").names}
    cal = _calfile(files["dir"] / "diag6.json", "diag6", diag)
    code, out, err = _run(capsys, "nav", cal, "--truth", files["truth"], "--json", "--attitude", "10,20,30")
    assert code == 0, err
    m = files["m"]
    est = {**{n: 0.0 for n in m.names}, **diag}  # the calibration lacks S and K2: they count as zero
    direct = navigation_error(m, m.from_dict(files["truth_d"]), m.from_dict(est), attitude_deg=(10, 20, 30))
    assert json.loads(out)["max_error_nmi"] == pytest.approx(direct.max_error_nmi, rel=1e-12)
    # a seed15 truth against a linear9 calibration: the six angles hold the three
    seed = _calfile(files["dir"] / "seed.json", "seed15", PAPER_TRUTH)
    lin = {k: v for k, v in files["est_d"].items() if k in get_model("linear9").names}
    code, out, err = _run(capsys, "nav", _calfile(files["dir"] / "lin.json", "linear9", lin), "--truth", seed, "--json")
    assert code == 0, err
    assert json.loads(out)["max_error_nmi"] > 0


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["{cal}", "--truth", "{dir}/missing.json"], "cannot read"),
        (["{dir}/missing.json", "--truth", "{truth}"], "cannot read"),
        (["{cal}", "--truth", "{dir}/bad.json"], "not valid JSON"),
        (["{cal}", "--truth", "{dir}/unknown.json"], "unknown parameter"),
        (["{cal}", "--truth", "{truth}", "--attitude", "1,2"], "--attitude"),
        (["{cal}", "--truth", "{truth}", "--attitude", "a,b,c"], "--attitude"),
        (["{cal}", "--truth", "{truth}", "--latitude", "95"], "latitude"),
        (["{cal}", "--truth", "{truth}", "--hours", "-1"], "hours"),
        (["{cal}", "--truth", "{dir}/units.json"], "units"),
        (["{cal}", "--truth", "{truth}", "--plot", "{dir}/no/such/dir/nav.png"], "cannot write"),
        (["{cal}", "--truth", "{truth}", "--gyro-bias-dph", "1,x,2"], "--gyro-bias"),
    ],
)
def test_cli_bad_input_is_one_line_exit_2(files, capsys, argv, fragment):
    d = files["dir"]
    (d / "bad.json").write_text("{not json")
    (d / "unknown.json").write_text(json.dumps({**files["truth_d"], "Q_x": 1.0}))
    _calfile(d / "units.json", files["m"], files["truth_d"], units="counts")
    args = [a.format(cal=files["cal"], truth=files["truth"], dir=d) for a in argv]
    code, out, err = _run(capsys, "nav", *args)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and fragment in err and "Traceback" not in err
