"""Command line: simulate → calibrate round trip, info, and one-line errors (exit 2) for bad input."""

import json

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.core.schemes import rotation_groups


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def positions(tmp_path, capsys):
    path = tmp_path / "p24.csv"
    code, _, _ = _run(capsys, "simulate", "--scheme", 24, "--model", "nonlinear12", "--noise-ug", 10, "--seed", 1,
                      "-o", path, "--truth-out", tmp_path / "truth.json")
    assert code == 0
    return path


def test_calibrate_json_contract(positions, capsys, tmp_path):
    code, out, err = _run(capsys, "calibrate", positions, "--model", "nonlinear12", "--json")
    assert code == 0, err
    res = json.loads(out)
    for key in ("model", "terms", "parameters", "stderr", "rms_residual_g", "cost", "n_positions", "g_local",
                "solver", "observability", "nfev", "nit", "runtime_s", "success", "message"):
        assert key in res
    truth = json.loads((tmp_path / "truth.json").read_text())
    for name, value in res["parameters"].items():
        assert abs(value - truth[name]) < 5 * res["stderr"][name], name
    assert res["n_positions"] == 24 and res["observability"]["rank"] == 12
    assert res["observability"]["unobservable"] == []
    # expected sqrt((24 - 12) / 24) · 10 µg ≈ 7 µg
    assert 3e-6 < res["rms_residual_g"] < 12e-6


def test_calibrate_seed15_names_the_unobservable_directions(positions, capsys):
    code, out, _ = _run(capsys, "calibrate", positions, "--model", "seed15", "--json")
    res = json.loads(out)
    assert code == 0 and res["observability"]["rank"] == 12
    names = sorted(sorted(w["name"] for w in d) for d in res["observability"]["unobservable"])
    assert names == [["S_xy", "S_zy"], ["S_xz", "S_yz"], ["S_yx", "S_zx"]]
    assert res["stderr"]["S_xz"] is None and res["stderr"]["K_x"] is not None


def test_info_reports_three_unobservable_directions_for_seed15(capsys):
    code, out, _ = _run(capsys, "info", "--scheme", 24, "--model", "seed15", "--noise-ug", 10, "--json")
    res = json.loads(out)
    assert code == 0 and res["rank"] == 12 and len(res["unobservable"]) == 3
    assert res["crlb"]["S_xz"] is None and res["crlb"]["K_x"] == pytest.approx(4.18e-6, rel=0.02)


def _write(tmp_path, text, name="bad.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _good_rows(n=24, scale=1.0):
    A = rotation_groups(45.0)[:n] * scale
    return "\n".join(f"{i},{float(a[0])!r},{float(a[1])!r},{float(a[2])!r}" for i, a in enumerate(A))


BAD_INPUTS = {
    "missing column": ("position,ax,ay\n0,1,0\n", "missing column(s) az"),
    "misnamed column": ("position,accx1,accy1,accz1\n" + _good_rows(), "rename 'accx1' → 'ax'"),
    "non-numeric": ("position,ax,ay,az\n" + _good_rows().replace("0,0.0,0.0,1.0", "0,0.0,abc,1.0", 1), "not a number"),
    "nan": ("position,ax,ay,az\n" + _good_rows().replace("0,0.0,0.0,1.0", "0,0.0,nan,1.0", 1), "is nan"),
    "inf": ("position,ax,ay,az\n" + _good_rows().replace("0,0.0,0.0,1.0", "0,0.0,inf,1.0", 1), "is inf"),
    "too few positions": ("position,ax,ay,az\n" + _good_rows(8), "fewer than the 12 parameters"),
    "m/s2 as g": ("position,ax,ay,az\n" + _good_rows(scale=9.80665), "looks like m/s²"),
    "empty": ("", "is empty"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_is_one_line_and_exit_2(case, tmp_path, capsys):
    text, fragment = BAD_INPUTS[case]
    path = _write(tmp_path, text)
    code, out, err = _run(capsys, "calibrate", path, "--model", "nonlinear12")
    assert code == 2
    assert fragment in err, err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_unobservable_positions_name_the_directions(tmp_path, capsys):
    # every position turns about x: the x axis never sees gravity, so K_x and b_x cannot be told apart
    A = rotation_groups(30.0)[:12]
    rows = "\n".join(f"{i},{a[0] + 1e-4},{a[1]},{a[2]}" for i, a in enumerate(A))
    path = _write(tmp_path, "position,ax,ay,az\n" + rows)
    code, _, err = _run(capsys, "calibrate", path, "--model", "diag6")
    assert code == 2 and "unobservable" in err and "K_x" in err and "b_x" in err, err
    assert err.count("\n") == 1


@pytest.mark.parametrize("argv, fragment", [
    (["--model", "linear10"], "unknown model or term 'linear10'"),
    (["--model", "linear9+warp"], "unknown model or term 'warp'"),
    (["--solver", "nope"], "unknown solver 'nope'"),
    (["--option", "nope=1"], "unknown option(s) nope"),
])
def test_unknown_names_are_clear_errors(positions, capsys, argv, fragment):
    code, _, err = _run(capsys, "calibrate", positions, *argv)
    assert code == 2 and fragment in err and err.count("\n") == 1, err


def test_unreadable_file_and_overwrite_refusal(tmp_path, positions, capsys):
    code, _, err = _run(capsys, "calibrate", tmp_path / "missing.csv")
    assert code == 2 and "cannot read" in err
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"\xff\xfe\x00\x81")
    code, _, err = _run(capsys, "calibrate", binary)
    assert code == 2 and "cannot read" in err
    code, _, err = _run(capsys, "simulate", "-o", positions)
    assert code == 2 and "--force" in err
    assert positions.read_text().startswith("position,ax")


def test_simulate_with_hidden_effect_and_counts(tmp_path, capsys):
    out = tmp_path / "eff.csv"
    code, _, err = _run(capsys, "simulate", "--scheme", 36, "--model", "linear9", "--effect", "cubic:K3_x=1e-3",
                        "--seed", 2, "-o", out, "--truth-out", tmp_path / "t.json")
    assert code == 0, err
    truth = json.loads((tmp_path / "t.json").read_text())
    assert truth["K3_x"] == 1e-3 and truth["K3_y"] == 0.0
    code, _, err = _run(capsys, "simulate", "--effect", "cubic:K9=1", "-o", tmp_path / "x.csv")
    assert code == 2 and "not a parameter of cubic" in err


def test_counts_data_needs_units(tmp_path, capsys):
    A = rotation_groups(45.0)
    rows = "\n".join(f"{i},{16384 * a[0] + 20},{16384 * a[1]},{16384 * a[2]}" for i, a in enumerate(A))
    path = _write(tmp_path, "position,ax,ay,az\n" + rows)
    code, _, err = _run(capsys, "calibrate", path, "--model", "linear9")
    assert code == 2 and "--units counts" in err
    # the hand-written counts are exact (residual ~1e-17 g): an exact fit is refused unless forced
    code, _, err = _run(capsys, "calibrate", path, "--model", "linear9", "--units", "counts")
    assert code == 2 and "--force-weak" in err
    code, out, err = _run(capsys, "calibrate", path, "--model", "linear9", "--units", "counts", "--json",
                          "--force-weak")
    assert code == 0, err
    assert json.loads(out)["parameters"]["K_x"] == pytest.approx(16384, rel=1e-9)
    assert np.isclose(json.loads(out)["parameters"]["b_x"], 20 / 16384, rtol=1e-6)


def test_output_cut_short_by_the_reader_is_not_a_traceback():
    """`optcal solvers | head -1`: the reader closes the pipe early; no traceback, SIGPIPE's status."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-c", "import sys; from optcal.app.cli import main; sys.exit(main())",
                             "solvers"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.readline()
    proc.stdout.close()  # the reader goes away after one line
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) in (0, 141)
    assert "Traceback" not in err and "BrokenPipe" not in err


def test_python_dash_m_runs_the_same_command_line(tmp_path):
    """`python -m optcal` is the `optcal` script: the same parser, the same one-line refusal and exit status."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "optcal", "calibrate", str(tmp_path / "absent.csv")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("optcal calibrate: error:") and proc.stderr.count("\n") == 1
    assert "absent.csv" in proc.stderr and "Traceback" not in proc.stderr


def test_study_is_a_plug_in_command(capsys):
    from optcal.app.cli import _command_modules

    mods = dict(_command_modules())
    assert mods["study"].__name__ == "optcal.app.commands.study"
    assert {"calibrate", "simulate", "apply", "nav", "discover", "solvers"} <= set(mods)


@pytest.mark.parametrize("option", [["--columns", "ax=0,ay=1,az=2"], ["--time-unit", "ms"], ["--min-static", "1"],
                                    ["--method", "variance"]])
def test_a_raw_recording_s_option_on_a_positions_file_is_refused(positions, capsys, option):
    """Options that read a raw recording only were dropped without a word on a positions file (a user's
    --columns): refused in one line naming the option and --raw."""
    code, out, err = _run(capsys, "calibrate", positions, *option)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert err.startswith(f"optcal calibrate: error: {option[0]} reads a raw recording: add --raw"), err
