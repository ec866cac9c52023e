"""A term discovery found is a first-class model term (issue 31, docs/discovery.md "Using a found term"): its name
defines it, the NumPy model, the compiled kernel and the symbolic components agree on it, the calibration file
(format version 3) keeps it, and calibrate, apply, info and a study take it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from optcal import simulate
from optcal.app.cli import main
from optcal.core.calfile import read_calibration
from optcal.core.discovery.dictionary import feature_context, feature_values, generate
from optcal.core.errors import InputError
from optcal.core.model import TERMS, Context, NumpyOps, get_model
from optcal.core.presets import draw_truth
from optcal.core.problem import CalibrationProblem
from optcal.core.terms import previous_signs

ALL = "linear9+ax.ay@z+prevax@x+osc600@xyz+temp2s5@x+ay.temp1s5@x+ax.az2@z+time3s500@y"


def test_a_name_defines_the_term():
    t = TERMS["temp2s5@x"]
    assert t.params == ("c_temp2s5@x",) and t.needs == ("temp",) and t.group == "temperature"
    assert t.description == "bias_x += c·((T − T̄)/5 °C)²" and t.param_unit == "g"
    assert t.feature.physical() == (pytest.approx(1 / 25), "g/°C²")
    osc = TERMS["osc2p5@xyz"]
    assert osc.params == ("c_sin2p5@x", "c_cos2p5@x", "c_sin2p5@y", "c_cos2p5@y", "c_sin2p5@z", "c_cos2p5@z")
    assert osc.feature.period == 2.5 and osc.needs == ("t",)
    assert TERMS["ax.az2@z"].param_unit == "1/g²" and TERMS["ax.ay@z"].param_unit == "1/g"
    assert TERMS["prevax@x"].description == "bias_x += c·sgn(A_x of the previous pose)"
    # the table's own iteration is unchanged: the kernel, the docs and the solvers' groups see the built-in terms
    assert "ax.ay@z" in TERMS and "ax.ay@z" not in list(TERMS) and len(TERMS) == 11


@pytest.mark.parametrize("spec,match", [
    ("linear9+ay.ax@z", "write it as ax.ay@z"),
    ("linear9+ax@z", "a constant or a single component"),
    ("linear9+ax.ay@w", "OUTPUT one of x, y, z, xyz"),
    ("linear9+ax2.ay2@x", "more than 3"),
    ("linear9+temp2s5.osc60@x", "at most one factor"),
    ("linear9+cos600@x", "none of ax, ay2"),
    ("linear9+temp2s5@x+temp2s5@xyz", "share parameter"),
])
def test_a_malformed_name_is_one_line(spec, match):
    with pytest.raises(InputError, match=match) as e:
        get_model(spec)
    assert "\n" not in str(e.value) and len(str(e.value)) <= 300


def test_the_three_evaluators_agree():
    """The NumPy model's vectorised form, the term table's components and the compiled kernel (residuals and the
    analytic Jacobian, norm and turntable residuals) on a model holding every kind of feature."""
    model = get_model(ALL)
    rng = np.random.default_rng(7)
    truth = {n: 1 + 1e-3 * rng.normal() if n.startswith("K_") else 1e-3 * rng.normal() for n in model.names}
    for reference in (False, True):
        sim = simulate(model, truth, rng, scheme="random:40", noise_g=1e-5, temp=(20.0, 40.0), times=True,
                       reference=reference)
        x = sim.truth_vector(model)
        ctx = Context.from_columns(temp=sim.data.temp, t=sim.data.t)
        A = sim.A
        P = {n: x[k] for k, n in enumerate(model.names)}
        C = np.stack(model.components(P, (A[:, 0], A[:, 1], A[:, 2]), ctx), -1)
        assert np.abs(C - model.forward(x, A, ctx)[0]).max() < 1e-15
        kernel = CalibrationProblem(model, sim.data, reference=reference)
        oracle = CalibrationProblem(model, sim.data, reference=reference, backend="numpy")
        X = x + 1e-4 * rng.normal(size=(4, model.n_params))
        assert np.abs(kernel.residuals_full(X) - oracle.residuals_full(X)).max() < 1e-14
        Jk, Jn = kernel.jacobian_full(x), oracle.jacobian_full(x)
        assert np.abs(Jk - Jn).max() < 1e-12 * np.abs(Jn).max()
    # the inverse recovers the specific force through every feature, the previous pose's sign included
    N = model.forward(x, A, ctx)[0]
    assert np.abs(model.inverse(x, N, ctx)[0] - A).max() < 1e-14


def test_the_dictionary_evaluates_what_the_terms_define():
    """The dictionary's vectorised feature matrix equals each term's own values (Feature.values)."""
    rng = np.random.default_rng(3)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", temp=(20.0, 40.0), times=True)
    d = generate(get_model("linear9"), sim.data, periods=(600.0, 95.5), n_independent=19)
    assert {TERMS[a.term].feature.prev is not None for a in d.atoms} == {True, False}
    ctx = feature_context(sim.data)
    phi, L = feature_values(d.atoms, sim.A, ctx)
    col = 0
    for atom in d.atoms:
        term = TERMS[atom.term]
        for _ in term.axes:
            for kind in term.feature.kinds:
                v = term.feature.values((sim.A[:, 0], sim.A[:, 1], sim.A[:, 2]), ctx, kind, NumpyOps)
                assert np.allclose(phi[:, col], v, rtol=1e-13, atol=1e-15), atom.term
                col += 1
    assert col == phi.shape[1]
    # the previous pose: its sign on each axis, none below a quarter of g and none for the first pose; positions
    # within 2° in a row are one pose (the third is the second's pose held on: its previous pose is the first)
    A = np.array([[0.9, 0.0, 0.436], [-0.1, 0.6, -0.794], [-0.1, 0.601, -0.793], [0.3, -0.9, 0.316]])
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    s = previous_signs(A.T)
    assert s[0].tolist() == [0.0, 1.0, 1.0, 0.0] and s[1].tolist() == [0.0, 0.0, 0.0, 1.0]
    assert s[2].tolist() == [0.0, 1.0, 1.0, -1.0]


def test_the_calibration_file_keeps_a_user_term(tmp_path, capsys):
    rng = np.random.default_rng(11)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", noise_g=1e-5,
                   effects={"ax.ay@z": {"c_ax.ay@z": 3e-4}})
    pos = tmp_path / "p.csv"
    sim.data.to_csv(pos)
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(pos), "--model", "linear9+ax.ay@z", "-o", str(cal)]) == 0
    d = json.loads(cal.read_text())
    assert d["format_version"] == 3 and d["user_terms"] == {"ax.ay@z": "z output += c·A_x·A_y"}
    assert d["units"]["parameters"]["c_ax.ay@z"] == "1/g"
    back = read_calibration(cal)
    assert back.model.name == "scale+bias+misalignment+ax.ay@z"
    assert back.parameters["c_ax.ay@z"] == pytest.approx(3e-4, abs=4 * back.stderr[-1])
    # applied: the positions' specific force has the magnitude of gravity to the noise
    out = tmp_path / "a.csv"
    assert main(["apply", str(cal), str(pos), "-o", str(out)]) == 0
    A = np.loadtxt(out, delimiter=",", skiprows=1)[:, :3]
    assert np.abs(np.linalg.norm(A, axis=1) - 1.0).max() < 5e-5
    # a file of built-in terms stays version 2; version 2 with a user term, or a formula that is not the name's,
    # is refused in one line
    capsys.readouterr()
    for bad, match in (({**d, "format_version": 2}, "format_version 2 has no user-defined terms"),
                       ({**d, "user_terms": {"ax.ay@z": "z output += c·A_x"}}, "user_terms disagree"),
                       ({k: v for k, v in d.items() if k != "user_terms"}, "user_terms disagree")):
        f = tmp_path / "bad.json"
        f.write_text(json.dumps(bad))
        with pytest.raises(InputError, match=match):
            read_calibration(f)
    plain = tmp_path / "plain.json"
    assert main(["calibrate", str(pos), "--model", "linear9", "-o", str(plain)]) == 0
    assert json.loads(plain.read_text())["format_version"] == 2


def test_a_previous_pose_term_is_not_applied_to_samples(tmp_path):
    rng = np.random.default_rng(2)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", noise_g=1e-5,
                   effects={"prevax@x": {"c_prevax@x": 5e-5}})
    pos = tmp_path / "p.csv"
    sim.data.to_csv(pos)
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(pos), "--model", "linear9+prevax@x", "-o", str(cal)]) == 0
    with pytest.raises(InputError, match="needs static poses in order"):
        read_calibration(cal).apply(sim.data.N)


def test_end_to_end_discover_calibrate_apply_info(tmp_path, capsys):
    """The found term used as the report says: discover names it, calibrate fits it, apply applies the file, info
    gives its Cramér-Rao bound."""
    rng = np.random.default_rng(5)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", noise_g=1e-5,
                   effects={"ax.ay@z": {"c_ax.ay@z": 4e-4}})
    pos = tmp_path / "p.csv"
    sim.data.to_csv(pos)
    assert main(["discover", str(pos), "--noise-ug", "10", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    term = out["found"][0]["term"]
    assert term == "ax.ay@z" and out["closes_gap"] is True and out["verdict"] == "explained down to noise"
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(pos), "--model", f"linear9+{term}", "-o", str(cal)]) == 0
    assert main(["apply", str(cal), str(pos), "-o", str(tmp_path / "a.csv")]) == 0
    capsys.readouterr()
    assert main(["info", "--scheme", "random:40", "--model", f"linear9+{term}", "--noise-ug", "10"]) == 0
    text = capsys.readouterr().out
    line = next(ln for ln in text.splitlines() if ln.startswith("c_ax.ay@z"))
    assert "unobservable" not in line and "1/g" in line
    # the 24-position scheme has a zero component in every pose: A_x·A_y·A_z = 0, the term cannot be seen
    assert main(["info", "--scheme", "24", "--model", f"linear9+{term}", "--noise-ug", "10"]) == 0
    assert "c_ax.ay@z    unobservable" in capsys.readouterr().out


def test_a_found_terms_parameter_in_a_study(tmp_path):
    """A study spec with the term in its model: every solver fits it and its parameter is scored against the
    Cramér-Rao bound like any other."""
    from optcal import study

    spec = tmp_path / "userterm.toml"
    spec.write_text("""name = "userterm"
description = "a found term's parameter in a study"
runs = 3
quick_runs = 2
seed = 31
models = ["linear9+ax.ay@z"]
schemes = ["random:40"]
truth = "draw"
presets = "none"
noise_ug = 10.0
tilt_deg = 0.0
budget = 4000

[executor]
kind = "serial"

[[solvers]]
name = "scipy-lm"

[[solvers]]
name = "pso"
""")
    res = study(spec)
    t = res.trials
    assert len(t) == 6 and set(t["solver"]) == {"scipy-lm", "pso"} and (t["status"] == "ok").all()
    k = t.iloc[0]["names"].index("c_ax.ay@z")
    ratios = [abs(r["err"][k]) / r["crlb"][k] for _, r in t.iterrows()]
    assert all(np.isfinite(ratios)) and max(ratios) < 4
    assert res.summary["accuracy"].between(0.5, 2.0).all()


def test_cli_options_of_the_dictionary(tmp_path, capsys):
    from optcal.app.commands import discover as command
    from optcal.app.workflows import discovery as workflow

    assert command.MAX_DICTIONARY_TERMS == workflow.MAX_DICTIONARY_TERMS
    rng = np.random.default_rng(4)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", noise_g=1e-5, times=True,
                   effects={"osc600@x": {"c_sin600@x": 6e-5}})
    pos = tmp_path / "p.csv"
    sim.data.to_csv(pos)
    png = tmp_path / "d.png"
    assert main(["discover", str(pos), "--noise-ug", "10", "--diagnostics", str(png)]) == 0
    text = capsys.readouterr().out
    assert "found: bias_x += a·sin(2π·(t − t0)/" in text and png.stat().st_size > 30_000
    assert main(["discover", str(pos), "--noise-ug", "10", "--no-dictionary", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["found"] == [] and out["dictionary"] is None and out["diagnostics"]["items"][0]["name"] == "orientation"
    for argv, match in ((["--max-dictionary-terms", "-1"], "give 0 or more"),
                        (["--diagnostics", str(tmp_path / "d.txt")], "use a .png"),
                        (["--diagnostics", str(png)], "--force")):
        assert main(["discover", str(pos), *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and match in err


def test_casadi_evaluates_user_terms():
    """The CasADi solver calls the term table's components on its symbols: the same fit as lm on a model with a
    product, a sinusoid and a temperature power; a previous-pose term, which needs the positions' order, is
    refused with its reason."""
    pytest.importorskip("casadi")
    from optcal.app.fit import calibrate

    rng = np.random.default_rng(2)
    sim = simulate("linear9", draw_truth("linear9", rng), rng, scheme="random:40", noise_g=1e-5, temp=(20.0, 40.0),
                   times=True, effects={"ax.ay@z": {"c_ax.ay@z": 3e-4}, "osc600@x": {"c_sin600@x": 4e-5}})
    model = "linear9+ax.ay@z+osc600@x+temp2s5@x"
    a = calibrate(sim.data, model, solver="lm")
    b = calibrate(sim.data, model, solver="casadi-ipopt")
    assert np.abs(a.x - b.x).max() < 1e-8 and a.model.index("c_ax.ay@z") == 9
    c = calibrate(sim.data, "linear9+prevax@x", solver="casadi-ipopt")
    assert "needs the previous pose" in c.result.message
