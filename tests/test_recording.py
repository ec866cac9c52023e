"""Raw recordings: reading (formats, columns, rate), static-interval detection (Tedaldi et al. 2014),
intervals by hand, saturation, positions, local gravity, and every bad input through the CLI."""

import json

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.commands._dataopts import load_positions, parse_ks
from optcal.app.fit import calibrate
from optcal.app.workflows.recording import choose_threshold
from optcal.core import gravity
from optcal.core.errors import InputError
from optcal.core.model import get_model
from optcal.core.recording import (
    describe_detection,
    detect_static,
    given_intervals,
    label_intervals,
    positions_from_recording,
    read_intervals,
    read_recording,
    variance_statistic,
)
from optcal.core.schemes import scheme

K0 = 16384.0
TRUTH = {"K_x": 16301.0, "K_y": 16452.0, "K_z": 16690.0, "b_x": 0.021, "b_y": -0.013, "b_z": 0.042,
         "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3}


def _smooth(a, b, n):
    """Unit vectors from a to b (normalised linear interpolation; the sensor being turned)."""
    s = (0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n)))[:, None]
    v = (1 - s) * a + s * b
    v = np.where(np.linalg.norm(v, axis=1, keepdims=True) < 1e-6, a + 1e-3, v)
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def synth(rng, *, dirs=None, rate=100.0, dwell_s=3.0, move_s=1.5, init_s=4.0, noise_g=2e-3, start_moving=False,
          moving_only=False):
    """A raw int16 recording of a linear9 sensor turned by hand through ``dirs`` (default: the 24-position
    scheme): rests of ``dwell_s`` joined by ``move_s`` of turning with 0.2 g of hand shake. Returns the
    time, counts, the true static spans [start, end) and the truth vector."""
    m = get_model("linear9")
    x = m.from_dict(TRUTH)
    dirs = scheme("24") if dirs is None else dirs
    nd, nm = int(dwell_s * rate), int(move_s * rate)
    parts, spans, pos = [], [], 0
    if start_moving:
        parts.append(_smooth(dirs[-1], dirs[0], 3 * nm) + 0.3 * rng.standard_normal((3 * nm, 3)))
        pos += 3 * nm
    first = int(init_s * rate) + nd
    parts.append(np.repeat(dirs[:1], first, 0))
    spans.append((pos, pos + first))
    pos += first
    if moving_only:
        k = int(60 * rate)
        th = np.linspace(0, 6 * np.pi, k)
        parts.append(np.stack([np.sin(th), np.cos(th) * 0.6, np.cos(th) * 0.8], 1))
    else:
        for a, b in zip(dirs[:-1], dirs[1:]):
            shake = 0.2 * np.sin(2 * np.pi * 3.0 * np.arange(nm) / rate + rng.uniform(0, 6, 3)[:, None]).T
            parts.append(_smooth(a, b, nm) + shake * np.sin(np.linspace(0, np.pi, nm))[:, None])
            parts.append(np.repeat(b[None], nd, 0))
            spans.append((pos + nm, pos + nm + nd))
            pos += nm + nd
    A = np.concatenate(parts)
    N = m.forward(x, A + noise_g * rng.standard_normal(A.shape))[0]
    N = np.clip(np.round(N), -32768, 32767)
    t = np.arange(len(N)) / rate
    return t, N, np.array(spans), x


def write(path, t, N, header="t,ax,ay,az", delim=",", fmt=None, pre=""):
    cols = N if t is None else np.column_stack([t, N])
    with open(path, "w") as fh:
        fh.write(pre)
        if header:
            fh.write(header.replace(",", delim) + "\n")
        np.savetxt(fh, cols, delimiter=delim, fmt=fmt or (["%.2f"] + ["%d"] * 3 if t is not None else "%d"))
    return str(path)


@pytest.fixture(scope="module")
def rec24(tmp_path_factory):
    rng = np.random.default_rng(2024)
    t, N, spans, x = synth(rng)
    path = write(tmp_path_factory.mktemp("rec") / "rec24.csv", t, N)
    return path, t, N, spans, x


def _err_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# -- reading --------------------------------------------------------------------------------------------
def test_reads_csv_with_header_and_time(rec24):
    path, t, N, _, _ = rec24
    rec = read_recording(path, units="counts")
    np.testing.assert_array_equal(rec.N, N)
    np.testing.assert_allclose(rec.t, np.round(t, 2))
    assert rec.rate == pytest.approx(100.0) and rec.columns == {"t": "t", "ax": "ax", "ay": "ay", "az": "az"}
    assert not rec.saturated.any()


def test_formats_columns_and_rate(tmp_path, rec24):
    _, t, N, _, _ = rec24
    n = 3000
    # whitespace-separated, no header, three columns, rate given
    p1 = write(tmp_path / "ws.txt", None, N[:n], header="", delim=" ")
    r1 = read_recording(p1, rate=50.0, units="counts")
    assert r1.rate == 50.0 and r1.t[-1] == pytest.approx((n - 1) / 50)
    np.testing.assert_array_equal(r1.N, N[:n])
    # leading key,value lines (as the MPU-6050 logger writes them): Fs gives the rate
    p2 = write(tmp_path / "meta.csv", None, N[:n], header="ax,ay,az", pre="Fs,200\nLogging Type,0\n")
    r2 = read_recording(p2, units="counts")
    assert r2.rate == 200.0 and r2.meta["fs"] == "200"
    # extra columns, chosen by name, by index and by role; a string label column is skipped
    M = np.column_stack([np.arange(n), np.arange(n), t[:n] * 1000, N[:n], 20 + 0.001 * np.arange(n)])
    p3 = tmp_path / "wide.csv"
    with open(p3, "w") as fh:
        fh.write("part,idx,time_ms,ax,ay,az,temp\n")
        for i in range(0, n, 1000):
            np.savetxt(fh, M[i:i + 1000], delimiter=",", fmt=["s%d", "%d", "%.1f", "%d", "%d", "%d", "%.3f"])
    by_name = read_recording(p3, columns="ax,ay,az", rate=100, units="counts")
    by_index = read_recording(p3, columns="3,4,5", rate=100, units="counts")
    by_role = read_recording(p3, columns="ax=ax,ay=4,az=az,temp=temp", rate=100, units="counts")
    for r in (by_name, by_index, by_role):
        np.testing.assert_array_equal(r.N, N[:n])
    assert by_role.temp is not None and by_role.temp[-1] == pytest.approx(20 + 0.001 * (n - 1))
    # a time column in ms is read as ms: its 10 ms steps are the given 100 Hz (issue #13; it used to be refused)
    ms = read_recording(p3, columns="time_ms,ax,ay,az", rate=100, units="counts")
    assert ms.reading["time_unit"] == "ms" and ms.rate == pytest.approx(100.0) and ms.t[-1] == pytest.approx(29.99)
    with pytest.raises(InputError, match="none of them the rate 37 Hz"):  # a rate no unit of the column gives
        read_recording(p3, columns="time_ms,ax,ay,az", rate=37, units="counts")
    with pytest.raises(InputError, match="not numeric"):
        read_recording(p3, columns="part,ax,ay,az", units="counts")
    with pytest.raises(InputError, match="did you mean 'ay'"):
        read_recording(p3, columns="ax,ayy,az", rate=100, units="counts")
    with pytest.raises(InputError, match="out of range"):
        read_recording(p3, columns="0,3,4,9", units="counts")
    with pytest.raises(InputError, match="no time column; give the sample rate"):
        read_recording(p3, columns="ax,ay,az", units="counts")


def test_fast_reader_and_numpy_reader_agree(tmp_path, rec24, monkeypatch):
    from optcal.core.recording import reading

    _, t, N, _, _ = rec24
    n = 2000
    body = "\n".join(f"{t[i]:.2f},{int(N[i, 0])},{int(N[i, 1])},{int(N[i, 2])}" for i in range(n))
    files = {
        "quoted.csv": '"t","ax","ay","az"\n' + body + "\n",
        "preamble.csv": "Fs,100\n\nnote,x\n" + "t,ax,ay,az\n" + body + "\n",  # a blank line in the preamble
        "comments.csv": "t,ax,ay,az\n" + body.replace("\n", "\n# a comment\n", 3) + "\n",
        "semicolon.csv": "t;ax;ay;az\n" + body.replace(",", ";") + "\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        fast = read_recording(tmp_path / name, units="counts")
        with monkeypatch.context() as m:
            m.setattr(reading, "_arrow_csv", None)
            slow = read_recording(tmp_path / name, units="counts")
        np.testing.assert_array_equal(fast.N, N[:n], err_msg=name)
        np.testing.assert_array_equal(slow.N, N[:n], err_msg=name)
        np.testing.assert_array_equal(fast.t, slow.t, err_msg=name)


def test_variance_statistic_matches_direct_computation(rng):
    N = rng.standard_normal((500, 3)) * [1.0, 2.0, 3.0] + [1e4, -2e4, 5e3]
    w = 21
    s = variance_statistic(N, w)
    direct = np.array([np.linalg.norm(N[i - 10:i + 11].var(axis=0)) for i in range(10, 490)])
    np.testing.assert_allclose(s[10:490], direct, rtol=1e-9)
    assert np.isnan(s[:10]).all() and np.isnan(s[490:]).all()


# -- detection ------------------------------------------------------------------------------------------
def test_detection_finds_every_pose_and_stays_inside_the_rests(rec24):
    path, _, _, spans, x = rec24
    rec = read_recording(path, units="counts")
    det = detect_static(rec, k=4)
    assert det.n_intervals == 24
    iv = det.intervals
    # each detected interval lies inside its true rest, and covers most of it (a window's width is lost)
    assert np.all(iv[:, 0] >= spans[:, 0]) and np.all(iv[:, 1] <= spans[:, 1])
    cover = (iv[:, 1] - iv[:, 0]) / (spans[:, 1] - spans[:, 0])
    assert np.all(cover[1:] > 0.6), cover
    # the calibration from the detected positions recovers the truth within 4 standard errors
    data = positions_from_recording(rec, det)
    assert len(data) == 24 and np.all(data.n_samples == iv[:, 1] - iv[:, 0])
    np.testing.assert_allclose(data.t, [rec.t[s:e].mean() for s, e in iv])
    cal = calibrate(data, "linear9")
    z = (cal.x - x) / cal.stderr
    assert np.all(np.abs(z) < 4), dict(zip(cal.model.names, z))


def test_threshold_search_picks_a_clean_threshold(rec24):
    path, _, _, spans, _ = rec24
    rec = read_recording(path, units="counts")
    det = choose_threshold(rec, "linear9", ks=(2, 4, 8, 1e4))
    assert [r["k"] for r in det.search] == [2, 4, 8, 1e4]
    # k = 1e4 calls the moves static: the recording becomes one interval, too few to fit
    assert det.search[-1]["n_intervals"] < 9 and det.search[-1]["score"] is None
    assert det.k in (2, 4, 8) and det.n_intervals == 24
    scores = [r["score"] for r in det.search if r["score"] is not None]
    assert det.search[[r["k"] for r in det.search].index(det.k)]["score"] == min(scores)
    # a custom score: the candidate it prefers is kept
    det2 = choose_threshold(rec, "linear9", lambda d: -float(np.sum(d.n_samples)), ks=(2, 8))
    assert det2.k == 8
    text = describe_detection(det)
    assert "24 static interval(s)" in text and f"k = {det.k:g}" in text and "k searched" in text


def test_parse_threshold_multipliers():
    assert parse_ks(None) == tuple(float(k) for k in range(2, 11))
    assert parse_ks("2:4") == (2.0, 3.0, 4.0) and parse_ks("3") == (3.0,) and parse_ks("1.5,6") == (1.5, 6.0)
    with pytest.raises(InputError, match="threshold-k"):
        parse_ks("two")
    with pytest.raises(InputError, match="positive"):
        parse_ks("0:3")


def test_saturated_samples_are_flagged_and_their_interval_dropped(tmp_path, rec24, capsys):
    _, t, N, spans, _ = rec24
    N = N.copy()
    s, e = spans[5]
    # the z output sits on the int16 rail through the 6th rest: quiet (it passes the variance test) but
    # its mean is wrong, so the interval must go
    N[s:e, 2] = 32767
    path = write(tmp_path / "sat.csv", t, N)
    rec = read_recording(path, units="counts")
    assert rec.saturated.sum() == e - s and rec.saturated[s:e].all()
    det = detect_static(rec, k=4)
    assert det.n_intervals == 23
    assert not np.any((det.intervals[:, 1] > s) & (det.intervals[:, 0] < e))
    assert any("saturated sample(s)" in n for n in det.notes)
    # a --saturation value flags samples beyond it
    rec2 = read_recording(path, units="counts", saturation=20000)
    assert rec2.saturated.sum() == e - s
    # the CLI says so, and fits the 23 clean intervals
    assert main(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9", "--threshold-k", "4"]) == 0
    out = capsys.readouterr().out
    assert "23 static interval(s)" in out and f"{e - s} saturated sample(s)" in out and "note: interval" in out
    # saturation that leaves too few intervals is an error that counts them
    # (a ±0.67 g range: every pose of the 24-position scheme has an axis beyond it)
    assert main(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9", "--saturation", "11000"]) == 2
    err = _err_line(capsys)
    assert "found 0 static interval(s)" in err and "needs at least 12" in err


# -- intervals by hand ----------------------------------------------------------------------------------
def test_intervals_by_hand_in_every_format(tmp_path, rec24):
    path, _, _, spans, _ = rec24
    rec = read_recording(path, units="counts")
    iv = spans[:10] + [50, -50]
    files = {
        "list.json": json.dumps(iv.tolist()),
        "dicts.json": json.dumps([{"start": int(s), "end": int(e)} for s, e in iv]),
        "sections.json": json.dumps({**{f"p{i}": {"start": int(s), "end": int(e)} for i, (s, e) in enumerate(iv)},
                                     "x_rot": {"start": 0, "end": 10}}),
        "pairs.csv": "start,end\n" + "\n".join(f"{s},{e}" for s, e in iv),
        "rows.txt": "\n".join(f"{s} {e}" for s, e in iv),
        "two_rows.csv": ",".join(str(s) for s in iv[:, 0]) + "\n" + ",".join(str(e) for e in iv[:, 1]),
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text)
        got, names = read_intervals(tmp_path / name)
        np.testing.assert_array_equal(got, iv, err_msg=name)
        if name == "sections.json":
            assert names == [f"p{i}" for i in range(10)]  # imucal's *_rot sections are rotations: skipped
    det = given_intervals(rec, iv)
    data = positions_from_recording(rec, det)
    np.testing.assert_allclose(data.N[3], rec.N[iv[3, 0]:iv[3, 1]].mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(data.std[3], rec.N[iv[3, 0]:iv[3, 1]].std(axis=0, ddof=1), rtol=1e-12)
    with pytest.raises(InputError, match="outside the recording"):
        given_intervals(rec, [[0, 10], [5, len(rec) + 1]])
    (tmp_path / "bad.csv").write_text("from,to\n1,2\n")
    with pytest.raises(InputError, match="start and end"):
        read_intervals(tmp_path / "bad.csv")


def test_label_column_gives_intervals(tmp_path, rec24):
    _, _, N, spans, _ = rec24
    n = spans[3, 1]
    lab = np.full(n, "move", dtype=object)
    for i, (s, e) in enumerate(spans[:4]):
        lab[s:e] = f"pose{i}"
    p = tmp_path / "lab.csv"
    with open(p, "w") as fh:
        fh.write("part,ax,ay,az\n")
        fh.writelines(f"{lab[i]},{int(a)},{int(b)},{int(c)}\n" for i, (a, b, c) in enumerate(N[:n]))
    rec = read_recording(p, rate=100, units="counts", labels="part")
    det = label_intervals(rec, ["pose0", "pose2"])
    np.testing.assert_array_equal(det.intervals, spans[[0, 2]])
    assert det.names == ["pose0", "pose2"]
    assert label_intervals(rec).n_intervals == 7  # four poses and the three moves between them
    with pytest.raises(InputError, match="do not occur"):
        label_intervals(rec, ["pose9"])


def test_plot_and_cli_raw_calibration(tmp_path, rec24, capsys):
    path = rec24[0]
    png, cal = tmp_path / "rec.png", tmp_path / "cal.json"
    code = main(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9", "--plot", str(png),
                 "-o", str(cal)])
    assert code == 0
    out = capsys.readouterr().out
    # segmentation is the default detector (issue #20): no threshold search
    assert "24 static interval(s)" in out and "change-point segmentation" in out and "residual RMS" in out
    assert "k searched" not in out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    assert json.loads(cal.read_text())["units"]["raw"] == "counts"  # format version 2 (ced30cc) names it units.raw


# -- local gravity --------------------------------------------------------------------------------------
def test_normal_gravity_against_published_values(monkeypatch):
    # WGS84 (NIMA TR8350.2, Table 3.4): normal gravity at the equator and at the poles
    assert gravity.normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert gravity.normal_gravity(90.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert gravity.normal_gravity(-90.0) == pytest.approx(9.8321849378, abs=1e-9)
    # 45°: the Somigliana closed form against the WGS84 series of TR8350.2 Eq. 4-2
    s2 = np.sin(np.radians(45.0)) ** 2
    series = 9.7803253359 * (1 + 0.0053024 * s2 - 0.0000058 * np.sin(np.radians(90.0)) ** 2)
    assert gravity.normal_gravity(45.0) == pytest.approx(9.8061977694, abs=1e-9)
    assert gravity.normal_gravity(45.0) == pytest.approx(series, abs=2e-6)
    # The often-quoted 9.806199203 m/s² at 45° is GRS80's (Moritz 1980): the same formula with GRS80's
    # constants must give it, and GRS80's polar value 9.8321863685.
    monkeypatch.setattr(gravity, "GAMMA_E", 9.7803267715)
    monkeypatch.setattr(gravity, "K_SOMIGLIANA", 0.001931851353)
    monkeypatch.setattr(gravity, "E2_WGS84", 0.00669438002290)
    assert gravity.normal_gravity(45.0) == pytest.approx(9.806199203, abs=1e-9)
    assert gravity.normal_gravity(90.0) == pytest.approx(9.8321863685, abs=1e-9)


def test_height_correction_and_local_gravity_options():
    # free-air gradient about 0.3086 mGal/m
    dg = gravity.normal_gravity(45.0, 1000.0) - gravity.normal_gravity(45.0)
    assert dg == pytest.approx(-3.086e-3, rel=2e-3)
    assert gravity.local_gravity_g(9.81) == pytest.approx(9.81 / 9.80665, rel=1e-15)
    assert gravity.local_gravity_g(latitude_deg=0.0) == pytest.approx(9.7803253359 / 9.80665, rel=1e-12)
    assert gravity.local_gravity_g() == 1.0
    with pytest.raises(InputError, match="not both"):
        gravity.local_gravity_g(9.81, 45.0)
    with pytest.raises(InputError, match="m/s²"):
        gravity.local_gravity_g(1.0)


# -- bad input, through the CLI: exit status 2 and one line on stderr -----------------------------------
def _cli(args, capsys):
    code = main(args)
    return code, _err_line(capsys)


def test_bad_input_empty_and_single_column(tmp_path, capsys):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    one = tmp_path / "one.csv"
    one.write_text("ax\n" + "\n".join(str(v) for v in range(100)) + "\n")
    for path, msg in ((empty, "is empty"), (one, "single column")):
        code, err = _cli(["calibrate", str(path), "--raw", "--units", "counts", "--rate", "100"], capsys)
        assert code == 2 and msg in err
    header_only = tmp_path / "header.csv"
    header_only.write_text("t,ax,ay,az\n")
    code, err = _cli(["calibrate", str(header_only), "--raw", "--units", "counts"], capsys)
    assert code == 2 and "no numeric rows" in err


def test_bad_input_non_monotonic_time(tmp_path, rec24, capsys):
    _, t, N, _, _ = rec24
    t = t.copy()
    t[500], t[501] = t[501], t[500]
    path = write(tmp_path / "swap.csv", t, N)
    code, err = _cli(["calibrate", path, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "does not increase from sample 500" in err


def test_bad_input_non_numeric_and_nan(tmp_path, rec24, capsys):
    _, t, N, _, _ = rec24
    path = write(tmp_path / "ok.csv", t[:3000], N[:3000])
    lines = open(path).read().splitlines()
    lines[200] = "1.99,12,abc,16000"
    (tmp_path / "text.csv").write_text("\n".join(lines) + "\n")
    code, err = _cli(["calibrate", str(tmp_path / "text.csv"), "--raw", "--units", "counts"], capsys)
    assert code == 2 and "abc" in err
    lines[3] = "0.02,12,,16000"  # an empty cell among the first rows: an error, not a skipped preamble
    (tmp_path / "empty_cell.csv").write_text("\n".join(lines) + "\n")
    code, err = _cli(["calibrate", str(tmp_path / "empty_cell.csv"), "--raw", "--units", "counts"], capsys)
    assert code == 2 and "line 4" in err and "empty or text cell" in err
    lines[3] = "0.02,12,13,16000"
    lines[200] = "1.99,12,nan,16000"
    (tmp_path / "nan.csv").write_text("\n".join(lines) + "\n")
    code, err = _cli(["calibrate", str(tmp_path / "nan.csv"), "--raw", "--units", "counts"], capsys)
    assert code == 2 and "nan" in err


def test_bad_input_no_rest_at_the_start(tmp_path, capsys):
    """A rest period given with --init-s (which asks for the variance detector) must be at rest; without it
    segmentation (the default since issue #20) needs no rest at the start, and the variance detector
    without --init-s takes the quietest windows as its reference (issue #13; tests/test_recording_formats.py
    checks the intervals)."""
    t, N, _, _ = synth(np.random.default_rng(5), start_moving=True)
    path = write(tmp_path / "moving.csv", t, N)
    code, err = _cli(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9", "--init-s", "2"], capsys)
    assert code == 2 and "are not at rest" in err and "--init-s" in err
    assert main(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9"]) == 0
    out = capsys.readouterr().out
    assert "24 static interval(s)" in out and "change-point segmentation" in out
    from optcal.app.workflows.recording import positions_from_raw

    data = positions_from_raw(path, units="counts", model="linear9", method="variance")
    assert len(data) == 24 and "quietest windows" in describe_detection(data)


def test_bad_input_no_static_intervals(tmp_path, capsys):
    t, N, _, _ = synth(np.random.default_rng(6), moving_only=True)
    path = write(tmp_path / "turning.csv", t, N)
    code, err = _cli(["calibrate", path, "--raw", "--units", "counts", "--model", "linear9"], capsys)
    assert code == 2 and "found 1 static interval(s)" in err and "needs at least 12" in err
    # the one interval is the rest at the start and the rest of the recording turns: it holds just that pose, and
    # the way out is more poses (issue #29: no other detector or setting would find another)
    # (12: linear9's parameters and the 3 residual degrees of freedom its fit asks for, the fit's own number)
    assert "the recording holds rests in just 1 orientation(s); record at least 12, in different orientations" in err


def test_bad_input_too_few_poses_says_how_many(tmp_path, capsys):
    t, N, _, _ = synth(np.random.default_rng(7), dirs=scheme("6"))
    path = write(tmp_path / "six.csv", t, N)
    code, err = _cli(["calibrate", path, "--raw", "--units", "counts", "--model", "nonlinear12"], capsys)
    assert code == 2 and "found 6 static interval(s)" in err and "needs at least 15" in err


def test_bad_input_ms2_declared_as_counts(tmp_path, rec24, capsys):
    _, t, N, _, _ = rec24
    path = write(tmp_path / "ms2.csv", t, N / K0 * 9.80665, fmt="%.6f")
    code, err = _cli(["calibrate", path, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "looks like m/s²" in err and "--units m/s2" in err


def test_quantised_still_start_and_constant_recording(tmp_path, rec24, capsys):
    _, t, N, spans, _ = rec24
    N = N.copy()
    N[: spans[0, 1]] = N[0]  # a coarse ADC holds the first rest exactly constant: ς_init = 0
    rec = read_recording(write(tmp_path / "still.csv", t, N), units="counts")
    det = detect_static(rec, k=4)
    assert det.init_variance > 0 and det.n_intervals == 24
    const = np.tile(N[:1], (2000, 1))
    code, err = _cli(["calibrate", write(tmp_path / "const.csv", t[:2000], const), "--raw", "--units", "counts"],
                     capsys)
    assert code == 2 and "never change" in err


def test_load_positions_uses_the_raw_path(rec24):
    import argparse

    from optcal.app.commands._dataopts import add_data_options

    p = argparse.ArgumentParser()
    add_data_options(p)
    p.add_argument("--model", default="linear9")
    args = p.parse_args(["--raw", "--units", "counts", "--threshold-k", "4"])
    data = load_positions(args, rec24[0])
    assert len(data) == 24 and data.units == "counts" and data.extra["detection"].k == 4
    assert "24 static interval(s)" in describe_detection(data)


# -- the library and the command line: parameters, options and imports ---------------------------------------
def test_library_errors_name_parameters_and_the_cli_names_options(tmp_path, rec24, capsys):
    import argparse
    import inspect

    from optcal.app.commands._dataopts import add_data_options, flags, with_flags
    from optcal.app.workflows.recording import positions_from_raw

    _, t, N, _, _ = rec24
    p = write(tmp_path / "norate.csv", None, N[:3000], header="ax,ay,az")
    with pytest.raises(InputError) as exc:
        read_recording(p, units="counts")
    assert "give the sample rate in Hz with `rate`" in str(exc.value) and "--" not in str(exc.value)
    code, err = _cli(["calibrate", p, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "give the sample rate in Hz with --rate" in err and "`" not in err
    with pytest.raises(InputError, match="`window_s` must be a positive number of seconds, got 0"):
        positions_from_raw(rec24[0], units="counts", threshold_k=4, window_s=0.0)
    code, err = _cli(["calibrate", rec24[0], "--raw", "--units", "counts", "--threshold-k", "4", "--window", "0"],
                     capsys)
    assert code == 2 and "--window must be a positive number of seconds, got 0" in err
    with pytest.raises(InputError, match="`threshold_k` -1: multipliers must be positive"):
        positions_from_raw(rec24[0], units="counts", threshold_k=-1)
    from optcal.core.recording import parse_ks as library_parse_ks

    assert library_parse_ks((3, 5.5)) == (3.0, 5.5) and library_parse_ks(4) == (4.0,)
    assert library_parse_ks("2:4") == parse_ks("2:4") == (2.0, 3.0, 4.0)
    with pytest.raises(InputError, match="^`threshold_k` 'two': give a number"):
        library_parse_ks("two")
    with pytest.raises(InputError, match="^--threshold-k 'two': give a number"):
        parse_ks("two")
    # every parameter the CLI maps is one of the options object's (which positions_from_raw takes), and every
    # option it maps to exists
    from optcal.core.recording.options import RawOptions

    assert "options" in inspect.signature(positions_from_raw).parameters
    parser = argparse.ArgumentParser()
    add_data_options(parser)
    options = {s for a in parser._actions for s in a.option_strings}
    assert set(flags()) <= set(RawOptions.names()) and set(flags().values()) <= options | {"--units"}
    text = "lower `min_static_s`, set `init_s`, keep `other`"
    assert with_flags(text) == "lower --min-static, set --init-s, keep `other`"


def test_the_library_path_gives_the_cli_path_positions(tmp_path, rec24):
    from optcal.app.workflows.recording import positions_from_raw

    path, _, _, spans, _ = rec24
    data = positions_from_raw(path, units="counts", threshold_k=4, model="linear9")
    det = data.extra["detection"]
    assert len(data) == 24 and det.k == 4 and det.method == "variance"
    searched = positions_from_raw(path, units="counts", threshold_k=(4.0, 8.0), model="linear9")
    assert [r["k"] for r in searched.extra["detection"].search] == [4.0, 8.0]
    np.testing.assert_allclose(data.N, positions_from_recording(det.recording, det).N, rtol=0)
    (tmp_path / "six.json").write_text(json.dumps(spans[:6].tolist()))
    given = positions_from_raw(path, units="counts", intervals=tmp_path / "six.json", model="diag6")
    assert given.extra["detection"].method == "given" and np.all(given.n_samples == spans[:6, 1] - spans[:6, 0])
    with pytest.raises(InputError, match="found 6 static interval.*needs at least 12.*lower `min_static_s`"):
        positions_from_raw(path, units="counts", intervals=tmp_path / "six.json", model="linear9")


def _imports(path, package):
    """The optcal modules a module of ``package`` imports anywhere in it (functions included), absolute."""
    import ast

    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            parts = package.split(".")
            mod = ".".join([*parts[:len(parts) - node.level + 1], *([node.module] if node.module else [])]) \
                if node.level else node.module
            found |= {f"{mod}.{a.name}" for a in node.names} if node.module is None else {mod}
    return {m for m in found if m.split(".")[0] == "optcal"}


def test_recording_package_imports_no_app_no_plots_and_has_no_cycle():
    from pathlib import Path

    import optcal.core.recording

    root = Path(optcal.core.recording.__file__).parent
    graph = {}
    for f in sorted(root.glob("*.py")):
        name = "optcal.core.recording" + ("" if f.name == "__init__.py" else "." + f.stem)
        graph[name] = _imports(f, "optcal.core.recording")
        # the core's recording path: no application layer (the workflow that fits lives in optcal.app), no figure
        assert not any(m.startswith(("optcal.app", "optcal.solvers", "optcal.core.plots")) for m in graph[name]), name
    assert {"optcal.core.recording.reading", "optcal.core.recording.segment"} <= graph["optcal.core.recording"]
    # no cycle among the package's modules (its __init__ only re-exports, and no module imports it)
    inner = {k: {m for m in v if m in graph and m != "optcal.core.recording"} for k, v in graph.items()}
    assert not any("optcal.core.recording" in v for k, v in graph.items() if k != "optcal.core.recording")
    done, stack = set(), []

    def visit(n):
        assert n not in stack, " -> ".join([*stack, n])
        if n not in done:
            stack.append(n)
            for m in inner[n]:
                visit(m)
            stack.pop()
            done.add(n)

    for n in inner:
        visit(n)
    assert {f"optcal.core.recording.{m}" for m in ("sniff", "reading", "detection", "segment", "intervals",
                                                   "positions", "report")} <= done


def test_recording_figure_uses_no_pyplot_and_calibrate_writes_nothing_on_a_bad_plot(tmp_path, rec24, capsys):
    import subprocess
    import sys

    code = ("import sys, numpy as np\n"
            "from optcal.core.recording import read_recording, detect_static\n"
            "from optcal.core.plots.recording import recording_figure\n"
            f"rec = read_recording({rec24[0]!r}, units='counts')\n"
            "det = detect_static(rec, 4)\n"
            "fig = recording_figure(rec, det, np.zeros(det.n_intervals))\n"
            "print(type(fig).__module__, len(fig.axes), 'matplotlib.pyplot' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["matplotlib.figure", "3", "False"]
    cal = tmp_path / "cal.json"
    base = ["calibrate", rec24[0], "--raw", "--units", "counts", "--model", "linear9", "--threshold-k", "4",
            "-o", str(cal)]
    cases = {
        # a raw recording without --raw is named as such before anything is fitted, plotted or written
        "not raw": (["calibrate", rec24[0], "--plot", str(tmp_path / "p.png"), "-o", str(cal)], "pass --raw"),
        "no such folder": ([*base, "--plot", str(tmp_path / "nowhere" / "p.png")], "does not exist"),
        "unknown format": ([*base, "--plot", str(tmp_path / "p.xyz")], "suffix naming its format"),
    }
    for name, (argv, message) in cases.items():
        code, err = _cli(argv, capsys)
        assert code == 2 and message in err, name
        assert not cal.exists() and not (tmp_path / "p.png").exists(), name
    png = tmp_path / "kept.png"
    png.write_bytes(b"mine")
    code, err = _cli([*base, "--plot", str(png)], capsys)
    assert code == 2 and "--force" in err and png.read_bytes() == b"mine" and not cal.exists()
    assert main([*base, "--plot", str(png), "--force"]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG" and cal.exists()
    assert f"wrote {png}" in capsys.readouterr().out
