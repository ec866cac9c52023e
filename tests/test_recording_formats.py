"""Raw recordings as real sensors write them (issue #13; docs/design.md, "Raw recordings"): unsigned and narrow integer
counts and their saturation found from the data, time columns in s, ms, µs or ns, delimiters, decimal
commas, byte-order marks, duplicate names, compressed and MATLAB files, a positions file and a recording
given for each other, detection without a rest at the start and the diagnosis of too few intervals."""

import bz2
import gzip
import json
import lzma

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.app.workflows.recording import choose_threshold, positions_from_raw
from optcal.core.errors import InputError
from optcal.core.model import get_model
from optcal.core.recording import detect_static, detection_summary, positions_from_recording, read_recording
from optcal.core.recording import reading as reading_module
from optcal.core.recording.reading import RAIL_MARGIN
from optcal.core.schemes import scheme

TRUTH = {"K_x": 30000.0, "K_y": 29500.0, "K_z": 30400.0, "b_x": 0.012, "b_y": -0.020, "b_z": 0.100,
         "S_yz": 2.0e-3, "S_zy": -1.5e-3, "S_zx": 1.0e-3}
MID = 32768.0  # an offset-binary ADC's code for zero


def turned(rng, *, rate=100.0, dwell_s=3.0, move_s=1.5, first_s=4.0, noise_g=1e-3, start_moving=False,
           knock_moves=(), dirs=None):
    """Specific force (g) of a sensor turned through ``dirs`` (default: the 24-position scheme): a first rest
    of ``first_s`` + ``dwell_s``, then each pose held ``dwell_s``, joined by ``move_s`` of turning with hand
    shake; ``knock_moves`` get a ±3 g knock (which clips); ``start_moving`` adds 4.5 s of shaking first.
    Returns (A, spans of the rests as [start, end) samples)."""
    dirs = scheme("24") if dirs is None else dirs
    nd, nm = int(dwell_s * rate), int(move_s * rate)
    parts, spans, pos = [], [], 0
    if start_moving:
        parts.append(dirs[-1] + 0.3 * rng.standard_normal((3 * nm, 3)))
        pos += 3 * nm
    first = int(first_s * rate) + nd
    parts.append(np.repeat(dirs[:1], first, 0))
    spans.append((pos, pos + first))
    pos += first
    for i, (a, b) in enumerate(zip(dirs[:-1], dirs[1:])):
        s = (0.5 - 0.5 * np.cos(np.linspace(0, np.pi, nm)))[:, None]
        v = (1 - s) * a + s * b + 1e-3
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        v += 0.2 * np.sin(np.linspace(0, 6 * np.pi, nm))[:, None] * rng.uniform(-1, 1, 3)
        if i in knock_moves:
            v[nm // 2 - 5:nm // 2 + 5] = 3.0 * np.sign(rng.standard_normal(3))
        parts += [v, np.repeat(b[None], nd, 0)]
        spans.append((pos + nm, pos + nm + nd))
        pos += nm + nd
    A = np.concatenate(parts)
    return A + noise_g * rng.standard_normal(A.shape), np.array(spans)


def counts(A, lo=-32768, hi=32767, offset=0.0):
    """Outputs of the TRUTH sensor in counts, rounded and clipped to [lo, hi]; int16 by default, where
    it is fed half the specific force (15,000 counts per g: inside the rails)."""
    m = get_model("linear9")
    A = A if offset else 0.5 * A
    return np.clip(np.round(m.forward(m.from_dict(TRUTH), A)[0] + offset), lo, hi)


def write(path, t, N, header="t,ax,ay,az", delim=",", fmt="%d", tfmt="%.2f", pre=""):
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(pre + (header.replace(",", delim) + "\n" if header else ""))
        cols = N if t is None else np.column_stack([t, N])
        np.savetxt(fh, cols, delimiter=delim, fmt=fmt if t is None else [tfmt] + [fmt] * 3)
    return str(path)


def _cli(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err.strip()


@pytest.fixture(scope="module")
def uint16(tmp_path_factory):
    """An offset-binary 16-bit recording (zero g at 32768, about 30,000 counts per g) whose +z poses sit on
    the 65535 rail (b_z = 0.1 g) and whose 3rd and 12th moves are knocks that clip at 0 and 65535."""
    A, spans = turned(np.random.default_rng(13), knock_moves=(2, 11))
    N = counts(A, 0, 65535, MID)
    t = np.arange(len(N)) / 100.0
    return write(tmp_path_factory.mktemp("u16") / "u16.csv", t, N), t, N, spans


# -- 1. integer counts, signed or unsigned, and saturation from the data --------------------------------
def test_unsigned_counts_are_recognised_and_their_rails_found(uint16):
    path, _, N, spans = uint16
    rec = read_recording(path, units="counts")
    m = RAIL_MARGIN * 65535  # 33 codes: a sensor may clip a few codes short of its format's limit
    on_rail = np.any((N <= m) | (N >= 65535 - m), axis=1)
    assert rec.reading["adc"] == "uint16" and rec.reading["adc_inferred"] and rec.reading["rails"] == [0, 65535]
    np.testing.assert_array_equal(rec.saturated, on_rail)
    # the two +z rests (1st, 11th: 7 + 3 s), the two knocks and the turns near +z: 1234 samples at the rails and
    # 4 within 33 codes of one
    assert int(rec.saturated.sum()) == 1238 and rec.saturated[spans[0, 0]:spans[0, 1]].all()
    assert rec.saturated[spans[10, 0]:spans[10, 1]].all()
    det = choose_threshold(rec, "linear9")
    assert det.n_intervals == 22  # the 24 rests but the two on the rail
    hit = [(det.intervals[:, 0] < e) & (det.intervals[:, 1] > s) for s, e in spans[[0, 10]]]
    assert not np.any(hit) and sum("dropped" in n for n in det.notes) == 2
    cal = calibrate(positions_from_recording(rec, det), "linear9")
    x = get_model("linear9").from_dict(TRUTH)
    x[3:6] += MID / x[:3]  # the offset-binary zero is an output offset K·b of 32768 counts
    assert np.all(np.abs((cal.x - x) / cal.stderr) < 4)
    s = detection_summary(det)
    assert s["n_saturated_samples"] == 1238 and s["reading"]["adc"] == "uint16"
    assert s["rate_hz"] == pytest.approx(100.0)
    assert s["n_intervals"] == 22 and json.dumps(s)


def test_unsigned_recording_calibrates_without_flags_and_says_what_was_set_aside(uint16, capsys):
    code, out, err = _cli(["calibrate", uint16[0], "--raw", "--units", "counts", "--model", "linear9"], capsys)
    assert code == 0, err
    assert "counts uint16 (inferred from the data; rails 0 and 65535 counts)" in out
    assert "1238 saturated sample(s)" in out and "1238 sample(s) set aside as saturated" in out
    assert "22 static interval(s)" in out  # the default detector (segmentation) sets the two +z rests aside
    # the variance detector (chosen by its threshold) names the two intervals it dropped for saturation
    code, out, err = _cli(["calibrate", uint16[0], "--raw", "--units", "counts", "--model", "linear9",
                           "--threshold-k", "4"], capsys)
    assert code == 0 and "22 static interval(s)" in out and out.count("dropped:") == 2, err


def test_unsigned_recording_json_says_what_was_set_aside(uint16, capsys):
    code, out, _ = _cli(["calibrate", uint16[0], "--raw", "--units", "counts", "--model", "linear9", "--json"],
                        capsys)
    assert code == 0
    rec = json.loads(out)["recording"]
    assert rec["n_saturated_samples"] == 1238 and rec["reading"]["adc"] == "uint16" and rec["n_intervals"] == 22


def test_declared_adc_and_rails_found_from_the_data(tmp_path):
    """A 12-bit signed ADC (±2048 codes, 1000 counts per g) clips at 2047 and −2048: declared as int12 its
    rails are saturation; undeclared (read as int16) the same samples are found where the axes stick at
    their extremes. A sensor too coarse for its noise to move (constant poses) gets no rail that way."""
    rng = np.random.default_rng(3)
    A, _ = turned(rng, knock_moves=(4, 9, 15))
    N = np.clip(np.round(A * 1000.0 + [30, -20, 60]), -2048, 2047)
    path = write(tmp_path / "int12.csv", np.arange(len(N)) / 100.0, N)
    declared = read_recording(path, units="counts", adc="int12")
    assert declared.reading["rails"] == [-2048, 2047] and not declared.reading.get("adc_inferred")
    inferred = read_recording(path, units="counts")
    assert inferred.reading["adc"] == "int16" and set(inferred.reading["stuck"]) <= {"ax", "ay", "az"}
    on_rail = np.any((N == -2048) | (N == 2047), axis=1)
    assert on_rail.sum() == 30  # three knocks of 10 samples
    np.testing.assert_array_equal(declared.saturated, on_rail)
    np.testing.assert_array_equal(inferred.saturated, on_rail)
    coarse = np.round(scheme("24").repeat(300, 0) * 3 + 0.01 * rng.standard_normal((7200, 3)))  # ±3 counts
    quiet = read_recording(write(tmp_path / "coarse.csv", np.arange(7200) / 100.0, coarse), units="counts")
    assert not quiet.saturated.any() and "stuck" not in quiet.reading
    with pytest.raises(InputError, match="^`adc` 'int'"):
        read_recording(path, units="counts", adc="int")


# -- 2. time columns in s, ms, µs, ns -------------------------------------------------------------------
@pytest.mark.parametrize("unit,scale,rate", [("s", 1.0, 100.0), ("ms", 1e3, 100.0), ("us", 1e6, 250.0),
                                             ("ns", 1e9, 1000.0), ("ms", 1e3, 5.0)])
def test_time_unit_from_the_median_step(tmp_path, unit, scale, rate):
    n = 3000
    rng = np.random.default_rng(1)
    N = np.round(rng.standard_normal((n, 3)) * 50 + [0, 0, 16000])
    t = np.arange(1, n + 1) / rate * scale + 1.7e9 * (unit == "s")
    path = write(tmp_path / f"{unit}.csv", t, N, tfmt="%.6f" if unit == "s" else "%.0f")
    rec = read_recording(path, units="counts")
    assert rec.reading["time_unit"] == unit and rec.rate == pytest.approx(rate, rel=1e-6)
    assert rec.duration == pytest.approx((n - 1) / rate, rel=1e-6)


def test_time_unit_declared_and_implausible_steps(tmp_path, capsys):
    N = np.round(np.random.default_rng(2).standard_normal((3000, 3)) * 50 + [0, 0, 16000])
    path = write(tmp_path / "ms1.csv", np.arange(3000) * 1.0, N, tfmt="%d")  # 1 ms steps: 1 kHz, not 1 Hz
    assert read_recording(path, units="counts").rate == pytest.approx(1000.0)
    assert read_recording(path, units="counts", time_unit="s").rate == pytest.approx(1.0)
    fast = write(tmp_path / "fast.csv", np.arange(3000) * 2e-6, N, tfmt="%.7f")  # 500 kHz in s, more in ms…
    with pytest.raises(InputError, match="none between 1 Hz and 100 kHz; set `time_unit`"):
        read_recording(fast, units="counts")
    code, _, err = _cli(["calibrate", fast, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "set --time-unit" in err and len(err.splitlines()) == 1
    # relative stamps in ns at 1 kHz (a new user's log) are 1 Hz in µs: the data do not tell, and it was read
    # as a 4.6-hour recording at 1 Hz; refused, naming both, and read as declared
    rel = write(tmp_path / "rel_ns.csv", np.arange(3000) * 999_936.0, N, tfmt="%.0f")
    code, _, err = _cli(["calibrate", rel, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "is 1 Hz in us or 1000 Hz in ns; set --time-unit (or give --rate)" in err
    assert read_recording(rel, units="counts", time_unit="ns").rate == pytest.approx(1000.064, rel=1e-6)
    assert read_recording(rel, units="counts", rate=1000.0).reading["time_unit"] == "ns"


# -- 3. delimiters, decimal comma, BOM, duplicate names, positions and recordings swapped ---------------
def test_delimiters_decimal_comma_and_bom_with_both_readers(tmp_path, monkeypatch):
    rng = np.random.default_rng(4)
    n = 2000
    t = np.arange(n) / 100.0
    A = np.round(rng.standard_normal((n, 3)) * 0.01 + [0.1, -0.2, 0.97], 4)
    rows = [(f"{t[i]:.2f}", *(f"{v:.4f}" for v in A[i])) for i in range(n)]
    files = {
        "semicolon_comma.csv": ("t;ax;ay;az", ";", ","),
        "tab_comma.tsv": ("t\tax\tay\taz", "\t", ","),
        "space_comma.txt": (None, " ", ","),
        "bom_comma.csv": ("\ufefft,ax,ay,az", ",", "."),
    }
    for name, (header, delim, dec) in files.items():
        body = "\n".join(delim.join(f.replace(".", dec) for f in r) for r in rows)
        (tmp_path / name).write_text((header + "\n" if header else "") + body + "\n", encoding="utf-8")
        for arrow in (True, False):
            with monkeypatch.context() as m:
                if not arrow:
                    m.setattr(reading_module, "_arrow_csv", None)
                rec = read_recording(tmp_path / name)
            np.testing.assert_array_equal(rec.N, A, err_msg=f"{name} arrow={arrow}")
            assert rec.rate == pytest.approx(100.0) and rec.reading["decimal"] == dec, name
        assert rec.reading["delimiter"] == {" ": "whitespace"}.get(delim, delim)


def test_duplicate_column_names_are_refused(tmp_path, capsys):
    path = write(tmp_path / "dup.csv", np.arange(500) / 100.0, np.ones((500, 3)), header="t,ax,AX,az")
    with pytest.raises(InputError, match=r"names column 'AX' twice \(columns 1 and 2\); rename one"):
        read_recording(path, units="counts")
    code, _, err = _cli(["calibrate", path, "--raw", "--units", "counts"], capsys)
    assert code == 2 and "twice" in err and len(err.splitlines()) == 1


def test_positions_file_and_recording_given_for_each_other(tmp_path, uint16, capsys):
    from optcal.core.data import PositionsData

    pos = tmp_path / "positions.csv"
    PositionsData(N=scheme("24"), n_samples=np.full(24, 300.0), std=np.full((24, 3), 1e-3)).to_csv(pos)
    code, _, err = _cli(["calibrate", str(pos), "--raw", "--model", "linear9"], capsys)
    assert code == 2 and "looks like a positions file" in err and "(drop --raw)" in err
    assert "position, n" in err and len(err.splitlines()) == 1
    code, _, err = _cli(["calibrate", uint16[0], "--units", "counts", "--model", "linear9"], capsys)
    assert code == 2 and "looks like a raw recording" in err and err.endswith("pass --raw")
    assert "rows, one per sample" in err and len(err.splitlines()) == 1
    headerless = write(tmp_path / "nohead.txt", None, np.ones((300, 3)), header="")
    code, _, err = _cli(["calibrate", headerless, "--model", "linear9"], capsys)
    assert code == 2 and "300 rows of 3 numbers and no header" in err and "pass --raw" in err


# -- 4. compressed and MATLAB files ----------------------------------------------------------------------
def test_compressed_recordings_read_by_suffix(tmp_path, uint16):
    plain = open(uint16[0], "rb").read()
    for suffix, pack in ((".gz", gzip.compress), (".bz2", bz2.compress), (".xz", lzma.compress)):
        path = tmp_path / f"u16.csv{suffix}"
        path.write_bytes(pack(plain))
        rec = read_recording(path, units="counts")
        np.testing.assert_array_equal(rec.N, uint16[2])
        assert rec.reading["compression"] == suffix and rec.reading["adc"] == "uint16"


def test_mat_recordings_and_positions(tmp_path, uint16, capsys):
    from scipy.io import savemat

    _, t, N, _ = uint16
    savemat(tmp_path / "matrix.mat", {"log": np.column_stack([t, N])})
    savemat(tmp_path / "named.mat", {"time": t[:, None], "acc_x": N[:, 0], "acc_y": N[:, 1], "acc_z": N[:, 2],
                                     "note": "bench 3"})
    for name in ("matrix.mat", "named.mat"):
        rec = read_recording(tmp_path / name, units="counts")
        np.testing.assert_array_equal(rec.N, N)
        assert rec.rate == pytest.approx(100.0) and rec.reading["format"] == "MAT file"
        assert int(rec.saturated.sum()) == 1238
    assert read_recording(tmp_path / "named.mat", units="counts").columns == {"t": "time", "ax": "acc_x",
                                                                              "ay": "acc_y", "az": "acc_z"}
    data = positions_from_raw(tmp_path / "matrix.mat", units="counts", model="linear9")
    assert len(data) == 22
    m = get_model("linear9")
    P = m.forward(m.from_dict({**TRUTH, "K_x": 1.0, "K_y": 1.0, "K_z": 1.0}), scheme("24"))[0]
    P = P + 1e-4 * np.random.default_rng(0).standard_normal(P.shape)
    savemat(tmp_path / "pos.mat", {"V": P.T})  # 3 × 24, as Hassan & Bao store theirs
    code, out, err = _cli(["calibrate", str(tmp_path / "pos.mat"), "--model", "linear9", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["n_positions"] == 24 and 50e-6 < json.loads(out)["rms_residual_g"] < 150e-6
    code, _, err = _cli(["calibrate", str(tmp_path / "pos.mat"), "--raw", "--rate", "50"], capsys)
    assert code == 2 and "differ by a median 76% of the outputs' magnitude, as positions" in err and "drop --raw" in err
    code, _, err = _cli(["calibrate", str(tmp_path / "matrix.mat"), "--units", "counts"], capsys)
    assert code == 2 and "looks like a raw recording" in err


# -- 5. detection without a rest at the start, and the diagnosis of too few intervals ---------------------
def test_detection_needs_no_rest_at_the_start(tmp_path):
    A, spans = turned(np.random.default_rng(8), start_moving=True)
    N = counts(A, -32768, 32767)
    rec = read_recording(write(tmp_path / "moving.csv", np.arange(len(N)) / 100.0, N), units="counts")
    with pytest.raises(InputError, match="the first 2 s are not at rest"):
        detect_static(rec, 4, init_s=2.0)
    det = detect_static(rec, 4)
    assert det.reference == "quietest windows" and det.init_samples is None
    assert det.n_intervals == 24
    assert np.all(det.intervals[:, 0] >= spans[:, 0]) and np.all(det.intervals[:, 1] <= spans[:, 1])
    # with a rest at the start, the default is imu_tk's initial-rest method, as with init_s = 2
    A, _ = turned(np.random.default_rng(9))
    rec2 = read_recording(write(tmp_path / "rest.csv", np.arange(len(A)) / 100.0, counts(A, -32768, 32767)),
                          units="counts")
    a, b = detect_static(rec2, 4), detect_static(rec2, 4, init_s=2.0)
    assert a.reference == "initial rest" and a.init_variance == b.init_variance
    np.testing.assert_array_equal(a.intervals, b.intervals)


def test_too_few_intervals_says_why_and_what_to_change(tmp_path, capsys):
    """Poses held 1.6 s, for the variance detector (k = 4): with the 1 s window, 0.6 s of each is static,
    under the default 1 s minimum; the error counts the short candidates and names the minimum that admits
    enough of them."""
    A, _ = turned(np.random.default_rng(10), dwell_s=1.6, move_s=1.0)
    N = counts(A, -32768, 32767)
    path = write(tmp_path / "short.csv", np.arange(len(N)) / 100.0, N)
    with pytest.raises(InputError) as exc:
        positions_from_raw(path, units="counts", model="linear9", threshold_k=4)
    msg = str(exc.value)
    assert msg.startswith("found 1 static interval(s) (k = 4), model linear9 needs at least 12")
    assert "0 sample(s) set aside as saturated" in msg
    assert "23 candidate(s) shorter than `min_static_s` = 1 s (the longest 0.64 s)" in msg
    assert msg.endswith("lower `min_static_s` to 0.6 s")
    variance = ["calibrate", path, "--raw", "--units", "counts", "--model", "linear9", "--threshold-k", "4"]
    code, _, err = _cli(variance, capsys)
    assert code == 2 and "shorter than --min-static = 1 s" in err and err.endswith("lower --min-static to 0.6 s")
    code, out, err = _cli([*variance, "--min-static", "0.6"], capsys)
    assert code == 0 and "24 static interval(s)" in out


# -- 6. gyroscope columns (issue #23: the gyroscope is calibrated from the same recording) ------------------
def test_gyroscope_columns_by_name_and_by_position(tmp_path):
    """gx, gy, gz are read by their names (gyro_x, wx, ...) or as columns 4-6 of a header-less 7-column file
    (t ax ay az gx gy gz), kept in the file's units as ``Recording.W``; a gyroscope axis held at its extreme is
    ``gyro_saturated`` (the accelerometer's ``saturated`` is not touched); 3, 4 and 5 columns mean what they did."""
    rng = np.random.default_rng(23)
    n = 3000
    t = np.arange(n) / 100.0
    N = np.round(rng.standard_normal((n, 3)) * 30 + [0, 0, 16000])
    W = np.round(rng.standard_normal((n, 3)) * 5)
    W[100:120, 1] = 32767  # a turn too fast for the gyroscope: 20 samples on the rail of the y axis
    named = write(tmp_path / "imu.csv", None, np.column_stack([t, N, W]),
                  header="time,acc_x,acc_y,acc_z,gyro_x,gyro_y,gyro_z", fmt="%.6g")
    rec = read_recording(named, units="counts")
    assert rec.columns == {"t": "time", "ax": "acc_x", "ay": "acc_y", "az": "acc_z", "gx": "gyro_x",
                           "gy": "gyro_y", "gz": "gyro_z"}
    np.testing.assert_array_equal(rec.W, W)
    np.testing.assert_array_equal(rec.N, N)
    assert int(rec.gyro_saturated.sum()) == 20 and rec.gyro_saturated[100:120].all()
    assert rec.reading["gyro_adc"] == "int16" and rec.reading["gyro_stuck"] == {"gy": [32767.0]}
    assert not rec.saturated.any()
    rad = np.column_stack([t, N / 16000.0, W * 1e-3])
    headerless = tmp_path / "imu.txt"
    np.savetxt(headerless, rad, fmt="%.6f")
    rec = read_recording(headerless)
    assert rec.columns == {"t": 0, "ax": 1, "ay": 2, "az": 3, "gx": 4, "gy": 5, "gz": 6}
    np.testing.assert_allclose(rec.W, W * 1e-3, atol=1e-9)
    assert int(rec.gyro_saturated.sum()) == 20 and "gyro_adc" not in rec.reading  # not counts: no ADC rails
    for k, roles in ((3, ("ax", "ay", "az")), (4, ("t", "ax", "ay", "az")), (5, ("t", "ax", "ay", "az", "temp"))):
        p = tmp_path / f"c{k}.txt"
        table = {3: rad[:, 1:4], 4: rad[:, :4], 5: np.column_stack([rad[:, :4], np.full(n, 21.5)])}[k]
        np.savetxt(p, table, fmt="%.6f")
        rec = read_recording(p, rate=100.0)
        assert tuple(rec.columns) == roles and rec.W is None and rec.gyro_saturated is None
    assert read_recording(named, units="counts", columns="time,acc_x,acc_y,acc_z").W is None
    rec = read_recording(named, units="counts", columns="ax=acc_x,ay=acc_y,az=acc_z,gx=5,gy=4,gz=6,t=0")
    np.testing.assert_array_equal(rec.W, W[:, [1, 0, 2]])
    with pytest.raises(InputError, match="^`columns` names gx, gy but not gz; a gyroscope needs gx, gy and gz$"):
        read_recording(named, units="counts", columns="t=0,ax=1,ay=2,az=3,gx=4,gy=5")
    partial = write(tmp_path / "partial.csv", None, np.column_stack([t, N, W[:, :2]]),
                    header="time,acc_x,acc_y,acc_z,gyro_x,gyro_y", fmt="%.6g")
    assert read_recording(partial, units="counts").W is None  # two named axes are no gyroscope


def test_a_sensor_that_clips_a_few_codes_short_of_its_format_is_at_its_rail():
    """A gyroscope read as int16 counts clips at ±32764 for a few samples of a fast turn (measured on a lab's
    log): within RAIL_MARGIN of the range (33 codes) of a rail is at it, for the gyroscope's rates and the
    accelerometer's counts alike; 32700 is not."""
    from optcal.core.recording.reading import gyro_saturation_of, saturation_of

    W = np.zeros((8, 3))
    W[2, 0], W[3, 1], W[5, 2], W[6, 0] = 32764, -32764, 32700, -32000
    sat, how = gyro_saturation_of(W, "counts", None)
    assert sat.tolist() == [False, False, True, True, False, False, False, False]
    assert how["gyro_adc"] == "int16" and how["gyro_rails"] == [-32768, 32767]
    assert saturation_of(W, "counts", None, None)[0].tolist() == sat.tolist()


def test_rows_without_time_that_differ_like_positions_hint_at_dropping_raw(tmp_path, capsys):
    """A positions file of running means (a lab's 178 means of 25 readings, turned continuously between them:
    consecutive rows differ by 12 % of g, neither clearly samples nor positions) given with --raw was told only
    to give --rate, which led to "no part of the recording is at rest". The refusal says it may be positions; a
    recording's samples (differing by their noise) are not told so."""
    rng = np.random.default_rng(0)
    ang = np.cumsum(rng.normal(0, 0.12, (178, 2)), axis=0)
    c0, s0, c1, s1 = np.cos(ang[:, 0]), np.sin(ang[:, 0]), np.cos(ang[:, 1]), np.sin(ang[:, 1])
    P = np.column_stack([c0 * c1, s0 * c1, s1])
    path = tmp_path / "means.txt"
    np.savetxt(path, P, delimiter="\t", fmt="%.6f")
    assert main(["calibrate", str(path), "--raw", "--units", "g"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("has no time column; give the sample rate in Hz with --rate (or, if its 178 rows are "
                        "positions, drop --raw)"), err
    S = np.tile(P[:1], (500, 1)) + rng.normal(0, 0.002, (500, 3))  # samples of one pose
    np.savetxt(path, S, delimiter="\t", fmt="%.6f")
    assert main(["calibrate", str(path), "--raw", "--units", "g"]) == 2
    assert capsys.readouterr().err.strip().endswith("give the sample rate in Hz with --rate")


@pytest.mark.parametrize("arrow", [True, False], ids=["arrow", "numpy"])
def test_interleaved_record_types_are_read_as_one_table(tmp_path, monkeypatch, arrow):
    """A logger that writes several record types in one CSV (a MicroStrain IMU's: the raw packets' rows leave the
    filter's cells empty, the filter's rows the raw ones) was refused at its first row of the other type. The
    rows without the chosen columns' values are left out and said; the samples are those of the raw rows alone.
    A single row with an empty cell in an ordinary file is still refused, naming it."""
    import optcal.core.recording.reading as reading

    if not arrow:
        monkeypatch.setattr(reading, "_arrow_reader", lambda: None)
    rng = np.random.default_rng(5)
    n = 400
    t = 1.7e9 + np.arange(n) * 0.01
    A = np.round(rng.normal(0, 0.002, (n, 3)) + [0.0, 0.0, 1.0], 6)
    W = np.round(rng.normal(0, 0.001, (n, 3)), 6)
    lines = ["state,timestamp,scaledAccelX,scaledAccelY,scaledAccelZ,scaledGyroX,scaledGyroY,scaledGyroZ,quatW,quatX"]
    for i in range(n):
        lines.append("R," + ",".join(f"{v:.6f}" for v in (t[i], *A[i], *W[i])) + ",,")
        if i % 2:  # a filter record between raw ones: its own columns, the raw ones empty
            lines.append(f"S,{t[i] + 0.005:.6f},,,,,,,0.99,0.01")
    path = tmp_path / "interleaved.csv"
    path.write_text("\n".join(lines) + "\n")
    cols = "t=timestamp,ax=scaledAccelX,ay=scaledAccelY,az=scaledAccelZ,gx=scaledGyroX,gy=scaledGyroY,gz=scaledGyroZ"
    rec = read_recording(path, columns=cols, units="g")
    np.testing.assert_allclose(rec.N, A, atol=1e-9)
    np.testing.assert_allclose(rec.W, W, atol=1e-9)
    assert rec.rate == pytest.approx(100.0, rel=1e-6) and rec.reading["other_record_rows"] == n // 2
    from optcal.core.recording.report import reading_line

    assert f"{n // 2} row(s) of another record type, interleaved" in reading_line(rec.reading, 0)
    # one broken row in an ordinary file: refused as before
    plain = tmp_path / "plain.csv"
    rows = ["t,ax,ay,az"] + [f"{t[i]:.6f}," + ",".join(f"{v:.6f}" for v in A[i]) for i in range(n)]
    rows[50] = f"{t[49]:.6f},0.0,,1.0"
    plain.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError):
        read_recording(plain, units="g")


def test_a_sensor_s_outputs_under_a_prefix_are_its_columns(tmp_path):
    """MicroStrain's scaledAccelX … scaledGyroZ beside the filter's estCompensatedAccelX and estLinearAccelX: the
    scaled ones are the sensor's outputs (a prefix of sniff.SENSOR_PREFIXES), the estimates are not read, and a
    linear acceleration alone (gravity taken out) is not taken for the accelerometer."""
    rng = np.random.default_rng(2)
    n = 300
    A = rng.normal(0, 0.002, (n, 3)) + [0, 0, 1]
    W = rng.normal(0, 0.001, (n, 3))
    names = ["timestamp", "scaledAccelX", "scaledAccelY", "scaledAccelZ", "scaledGyroX", "scaledGyroY", "scaledGyroZ",
             "estCompensatedAccelX", "estCompensatedAccelY", "estCompensatedAccelZ", "estLinearAccelX",
             "estLinearAccelY", "estLinearAccelZ"]
    table = np.column_stack([np.arange(n) * 0.01, A, W, A + 0.01, A - [0, 0, 1]])
    path = tmp_path / "ms.csv"
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.6f")
    rec = read_recording(path, units="g")
    assert rec.columns["ax"] == "scaledAccelX" and rec.columns["gz"] == "scaledGyroZ"
    np.testing.assert_allclose(rec.N, A, atol=1e-6)
    lin = tmp_path / "linear.csv"
    np.savetxt(lin, table[:, [0, 10, 11, 12]], delimiter=",", comments="", fmt="%.6f",
               header="t,estLinearAccelX,estLinearAccelY,estLinearAccelZ")
    with pytest.raises(InputError, match="cannot tell which columns are ax, ay, az"):
        read_recording(lin, units="g")
