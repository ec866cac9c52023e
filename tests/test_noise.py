"""optcal noise (optcal/core/noise/, optcal/core/plots/noise.py, optcal/app/commands/noise.py): the Allan-deviation
reading of white noise, bias instability and bias random walk on synthetic noise of known strength, the JSON and Kalibr
outputs, bad input, and calibrate/info --noise-from."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest
from conftest import assert_numbers_carry_units

from optcal.app.cli import main
from optcal.core.noise import FLICKER_FACTOR, G0, WhiteNoise, analyse, analyse_axis, octave_m

FS = 100.0  # Hz


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def white(rng, n, density_g, axes=3):
    """White noise of two-sided density N (g/√Hz): per-sample SD N·√f_s."""
    return rng.standard_normal((n, axes)) * density_g * math.sqrt(FS)


def random_walk(rng, n, k_g_per_sqrt_s, axes=3):
    """A bias random walk of coefficient K (g/√s): increments of SD K·√Δt."""
    return np.cumsum(rng.standard_normal((n, axes)) * k_g_per_sqrt_s / math.sqrt(FS), axis=0)


def flicker(rng, n, b_g):
    """Flicker noise of two-sided PSD B²/(2π|f|), whose Allan deviation is 0.664·B at every τ."""
    f = np.fft.rfftfreq(n, 1.0 / FS)
    S = np.zeros_like(f)
    S[1:] = b_g**2 / (2 * np.pi * f[1:])
    X = np.sqrt(S * n * FS / 2) * (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f)))
    return np.fft.irfft(X, n)


def write_recording(path, N, rate=FS, time=True):
    t = np.arange(len(N)) / rate
    with open(path, "w") as fh:
        fh.write("t,ax,ay,az\n" if time else "ax,ay,az\n")
        for i in range(len(N)):
            row = (t[i], *N[i]) if time else tuple(N[i])
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    return path


# -- the readings ----------------------------------------------------------------------------------------
def test_white_noise_density_is_read_within_one_percent_and_its_interval_holds_the_truth():
    rng = np.random.default_rng(20240501)
    density = 100e-6  # g/√Hz
    N = white(rng, 200_000, density) + np.array([0.0, 0.0, 1.0])  # 2000 s at 100 Hz, at rest
    rep = analyse(N, FS, ci=0.95)
    for a in rep.axes:
        w = a.white
        assert w.kind == "estimate"
        assert w.value == pytest.approx(density, rel=0.01), a.axis
        assert w.low <= density <= w.high, (a.axis, w)
        assert w.high / w.low < 1.03  # a 2000-s record pins N to about 1 %
        # white noise alone: σ(τ) still falls at the longest τ, so B and K are upper bounds only
        assert a.bias_instability.kind == "upper bound" and a.random_walk.kind == "upper bound"
    assert rep.density_g() == pytest.approx(density, rel=0.01)


def test_the_white_noise_interval_is_not_too_narrow():
    """The 68 % interval of N (chi-square with the conservative EDF of optcal.noise) holds the truth in
    at least 68 % of 40 independent records (about 0.9 expected from the stated conservatism)."""
    rng = np.random.default_rng(7)
    density, n = 100e-6, 20_000
    m = octave_m(n)
    hits = [(lambda w: w.low <= density <= w.high)(analyse_axis(white(rng, n, density, 1)[:, 0], FS, m).white)
            for _ in range(40)]
    assert np.mean(hits) >= 0.68


def test_random_walk_is_recovered():
    rng = np.random.default_rng(11)
    density, k = 100e-6, 50e-6  # g/√Hz, g/√s: the two lines cross at τ = √3·N/K ≈ 3.5 s
    n = 400_000  # 4000 s
    rep = analyse(white(rng, n, density) + random_walk(rng, n, k), FS, ci=0.95)
    for a in rep.axes:
        rw = a.random_walk
        assert rw.kind == "estimate", a.axis
        assert rw.value == pytest.approx(k, rel=0.3), a.axis
        assert rw.low <= k <= rw.high, (a.axis, rw)
        assert rw.how == "fit" and a.white.value == pytest.approx(density, rel=0.02)
        # where the random walk dominates, σ(τ) lies on the +1/2 line K·√(τ/3)
        late = (a.tau_s >= 40) & (a.edf >= 10)  # the longest τ have a few degrees of freedom only
        np.testing.assert_allclose(a.adev_g[late], rw.value * np.sqrt(a.tau_s[late] / 3.0), rtol=0.3)
        firm = a.edf >= 10
        np.testing.assert_allclose(np.sqrt(a.fit.variance(a.tau_s[firm])), a.adev_g[firm], rtol=0.2)
        # the figure's lines (term_adev_g) pass through N at τ = 1 s and K at τ = 3 s
        assert (a.white_tau_s, a.rw_tau_s) == (1.0, 3.0)
        assert a.term_adev_g("white", a.white_tau_s) == pytest.approx(a.white.value, rel=1e-12)
        assert a.term_adev_g("random_walk", a.rw_tau_s) == pytest.approx(rw.value, rel=1e-12)


def test_the_fit_recovers_exact_coefficients_from_a_noise_free_curve():
    from optcal.core.noise import fit_terms

    taus = 2.0 ** np.arange(14) / FS
    a, b, c = (80e-6) ** 2, (0.664 * 12e-6) ** 2, (3e-6) ** 2 / 3
    fit = fit_terms(taus, np.sqrt(a / taus + b + c * taus), np.rint(taus * FS).astype(int), 2_000_000,
                    np.ones(len(taus), bool))
    np.testing.assert_allclose(fit.coef, [a, b, c], rtol=1e-9)
    # a curve without a floor: b is held at 0, not pushed negative
    fit = fit_terms(taus, np.sqrt(a / taus + c * taus), np.rint(taus * FS).astype(int), 2_000_000,
                    np.ones(len(taus), bool))
    assert fit.coef[1] < 1e-12 * a
    np.testing.assert_allclose(fit.coef[[0, 2]], [a, c], rtol=1e-9)


def test_flicker_noise_gives_a_plateau_read_as_bias_instability():
    rng = np.random.default_rng(3)
    density, b = 20e-6, 20e-6  # white meets the plateau 0.664·B at τ ≈ 2.3 s
    n = 400_000
    N = np.column_stack([flicker(rng, n, b) for _ in range(3)]) + white(rng, n, density)
    rep = analyse(N, FS)
    for a in rep.axes:
        bi = a.bias_instability
        assert bi.kind == "estimate", a.axis
        assert bi.value == pytest.approx(b, rel=0.2), a.axis
        assert bi.low <= b <= bi.high, bi
        plateau = (a.tau_s >= 20) & (a.tau_s <= 160)
        assert np.all(np.abs(a.slope[plateau]) < 0.25), a.slope  # flat, not a −1/2 or +1/2 line
        np.testing.assert_allclose(a.adev_g[plateau], FLICKER_FACTOR * b, rtol=0.25)
        np.testing.assert_allclose(a.term_adev_g("floor", [1.0, 100.0]), FLICKER_FACTOR * bi.value, rtol=1e-12)
        assert a.white.value == pytest.approx(density, rel=0.03)


def test_sigma_of_a_mean_is_density_over_root_dwell():
    w = WhiteNoise(100e-6, 100.0, "x")
    assert w.sigma_of_mean_g(4.0) == pytest.approx(50e-6)
    assert w.sigma_of_mean_g([4.0, 1.0]) == pytest.approx(100e-6 * math.sqrt((1 / 4 + 1) / 2))


# -- the command -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def static_recording(tmp_path_factory):
    """A 600-s recording at rest in m/s², 100 Hz: N = 150, 120, 200 µg/√Hz, K = 20 µg/√s on x."""
    rng = np.random.default_rng(5)
    n = 60_000
    dens = np.array([150e-6, 120e-6, 200e-6])
    N = white(rng, n, 1.0) * dens + np.array([0.01, -0.02, 1.0])
    N[:, 0] += random_walk(rng, n, 20e-6, 1)[:, 0]
    return write_recording(tmp_path_factory.mktemp("noise") / "rest.csv", N * G0), dens


def test_json_has_units_in_every_key(static_recording, capsys):
    path, dens = static_recording
    code, out, err = _run(capsys, "noise", path, "--units", "m/s2", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["kind"] == "optcal noise" and res["rate_hz"] == pytest.approx(FS) and res["units"] == "m/s2"
    for axis, d in zip("xyz", dens):
        ax = res["axes"][axis]
        assert ax["white_noise_density_ug_per_sqrt_hz"]["value"] == pytest.approx(d * 1e6, rel=0.03)
        assert ax["white_noise_density_g_per_sqrt_hz"]["value"] == pytest.approx(
            ax["white_noise_density_ug_per_sqrt_hz"]["value"] * 1e-6)
        for key in ("bias_instability_ug", "random_walk_ug_per_sqrt_s"):
            assert ax[key]["kind"] in ("estimate", "upper bound") and ax[key]["value"] > 0
        assert len(ax["allan"]["tau_s"]) == len(ax["allan"]["adev_ug"]) == len(ax["allan"]["edf"])
    assert res["white_noise_density_rms_g_per_sqrt_hz"] == pytest.approx(math.sqrt(np.mean(dens**2)), rel=0.03)

    # every number sits under a key that names its unit, or is a count, a level, an EDF or a slope
    unit = re.compile(r"_(s|hz|ug|g|g_per_sqrt_hz|ug_per_sqrt_hz|ug_per_sqrt_s|units_per_g)$")
    assert_numbers_carry_units(res, unit)


def test_kalibr_yaml_is_the_si_form_of_the_ug_figures(static_recording, capsys, tmp_path):
    path, _ = static_recording
    yml = tmp_path / "imu.yaml"
    code, out, err = _run(capsys, "noise", path, "--units", "m/s2", "--json", "--kalibr-yaml", yml)
    assert code == 0, err
    res = json.loads(out)
    fields = dict(re.findall(r"^(\w+):\s*([-+0-9.eE]+)", yml.read_text(), flags=re.M))
    assert set(fields) == {"accelerometer_noise_density", "accelerometer_random_walk", "update_rate"}
    n_ug = max(a["white_noise_density_ug_per_sqrt_hz"]["value"] for a in res["axes"].values())
    k_ug = max(a["random_walk_ug_per_sqrt_s"]["value"] for a in res["axes"].values())
    assert float(fields["accelerometer_noise_density"]) == pytest.approx(n_ug * 1e-6 * G0, rel=1e-5)
    assert float(fields["accelerometer_random_walk"]) == pytest.approx(k_ug * 1e-6 * G0, rel=1e-5)
    assert float(fields["update_rate"]) == pytest.approx(FS)
    yaml = pytest.importorskip("yaml")
    assert yaml.safe_load(yml.read_text())["update_rate"] == pytest.approx(FS)


def test_table_plot_and_no_silent_overwrite(static_recording, capsys, tmp_path):
    path, _ = static_recording
    fig = tmp_path / "adev.png"
    code, out, err = _run(capsys, "noise", path, "--units", "m/s2", "--plot", fig, "--interval", "100:500")
    assert code == 0, err
    assert "white-noise density [µg/√Hz]" in out and "40000 samples" in out and f"wrote {fig}" in out
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, _, err = _run(capsys, "noise", path, "--units", "m/s2", "--plot", fig)
    assert code == 2 and "exists" in err and "--force" in err
    code, _, err = _run(capsys, "noise", path, "--units", "m/s2", "--plot", fig, "--force")
    assert code == 0, err


BAD = {
    "too short": (lambda d: write_recording(d / "short.csv", np.ones((10, 3))), [], "too short"),
    "no time, no rate": (lambda d: write_recording(d / "norate.csv", np.ones((100, 3)), time=False), [],
                         "no time column"),
    "taus asked too long": (lambda d: write_recording(d / "r.csv", np.ones((1000, 3))), ["--tau-max", "5"],
                            "too short for τ up to 5 s"),
    "bad interval": (lambda d: write_recording(d / "r.csv", np.ones((100, 3))), ["--interval", "5-9"], "START:END"),
    "empty interval": (lambda d: write_recording(d / "r.csv", np.ones((100, 3))), ["--interval", "50:60"],
                       "holds no sample"),
    "wrong units": (lambda d: write_recording(d / "r.csv", np.full((100, 3), 10000.0)), ["--units", "mg"],
                    "magnitude"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_line_and_exit_2_and_writes_nothing(case, capsys, tmp_path):
    make, extra, message = BAD[case]
    path = make(tmp_path)
    fig = tmp_path / "never.png"
    code, out, err = _run(capsys, "noise", path, *extra, "--plot", fig)
    assert code == 2, (out, err)
    assert err.count("\n") == 1 and err.startswith("optcal noise: error:") and message in err, err
    assert not fig.exists()


def test_non_static_data_warns(capsys, tmp_path):
    rng = np.random.default_rng(2)
    N = white(rng, 12_000, 100e-6) + np.array([0, 0, 1.0])
    N[6000:6100] += 0.3 * rng.standard_normal((100, 3))  # the sensor was bumped at 60 s
    path = write_recording(tmp_path / "bumped.csv", N)
    code, out, err = _run(capsys, "noise", path)
    assert code == 0
    assert "optcal: warning: the stretch does not look static" in err and "t ≈ 60" in err
    code, out, err = _run(capsys, "noise", path, "-q")
    assert code == 0 and err == ""
    code, out, err = _run(capsys, "noise", path, "--interval", ":59")  # the static part alone
    assert code == 0 and err == ""


def test_real_mpu6050_rest_has_the_datasheet_noise_density(capsys, corpus):
    """The 36-s initial rest of the MPU-6050 recording in the real corpus's mpu6050/ (ImuCalibration, MIT;
    the folder's README). InvenSense's datasheet gives 400 µg/√Hz; the three axes read 340–520."""
    path = corpus / "mpu6050" / "example_data_calibration.csv"
    code, out, err = _run(capsys, "noise", path, "--units", "counts", "--interval", "0:36", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["n_samples"] == 3600 and res["rate_hz"] == pytest.approx(100.0)
    for ax in res["axes"].values():
        assert 250 < ax["white_noise_density_ug_per_sqrt_hz"]["value"] < 700
        assert ax["random_walk_ug_per_sqrt_s"]["kind"] == "upper bound"  # 36 s do not reach the +1/2 slope


# -- calibrate / info --noise-from --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def positions_with_n(tmp_path_factory):
    """24 simulated positions with n = 1000 samples each (10 s at 100 Hz) and no sx, sy, sz."""
    from optcal.core.model import get_model
    from optcal.core.presets import PAPER_TRUTH
    from optcal.core.simulate import simulate

    model = get_model("nonlinear12")
    truth = {n: PAPER_TRUTH.get(n, 1.0 if n.startswith("K_") else 0.0) for n in model.names}
    sim = simulate(model, truth, np.random.default_rng(1), scheme="24", noise_density=30e-6, dwell_s=10.0,
                   rate_hz=100.0)
    path = tmp_path_factory.mktemp("pos") / "p24n.csv"
    replace(sim.data, std=None).to_csv(path)
    return path


def _noise_json(tmp_path, density_g, name):
    obj = {"kind": "optcal noise", "rate_hz": 100.0, "white_noise_density_rms_g_per_sqrt_hz": density_g}
    p = tmp_path / name
    p.write_text(json.dumps(obj))
    return p


def test_noise_from_sets_calibrates_standard_errors(positions_with_n, capsys, tmp_path, static_recording):
    from optcal.app.fit import calibrate
    from optcal.core.data import read_positions

    d1 = 30e-6
    j1, j2 = _noise_json(tmp_path, d1, "n1.json"), _noise_json(tmp_path, 2 * d1, "n2.json")
    code, out, err = _run(capsys, "calibrate", positions_with_n, "--noise-from", j1, "--json")
    assert code == 0, err
    r1 = json.loads(out)
    code, out, err = _run(capsys, "calibrate", positions_with_n, "--noise-from", j2, "--json")
    assert code == 0, err
    r2 = json.loads(out)
    # σ of a mean = N/√(n/rate) = 30 µg/√Hz / √10 s
    sigma = d1 / math.sqrt(10.0)
    assert r1["noise_from"]["sigma_mean_ug"] == pytest.approx(sigma * 1e6)
    assert r1["noise_from"]["dwell_s"] == pytest.approx(10.0)
    ref = calibrate(read_positions(positions_with_n), "nonlinear12", noise_g=sigma)
    for i, name in enumerate(ref.model.names):
        assert r1["stderr"][name] == pytest.approx(ref.stderr[i], rel=1e-6), name
        assert r2["stderr"][name] == pytest.approx(2 * r1["stderr"][name], rel=1e-9), name  # σ scales them
    assert r1["parameters"] == pytest.approx(r2["parameters"], rel=1e-12)  # the fit itself is unchanged
    # --dwell-s overrides n/rate: a 4x longer dwell halves σ
    code, out, err = _run(capsys, "calibrate", positions_with_n, "--noise-from", j1, "--dwell-s", 40, "--json")
    r3 = json.loads(out)
    assert code == 0 and r3["noise_from"]["sigma_mean_ug"] == pytest.approx(sigma / 2 * 1e6)
    # a recording works as well as its JSON (same analysis)
    path, _ = static_recording
    code, out, _ = _run(capsys, "noise", path, "--units", "m/s2", "--json")
    jrec = tmp_path / "rec.json"
    jrec.write_text(out)
    code, out_j, err = _run(capsys, "calibrate", positions_with_n, "--noise-from", jrec, "--json")
    # --units names the units of DATA and of the noise recording alike: the recording in g, as the positions are
    samples = np.loadtxt(path, delimiter=",", skiprows=1)
    rec_g = write_recording(tmp_path / "rest_g.csv", samples[:, 1:] / G0)
    code2, out_r, err2 = _run(capsys, "calibrate", positions_with_n, "--noise-from", rec_g, "--json")
    assert code == code2 == 0, (err, err2)
    assert json.loads(out_j)["stderr"] == pytest.approx(json.loads(out_r)["stderr"], rel=1e-9)


def test_info_noise_from_matches_noise_ug(capsys, tmp_path):
    j = _noise_json(tmp_path, 40e-6, "n.json")
    code, out, err = _run(capsys, "info", "--model", "nonlinear12", "--noise-from", j, "--dwell-s", 16, "--json")
    assert code == 0, err
    a = json.loads(out)
    code, out, _ = _run(capsys, "info", "--model", "nonlinear12", "--noise-ug", 10, "--json")
    b = json.loads(out)
    assert a["noise_ug"] == pytest.approx(10.0)  # 40 µg/√Hz / √16 s
    assert a["crlb"] == pytest.approx(b["crlb"], rel=1e-9)


@pytest.mark.parametrize("argv, message", [
    (["info", "--noise-from", "NOISE"], "--dwell-s"),
    (["info", "--noise-from", "NOISE", "--dwell-s", 5, "--noise-ug", 3], "not both"),
    (["calibrate", "POS", "--noise-from", "OTHER"], "not the JSON of an optcal noise"),
    (["calibrate", "POS", "--noise-from", "POS"], "no time column"),
])
def test_noise_from_bad_input(argv, message, capsys, tmp_path, positions_with_n):
    noise = _noise_json(tmp_path, 40e-6, "n.json")
    other = tmp_path / "cal.json"
    other.write_text('{"parameters": {"K_x": 1.0}}')
    argv = [{"NOISE": noise, "POS": positions_with_n, "OTHER": other}.get(a, a) for a in argv]
    code, _, err = _run(capsys, *argv)
    assert code == 2 and err.count("\n") == 1 and message in err, err


# -- colored_noise: the generator of simulated sensor noise -------------------------------------------------
@pytest.mark.parametrize("term, coef, expected", [
    ("white", 100e-6, lambda tau: 100e-6 / np.sqrt(tau)),               # σ = N/√τ
    ("flicker", 20e-6, lambda tau: FLICKER_FACTOR * 20e-6 + 0 * tau),   # σ = 0.664·B
    ("random_walk", 5e-6, lambda tau: 5e-6 * np.sqrt(tau / 3)),         # σ = K·√(τ/3)
])
def test_colored_noise_has_the_allan_deviation_of_its_coefficients(term, coef, expected):
    """1000 s at 100 Hz, three axes, seed fixed: allantools' overlapping ADEV at τ = 0.1, 1 and 10 s against
    the Allan relation of each term; the RMS over the axes within 4 % at 0.1 and 1 s (Greenhall EDF ≥ 600)
    and 10 % at 10 s (EDF ≈ 60-100)."""
    import allantools

    from optcal.core.noise.colored import colored_noise

    y = colored_noise(100_000, FS, np.random.default_rng(11), **{term: coef})
    assert y.shape == (100_000, 3)
    taus = np.array([0.1, 1.0, 10.0])
    adev = np.array([allantools.oadev(y[:, j], rate=FS, data_type="freq", taus=taus)[1] for j in range(3)])
    ratio = np.sqrt(np.mean(adev**2, axis=0)) / expected(taus)
    print(term, "σ_A / relation at", taus, "s:", np.round(ratio, 4))
    assert np.all(np.abs(ratio[:2] - 1) < 0.04), ratio
    assert abs(ratio[2] - 1) < 0.10, ratio


def test_colored_noise_white_plus_flicker_adds_in_allan_variance_and_is_read_back_by_optcal_noise():
    """White + flicker + random walk (N = 60 µg/√Hz, B = 15 µg, K = 1 µg/√s; 10 h at 10 Hz): the noise
    analysis of optcal.noise reads N within 1 %, B within 15 % and K within 40 % on every axis (seed fixed;
    K's part of the curve has only a few independent averages)."""
    from optcal.core.noise.colored import colored_noise

    y = colored_noise(360_000, 10.0, np.random.default_rng(5), white=60e-6, flicker=15e-6, random_walk=1e-6)
    rep = analyse(y + [0.0, 0.0, 1.0], 10.0)
    for a in rep.axes:
        print(a.axis, a.white.value, a.bias_instability.value, a.random_walk.value)
        assert a.white.value == pytest.approx(60e-6, rel=0.01)
        assert a.bias_instability.value == pytest.approx(15e-6, rel=0.15)
        assert a.random_walk.value == pytest.approx(1e-6, rel=0.40)


def test_colored_noise_draws_from_the_generator_only_and_axes_are_independent():
    from optcal.core.noise.colored import colored_noise

    kw = dict(white=1e-4, flicker=2e-5, random_walk=1e-6)
    a = colored_noise(5000, 50.0, np.random.default_rng(3), **kw)
    assert np.array_equal(a, colored_noise(5000, 50.0, np.random.default_rng(3), **kw))
    assert not np.array_equal(a, colored_noise(5000, 50.0, np.random.default_rng(4), **kw))
    c = np.corrcoef(np.diff(a, axis=0).T)  # increments: the flicker and walk parts are not stationary in a short run
    assert np.max(np.abs(c[np.triu_indices(3, 1)])) < 0.05
    assert np.array_equal(colored_noise(7, 1.0, np.random.default_rng(0), axes=2), np.zeros((7, 2)))
    assert colored_noise(1, 1.0, np.random.default_rng(0), flicker=1.0, axes=1).shape == (1, 1)


@pytest.mark.parametrize("kwargs, name", [
    (dict(n=0), "`n`"), (dict(n=2.5), "`n`"), (dict(rate_hz=0.0), "`rate_hz`"), (dict(rate_hz=math.nan), "`rate_hz`"),
    (dict(white=-1.0), "`white`"), (dict(flicker=math.inf), "`flicker`"), (dict(random_walk=-1e-6), "`random_walk`"),
    (dict(axes=0), "`axes`"),
])
def test_colored_noise_bad_input_names_the_parameter(kwargs, name):
    from optcal.core.errors import InputError
    from optcal.core.noise.colored import colored_noise

    args = dict(n=100, rate_hz=10.0) | kwargs
    n, rate = args.pop("n"), args.pop("rate_hz")
    with pytest.raises(InputError, match=re.escape(name)):
        colored_noise(n, rate, np.random.default_rng(0), **args)
