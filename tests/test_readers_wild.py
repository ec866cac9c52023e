"""Readers and messages for the files other labs write (issue #29, item 6): every refusal one line of at most
300 characters (long lists cut where they are made, a backstop in the command line); the intervals file
``{"intervals": [[s, e], ...]}`` (seconds from the first sample); a commented header line ``# id t dt ax ...``;
MATLAB v7.3 (HDF5) through h5py; column names such as ``ACCELX``, ``acc_x``, ``AccX``, ``GYROX``, ``tx``
mapped, or named in the refusal; ``--columns`` naming a column or a role twice refused in one line.

The real files come from the corpus beside the project (tests/corpus.py); those tests are skipped where it is
absent."""

import gzip
import json
from types import SimpleNamespace

import numpy as np
import pytest
from corpus import corpus

from optcal.app.cli import _run, main
from optcal.core.errors import MAX_LINE, InputError, listing, one_line
from optcal.core.recording import given_intervals, read_intervals, read_recording
from optcal.core.recording.intervals import IntervalTimes
from optcal.core.recording.reading import _load_numeric
from optcal.core.recording.sniff import ALIAS_KEYS, mat_table, sniff_layout
from optcal.core.synthetic_recording import poses_recording


def _cli(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def _refused(argv, capsys, fragment):
    """Exit 2, one line of at most MAX_LINE characters holding ``fragment``; the line is returned."""
    code, _, err = _cli(argv, capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert len(lines[0]) <= MAX_LINE, (len(lines[0]), lines[0])
    assert fragment in lines[0], lines[0]
    return lines[0]


def _write(path, header, table, delimiter=","):
    with open(path, "w") as fh:
        if header is not None:
            fh.write(header + "\n")
        np.savetxt(fh, table, delimiter=delimiter, fmt="%.10g")
    return path


@pytest.fixture(scope="module")
def poses():
    """A recording of 12 poses held 3 s each at 100 Hz (in g) and its true rests ([start, end) samples)."""
    syn = poses_recording(np.random.default_rng(29), n_poses=12, hold_s=3.0, noise_g=1e-3)
    return syn.recording, syn.rests


# == 1. one line of at most 300 characters =============================================================
def test_listing_names_the_first_few_and_counts_the_rest():
    assert listing(range(62)) == "0, 1, 2, 3, 4, 5, 6, 7, … (54 more)"
    assert listing(range(62), 3) == "0, 1, 2, … (59 more)"
    assert listing(["a", "b"], 3) == "a, b"
    assert listing(range(4), 3) == "0, 1, 2, 3"  # "… (1 more)" would hide one name in more characters
    assert listing("abcdef", 2, ",") == "a,b,… (4 more)"
    assert listing([]) == ""


def test_one_line_collapses_newlines_and_keeps_the_start_and_the_way_out():
    assert one_line("a\n  b\r\nc") == "a b c"
    assert one_line("short (aside)") == "short (aside)"
    problem = "file.csv: the table is broken: " + ", ".join(f"column {i} is odd" for i in range(60))
    out = one_line(problem + "; fix it with --columns", 200)
    assert len(out) <= 200 and out.startswith("file.csv: the table is broken: column 0 is odd, column 1 is odd")
    assert " … " in out and out.endswith("column 59 is odd; fix it with --columns")  # each clause keeps its ends
    # the folders of a long path go first, then the middle of the longest clause
    long = ("/very/long/folder/of/someone/who/keeps/data/deep/down/rec.csv looks odd (" + "x " * 60
            + "); pass --raw (or name the columns)")
    out = one_line(long, 150)
    assert len(out) <= 150 and out.startswith("…/rec.csv looks odd (x x") and out.endswith(
        "x x ); pass --raw (or name the columns)")
    assert len(one_line("y" * 1000)) <= MAX_LINE


def test_the_command_line_prints_any_refusal_in_one_line_of_at_most_300(capsys):
    def refuse(_args):
        raise InputError("line one\nline two: " + "word " * 200 + "; do this instead")

    assert _run(SimpleNamespace(command="calibrate", _run=refuse, _flags={})) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err.rstrip("\n")) <= MAX_LINE, err
    assert err.startswith("optcal calibrate: error: line one line two:") and err.rstrip().endswith("do this instead")


def _many_columns(path, rows=400):
    """A 62-column log of six IMUs on one bar (time, a counter, then 6 × 10 channels named per IMU): names
    no alias matches, as a lab's logger writes them."""
    names = ["time_utc", "counter"] + [f"imu{k}_{q}" for k in range(1, 7) for q in
                                        ("accel_1", "accel_2", "accel_3", "rate_1", "rate_2", "rate_3", "mag_1",
                                         "mag_2", "mag_3", "temp_raw")]
    assert len(names) == 62
    rng = np.random.default_rng(3)
    table = np.column_stack([np.arange(rows) / 100.0, np.arange(rows), rng.standard_normal((rows, 60))])
    return _write(path, ",".join(names), table)


def test_a_62_column_file_is_refused_in_one_short_line_that_names_the_way_out(tmp_path, capsys):
    path = _many_columns(tmp_path / "bar_of_six_imus.csv")
    with pytest.raises(InputError) as exc:
        read_recording(path)
    assert "(columns: time_utc, counter, imu1_accel_1, imu1_accel_2, imu1_accel_3, imu1_rate_1, imu1_rate_2, " \
           "imu1_rate_3, … (54 more))" in str(exc.value)
    line = _refused(["calibrate", path, "--raw"], capsys, "cannot tell which columns are ax, ay, az")
    assert "… (54 more)" in line and line.endswith("name them with --columns, e.g. t,ax,ay,az with names or "
                                                  "0-based indices")
    # a name that is not there: the columns listed are cut the same way
    line = _refused(["calibrate", path, "--raw", "--columns", "t=time_utc,ax=imu1_acc_1,ay=imu1_accel_2,"
                     "az=imu1_accel_3"], capsys, "no column 'imu1_acc_1' (did you mean 'imu1_accel_1'?)")
    assert "… (54 more)" in line


def test_a_broken_row_of_a_wide_file_is_named_in_a_short_line(tmp_path, capsys):
    path = _many_columns(tmp_path / "wide.csv")
    lines = path.read_text().splitlines()
    lines[5] = ",".join(["x"] * 40)  # 40 text cells where the data have 62 numbers
    path.write_text("\n".join(lines) + "\n")
    line = _refused(["calibrate", path, "--raw"], capsys, "line 6 (x,x,x,x,x,x,x,x,x,x,x,x,… (28 more)) breaks")
    assert line.endswith("breaks the data rows: 40 field(s) where they have 62; fix or remove it")


# == 2. intervals in seconds: {"intervals": [[s, e], ...]} ==============================================
def test_intervals_object_form_is_seconds_from_the_first_sample(tmp_path, poses):
    rec, rests = poses
    assert rec.t[0] == 0.0 and rec.rate == 100.0
    seconds = rests / 100.0  # the true rests' [start, end) as times from the first sample
    (tmp_path / "s.json").write_text(json.dumps({"intervals": seconds.tolist()}))
    iv, names = read_intervals(tmp_path / "s.json")
    assert isinstance(iv, IntervalTimes) and names is None
    np.testing.assert_array_equal(np.asarray(iv), seconds)
    np.testing.assert_array_equal(given_intervals(rec, iv, names).intervals, rests)
    # times written to fewer digits (ms), and {start, end} items, give the same samples
    (tmp_path / "ms.json").write_text(json.dumps({"intervals": [{"start": round(s, 3), "end": round(e, 3)}
                                                                 for s, e in seconds], "unit": "s"}))
    np.testing.assert_array_equal(given_intervals(rec, *read_intervals(tmp_path / "ms.json")).intervals, rests)
    # "unit": "samples" keeps them sample indices, as every other form is
    (tmp_path / "n.json").write_text(json.dumps({"intervals": rests.tolist(), "unit": "samples"}))
    iv, _ = read_intervals(tmp_path / "n.json")
    assert not isinstance(iv, IntervalTimes) and iv.dtype == np.int64
    np.testing.assert_array_equal(iv, rests)
    # a half-second interval from 1.0 s: the 50 samples at 100 Hz from sample 100
    (tmp_path / "half.json").write_text(json.dumps({"intervals": [[1.0, 1.5]]}))
    np.testing.assert_array_equal(given_intervals(rec, *read_intervals(tmp_path / "half.json")).intervals,
                                  [[100, 150]])


def test_intervals_object_form_refusals(tmp_path, poses):
    rec, _ = poses
    duration = rec.t[-1] - rec.t[0] + 0.01
    cases = {
        "outside.json": ({"intervals": [[0, 1], [duration - 1, duration + 5]]},
                         f"interval 1 ({duration - 1:g} s to {duration + 5:g} s) is empty or outside the recording's"),
        "negative.json": ({"intervals": [[-1, 1]]}, "interval 0 (-1 s to 1 s)"),
        "empty.json": ({"intervals": [[1.001, 1.005]]}, "is empty or outside"),
    }
    for name, (obj, fragment) in cases.items():
        (tmp_path / name).write_text(json.dumps(obj))
        with pytest.raises(InputError, match=r"\[start, end\) in seconds from the first sample") as exc:
            given_intervals(rec, *read_intervals(tmp_path / name))
        assert fragment in str(exc.value), str(exc.value)
    bad = {"unit.json": ({"intervals": [[0, 1]], "unit": "ms"}, "\"unit\" 'ms' is not one of s, samples"),
           "key.json": ({"intervals": [[0, 1]], "rate": 100}, "unknown key(s) rate beside \"intervals\""),
           "none.json": ({"intervals": []}, "holds no start,end pairs"),
           "nan.json": ({"intervals": [[0, None]]}, "finite numbers")}
    for name, (obj, fragment) in bad.items():
        (tmp_path / name).write_text(json.dumps(obj))
        with pytest.raises(InputError) as exc:
            read_intervals(tmp_path / name)
        assert fragment in str(exc.value), str(exc.value)
    # seconds written into a plain list (sample indices) are told how to write them
    (tmp_path / "list.json").write_text(json.dumps([[0.5, 1.5]]))
    with pytest.raises(InputError, match=r"whole sample indices \(for seconds, write \{\"intervals\""):
        read_intervals(tmp_path / "list.json")


def test_intervals_in_seconds_calibrate_as_the_same_samples_do(tmp_path, poses, capsys):
    rec, rests = poses
    path = _write(tmp_path / "rec.csv", "t,ax,ay,az", np.column_stack([rec.t, rec.N]))
    seconds = rests / rec.rate
    (tmp_path / "s.json").write_text(json.dumps({"intervals": seconds.tolist()}))
    (tmp_path / "n.json").write_text(json.dumps(rests.tolist()))
    fits = []
    for iv in ("s.json", "n.json"):
        code, out, err = _cli(["calibrate", path, "--raw", "--intervals", tmp_path / iv, "--model", "linear9",
                               "-o", tmp_path / f"{iv}.cal.json"], capsys)
        assert code == 0, err
        fits.append(json.loads((tmp_path / f"{iv}.cal.json").read_text())["parameters"])
    assert fits[0] == fits[1]


# == 3. a commented header line =======================================================================
def _imu_rows(n=300, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    return np.column_stack([np.arange(n), t, np.full(n, 0.01), rng.normal(0, 0.01, (n, 3)) + [0, 0, 1],
                            rng.normal(0, 0.5, (n, 3))])


@pytest.mark.parametrize("preamble", [
    "# id t dt ax ay az gx gy gz\n",
    "# logger v2, 100 Hz\n# id t dt ax ay az gx gy gz\n",
    "# id t dt ax ay az gx gy gz\n# -  s  s  g  g  g  dps dps dps\n",  # a units line after the names
    "# id t dt ax ay az gx gy gz\n#\n",
    "% id, t, dt, ax, ay, az, gx, gy, gz\n",
    "#ID T DT AX AY AZ GX GY GZ\n",
])
def test_a_commented_header_line_is_the_header(tmp_path, preamble):
    rows = _imu_rows()
    path = tmp_path / "log.txt"
    with open(path, "w") as fh:
        fh.write(preamble)
        np.savetxt(fh, rows, fmt="%.8g")
    lay = sniff_layout(path)
    assert lay.commented_header and [h.lower() for h in lay.header] == ["id", "t", "dt", "ax", "ay", "az", "gx",
                                                                        "gy", "gz"]
    rec = read_recording(path)
    assert rec.reading["header"] == "comment line"
    assert [rec.columns[r].lower() for r in ("t", "ax", "ay", "az", "gx", "gy", "gz")] == \
        ["t", "ax", "ay", "az", "gx", "gy", "gz"]
    np.testing.assert_allclose(rec.t, rows[:, 1], atol=1e-12)
    np.testing.assert_allclose(rec.N, rows[:, 3:6], rtol=1e-7)
    np.testing.assert_allclose(rec.W, rows[:, 6:9], rtol=1e-7)
    assert rec.rate == pytest.approx(100.0)


# == 4. MATLAB v7.3 (HDF5) ============================================================================
def write_mat73(path, variables: dict, compress: bool = False):
    """A MATLAB v7.3 file as MATLAB writes one: HDF5 behind a 512-byte userblock holding MATLAB's 128-byte
    header (text, subsystem offset, version 0x0200, endian mark ``IM``); each array stored with its
    dimensions reversed (HDF5 is row-major, MATLAB column-major) and its MATLAB_class."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            if isinstance(value, str):
                ds = f.create_dataset(name, data=np.frombuffer(value.encode("utf-16-le"), np.uint16)[:, None])
                ds.attrs["MATLAB_class"] = np.bytes_("char")
                ds.attrs["MATLAB_int_decode"] = np.int32(2)
                continue
            a = np.atleast_2d(np.asarray(value))
            ds = f.create_dataset(name, data=a.T, compression="gzip" if compress else None)
            ds.attrs["MATLAB_class"] = np.bytes_({"f": "double", "i": "int32", "u": "uint16", "b": "logical"}[
                a.dtype.kind])
        f.create_group("#refs#")
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Fri Nov 27 12:00:00 2026 HDF5 schema 1.00 ."
    header = text.ljust(116) + bytes(8) + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header.ljust(512, b"\x00"))
    return path


def test_a_mat_v73_matrix_is_read_as_matlab_shows_it(tmp_path, poses):
    rec, _ = poses
    table = np.column_stack([rec.t, rec.N])  # n × 4 in MATLAB: stored 4 × n in the HDF5 file
    path = write_mat73(tmp_path / "rec.mat", {"data": table, "note": "hand-held, 100 Hz"}, compress=True)
    assert path.read_bytes()[:19] == b"MATLAB 7.3 MAT-file"
    header, got = mat_table(path)
    assert header is None
    np.testing.assert_array_equal(got, table)
    r = read_recording(path)
    assert r.reading["format"] == "MAT file" and r.columns == {"t": 0, "ax": 1, "ay": 2, "az": 3}
    np.testing.assert_array_equal(r.N, rec.N)
    np.testing.assert_allclose(r.t, rec.t)
    # gzip-compressed as a whole, and stored as MATLAB's 4 × n (rows as columns), the same table
    (tmp_path / "rec.mat.gz").write_bytes(gzip.compress(path.read_bytes()))
    np.testing.assert_array_equal(read_recording(tmp_path / "rec.mat.gz").N, rec.N)
    wide = write_mat73(tmp_path / "wide.mat", {"accelBuffer": table.T})
    np.testing.assert_array_equal(read_recording(wide).N, rec.N)


def test_mat_v73_named_variables_are_columns(tmp_path, poses):
    rec, _ = poses
    n = len(rec)
    path = write_mat73(tmp_path / "vars.mat", {"time": rec.t[:, None], "AccX": rec.N[:, :1], "AccY": rec.N[:, 1:2],
                                               "AccZ": rec.N[:, 2:], "counts": np.arange(n, dtype=np.int32)[:, None],
                                               "valid": np.ones((n, 1), bool)})
    header, table = mat_table(path)
    assert header == ["AccX", "AccY", "AccZ", "counts", "time", "valid"]  # HDF5 lists them by name
    r = read_recording(path)
    assert r.columns == {"t": "time", "ax": "AccX", "ay": "AccY", "az": "AccZ"}
    np.testing.assert_array_equal(r.N, rec.N)


def test_mat_v73_without_numbers_and_broken_are_one_line(tmp_path, capsys):
    text = write_mat73(tmp_path / "text.mat", {"note": "nothing here"})
    line = _refused(["calibrate", text, "--raw"], capsys, "holds no numeric matrix (variables: note)")
    assert line.endswith("save the samples as an n × 3 or n × 4 matrix")
    broken = tmp_path / "broken.mat"
    broken.write_bytes(text.read_bytes()[:700])
    line = _refused(["calibrate", broken, "--raw"], capsys, "is a MATLAB v7.3 (HDF5) file that cannot be read")
    assert line.endswith("save it again from MATLAB, with save(FILE, ..., '-v7') or '-v7.3'")


def test_a_mat_v73_positions_file_calibrates(tmp_path, capsys):
    from optcal.core.model import get_model
    from optcal.core.presets import PAPER_TRUTH
    from optcal.core.simulate import simulate

    m = get_model("linear9")
    sim = simulate(m, {k: v for k, v in PAPER_TRUTH.items() if k in m.names}, np.random.default_rng(4),
                   scheme="24", noise_g=10e-6)
    path = write_mat73(tmp_path / "positions.mat", {"N": sim.data.N.T})  # 3 × 24, as Hassan & Bao store them
    code, out, err = _cli(["calibrate", path, "--model", "linear9", "-o", tmp_path / "cal.json"], capsys)
    assert code == 0, err
    got = json.loads((tmp_path / "cal.json").read_text())["parameters"]
    assert got["K_x"] == pytest.approx(PAPER_TRUTH["K_x"], rel=1e-4)


def test_the_corpus_v73_recording_is_read():
    import h5py

    path = corpus("sunsided", "full_sphere_accelerometer.mat")
    with h5py.File(path, "r") as f:
        stored = f["accelBuffer"][()]  # MATLAB's 10528 × 4, transposed by HDF5
    rec = read_recording(path)
    assert len(rec) == 10528 and rec.reading["format"] == "MAT file"
    np.testing.assert_array_equal(rec.N, stored[1:].T)
    np.testing.assert_allclose(rec.t, stored[0])
    assert rec.N[0].tolist() == pytest.approx([0.0520019531, -0.1826171875, -1.0107421875])
    norms = np.linalg.norm(rec.N, axis=1)
    assert 0.95 < np.median(norms) < 1.05  # in g


# == 5. column names ==================================================================================
@pytest.mark.parametrize("names", [
    "Timestamp(Ms),ACCELX,ACCELY,ACCELZ",
    "time,acc_x,acc_y,acc_z",
    "timestamp,AccX,AccY,AccZ",
    "tx,accX,accY,accZ",
    "t,Acc_X,Acc_Y,Acc_Z",
    "time [s],Acc X [m/s^2],Acc Y [m/s^2],Acc Z [m/s^2]",
    "t,ax,ay,az",
    "Time,Accelerometer_X,Accelerometer_Y,Accelerometer_Z",
])
def test_accelerometer_and_time_names_are_recognised(tmp_path, names):
    rows = _imu_rows()
    path = _write(tmp_path / "rec.csv", names, rows[:, [1, 3, 4, 5]])
    rec = read_recording(path)
    assert rec.columns == dict(zip(("t", "ax", "ay", "az"), names.split(",")))
    np.testing.assert_allclose(rec.N, rows[:, 3:6], rtol=1e-9)


@pytest.mark.parametrize("gyro", ["GYROX,GYROY,GYROZ", "gyr_x,gyr_y,gyr_z", "GyrX,GyrY,GyrZ", "gx,gy,gz",
                                  "Gyro X (dps),Gyro Y (dps),Gyro Z (dps)", "omega_x,omega_y,omega_z"])
def test_gyroscope_names_are_recognised(tmp_path, gyro):
    rows = _imu_rows()
    path = _write(tmp_path / "imu.csv", "time,ACCELX,ACCELY,ACCELZ," + gyro, rows[:, [1, 3, 4, 5, 6, 7, 8]])
    rec = read_recording(path)
    assert [rec.columns[g] for g in ("gx", "gy", "gz")] == gyro.split(",")
    np.testing.assert_allclose(rec.W, rows[:, 6:9], rtol=1e-9)


def test_tx_beside_ty_and_tz_is_an_axis_not_the_time(tmp_path, capsys):
    """A lab's header ``time tx ty tz wx wy wz`` (an AHRS board's log): ``time`` is the time, not refused as one of
    two candidates; tx, ty, tz are no alias, so the accelerometer must be named. ``calibrate`` then reads the
    columns named; ``imu`` takes the gyroscope the header names (wx, wy, wz) without ``--gyro-columns``, unless
    one of them was taken for the accelerometer."""
    from optcal.core.gyro.recording import read_gyro

    rows = _imu_rows()
    path = _write(tmp_path / "ahrs.csv", "time,tx,ty,tz,wx,wy,wz", rows[:, [1, 3, 4, 5, 6, 7, 8]])
    with pytest.raises(InputError, match=r"cannot tell which columns are ax, ay, az \(columns: time, tx, ty"):
        read_recording(path)
    acc = read_recording(path, columns="time,tx,ty,tz")
    assert acc.columns == {"t": "time", "ax": "tx", "ay": "ty", "az": "tz"} and acc.W is None
    gyro = read_gyro(path, acc, units="rad/s")
    assert gyro.columns == {"t": "time", "ax": "wx", "ay": "wy", "az": "wz"}
    np.testing.assert_allclose(gyro.N, rows[:, 6:9], rtol=1e-9)
    taken = read_recording(path, columns="time,wx,ty,tz")
    with pytest.raises(InputError, match="name the gyroscope's columns"):
        read_gyro(path, taken, units="rad/s")


def test_the_alias_table_gives_each_name_one_role():
    roles = list(ALIAS_KEYS)
    for i, a in enumerate(roles):
        for b in roles[i + 1:]:
            assert not ALIAS_KEYS[a] & ALIAS_KEYS[b], (a, b, ALIAS_KEYS[a] & ALIAS_KEYS[b])
    assert {"accelx", "accx", "ax", "accelerometerx"} <= ALIAS_KEYS["ax"]
    assert {"gyrox", "gyrx", "gx"} <= ALIAS_KEYS["gx"] and {"t", "tx", "time", "timestamp"} <= ALIAS_KEYS["t"]


def test_text_and_raw_columns_are_not_taken_for_a_role(tmp_path):
    """TWLogger's layout: ``Time(hh:mm:ss)`` is text (the numeric ``Timestamp(Ms)`` is the time) and
    ``Temp(Raw)`` is no temperature in °C; ``Temp(C)`` is."""
    rows = _imu_rows(50)
    lines = ["Date,Time(hh:mm:ss),Timestamp(Ms),Temp(Raw),ACCELX,ACCELY,ACCELZ"] + [
        f"07/11/2018,05:34:{i % 60:02d},{1000 * r[1]:.0f},0,{r[3]:.6f},{r[4]:.6f},{r[5]:.6f}"
        for i, r in enumerate(rows)]
    (tmp_path / "tw.csv").write_text("\n".join(lines) + "\n")
    rec = read_recording(tmp_path / "tw.csv")
    assert rec.columns == {"t": "Timestamp(Ms)", "ax": "ACCELX", "ay": "ACCELY", "az": "ACCELZ"}
    assert rec.temp is None and rec.reading["time_unit"] == "ms"
    np.testing.assert_allclose(rec.t, rows[:, 1], atol=1e-9)
    (tmp_path / "c.csv").write_text("\n".join(ln.replace("Temp(Raw)", "Temp(C)") for ln in lines) + "\n")
    assert read_recording(tmp_path / "c.csv").columns["temp"] == "Temp(C)"


def test_two_columns_for_one_role_are_refused_naming_both(tmp_path, capsys):
    rows = _imu_rows()
    path = _write(tmp_path / "two.csv", "t,ax,acc_x,ay,az", rows[:, [1, 3, 3, 4, 5]])
    line = _refused(["calibrate", path, "--raw"], capsys, "columns ax, acc_x could each be ax; name the columns "
                                                          "with --columns")
    assert line.startswith("optcal calibrate: error: ")
    # a gyroscope that two columns could be is left out (the accelerometer is still read)
    path = _write(tmp_path / "g.csv", "t,ax,ay,az,gx,gyr_x,gy,gz", rows[:, [1, 3, 4, 5, 6, 6, 7, 8]])
    assert read_recording(path).W is None


def test_the_twlogger_recording_is_read_without_columns():
    path = corpus("twlogger", "T1D0711-00.CSV.gz")
    rec = read_recording(path, units="counts")
    assert rec.columns == {"t": "Timestamp(Ms)", "ax": "ACCELX", "ay": "ACCELY", "az": "ACCELZ"}
    assert len(rec) == 44000 and rec.reading["time_unit"] == "ms"
    assert rec.N[0].tolist() == [1488.0, 976.0, -4832.0] and rec.t[0] == pytest.approx(15.225)
    assert rec.rate == pytest.approx(62.5)  # a 16 ms step


def test_a_raw_recording_with_recognised_names_given_as_positions_is_told_to_use_raw(tmp_path, capsys):
    rows = _imu_rows(1500)
    path = _write(tmp_path / "named.csv", "T,ACCELX,ACCELY,ACCELZ", rows[:, [1, 3, 4, 5]])
    line = _refused(["calibrate", path], capsys, "looks like a raw recording, not a positions file")
    assert "(1500 rows, one per sample" in line and line.endswith("; pass --raw")


# == 6. --columns naming a column or a role twice =====================================================
@pytest.mark.parametrize("spec, fragment", [
    ("ax=a,ay=a,az=c", "gives column 'a' for both ax and ay; each role needs a column of its own"),
    ("t=t,ax=a,ay=b,az=a", "gives column 'a' for both ax and az"),
    ("a,a,c", "gives column 'a' for both ax and ay"),
    ("t,a,b,t", "gives column 't' for both t and az"),
    ("ax=a,ax=b,ay=b,az=c", "gives ax more than once (a, b); give each role one column"),
    ("ax=a,ay=b,az=c,ax=0", "gives ax more than once (a, 0)"),
])
def test_a_column_or_role_given_twice_is_one_line(tmp_path, capsys, spec, fragment):
    rows = _imu_rows()
    path = _write(tmp_path / "abc.csv", "t,a,b,c", rows[:, [1, 3, 4, 5]])
    with pytest.raises(InputError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        read_recording(path, columns=spec)
    _refused(["calibrate", path, "--raw", "--columns", spec], capsys, fragment)


def test_columns_as_a_mapping(tmp_path):
    rows = _imu_rows()
    path = _write(tmp_path / "abc.csv", "t,a,b,c", rows[:, [1, 3, 4, 5]])
    rec = read_recording(path, columns={"t": "t", "ax": "c", "ay": "b", "az": 1})
    np.testing.assert_allclose(rec.N, rows[:, [5, 4, 3]], rtol=1e-9)
    with pytest.raises(InputError, match="gives column 'a' for both ax and ay"):
        read_recording(path, columns={"ax": "a", "ay": "a", "az": "c"})


def test_a_column_asked_for_twice_is_read_once(tmp_path):
    """The loader itself takes a repeated column (Arrow's reader refuses one with a KeyError)."""
    rows = _imu_rows()
    path = _write(tmp_path / "abc.csv", "t,a,b,c", rows[:, [1, 3, 4, 5]])
    lay = sniff_layout(path)
    got = _load_numeric(path, lay, [1, 1, 3])
    np.testing.assert_allclose(got, rows[:, [3, 3, 5]], rtol=1e-9)


# == 6. WitMotion's exports =====================================================================================
# The layouts WitMotion's PC software writes (one of issue #29's labs logged with a WitMotion sensor): a
# time-of-day text column, the accelerometer in g, the rates in °/s named As or w, angles, and a temperature
# named T(°) that is no time
def _wit(path, header, rows, clock, delimiter=","):
    """``rows`` (_imu_rows) written under ``header`` with ``clock(i)`` as the first field; the angles 0."""
    lines = [header] + [delimiter.join([clock(i), *(f"{v:.6f}" for v in r[3:9]), "0.00", "0.00", "0.00", "25.1"])
                        for i, r in enumerate(rows)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _hms(i, start_s=23 * 3600 + 59 * 60 + 58.5):
    """Sample i at 100 Hz as a time of day hh:mm:ss.fff, from 23:59:58.500 (midnight passes after 1.5 s)."""
    s = (start_s + i / 100.0) % 86400
    return f"{int(s // 3600):02d}:{int(s % 3600 // 60):02d}:{s % 60:06.3f}"


@pytest.mark.parametrize("header,clock,delimiter,temp", [
    ("Time\tax(g)\tay(g)\taz(g)\twx(deg/s)\twy(deg/s)\twz(deg/s)\tAngleX(deg)\tAngleY(deg)\tAngleZ(deg)\tT(°)",
     _hms, "\t", "T(°)"),
    ("Chip Time(),Acceleration X(g),Acceleration Y(g),Acceleration Z(g),Angular velocity X(°/s),"
     "Angular velocity Y(°/s),Angular velocity Z(°/s),Angle X(°),Angle Y(°),Angle Z(°),Temperature(°C)",
     lambda i: ("2024-5-1 " if i < 150 else "2024-5-2 ") + _hms(i), ",", "Temperature(°C)"),
    ("time,AccX(g),AccY(g),AccZ(g),AsX(°/s),AsY(°/s),AsZ(°/s),AngleX(°),AngleY(°),AngleZ(°),T(°C)",
     lambda i: f"{i / 100.0:.3f}", ",", "T(°C)"),
    ("时间\t加速度X(g)\t加速度Y(g)\t加速度Z(g)\t角速度X(°/s)\t角速度Y(°/s)\t角速度Z(°/s)\t角度X(°)\t角度Y(°)\t角度Z(°)\t温度(°C)",
     lambda i: ("2024-05-01T" if i < 150 else "2024-05-02T") + _hms(i), "\t", "温度(°C)"),  # the software in Chinese
])
def test_witmotion_exports_are_read_as_written(tmp_path, header, clock, delimiter, temp):
    """Times of day are seconds from the first sample, across midnight with and without a date; T(°) is the
    temperature, not the time; AsX(°/s) and wx(deg/s) are the gyroscope, in deg/s as the names say, without
    --gyro-units."""
    from optcal.core.gyro.recording import read_gyro

    rows = _imu_rows()
    path = _wit(tmp_path / "wit.txt", header, rows, clock, delimiter)
    rec = read_recording(path)
    names = header.split(delimiter)
    assert rec.columns["t"] == names[0] and rec.columns["temp"] == temp
    assert [rec.columns[r] for r in ("ax", "ay", "az", "gx", "gy", "gz")] == names[1:7]
    np.testing.assert_allclose(rec.t, rows[:, 1], atol=1e-6)  # the clock's ms, from the first sample
    assert rec.rate == pytest.approx(100.0) and rec.temp[0] == 25.1
    np.testing.assert_allclose(rec.N, rows[:, 3:6], atol=1e-6)
    if not header.startswith("time,"):
        assert rec.reading["clock_column"] == names[0]
    gyro = read_gyro(path, rec, units=None)
    assert gyro.reading["gyro_units"] == "deg/s"
    np.testing.assert_allclose(gyro.N, rows[:, 6:9], atol=1e-6)
    np.testing.assert_allclose(gyro.t, rec.t)


def test_clock_seconds():
    from optcal.core.recording.clock import clock_seconds

    assert clock_seconds(["23:59:59.5", "00:00:00.0", "00:00:00,5"]).tolist() == [0.0, 0.5, 1.0]
    assert clock_seconds(["2024-2-28 23:59:59", "2024-02-29 00:00:01", "2024/3/1 00:00:01"]).tolist() == \
        [0.0, 2.0, 86402.0]
    assert clock_seconds(["12:00:00", "2024-1-1 12:00:01"]) is None  # a date on some rows only: not one clock
    assert clock_seconds(["12:00:00", "12:00:0x"]) is None
    assert clock_seconds(["2024-13-1 12:00:00"]) is None  # no such date
    assert clock_seconds([]) is None
    assert clock_seconds([" 1:02:03 ", "2024-5-1T01:02:04"]) is None  # undated, then dated
    assert clock_seconds(["2024-05-01T14:25:31.123", "2024-5-1  14:25:31.133"]).tolist() == pytest.approx([0, 0.01])
    for bad in ("01:2:03", "10:00:00.", "10:00:00.5.5", "null", "10:00", "100:00:00", "x 10:00:00"):
        assert clock_seconds([bad]) is None, bad


def test_a_clock_that_stands_still_is_refused_and_a_rate_reads_past_it(tmp_path, capsys):
    """A PC's clock stamps several samples alike: refused in one line that names the way out; with --rate the
    clock is not read."""
    rows = _imu_rows()
    path = _wit(tmp_path / "wit.csv", "Time,ax(g),ay(g),az(g),wx(deg/s),wy(deg/s),wz(deg/s),A,B,C,T(°)", rows,
                lambda i: _hms(2 * (i // 2)))
    _refused(["calibrate", path, "--raw"], capsys, "does not increase from sample 0 (t = 0) to 1 (t = 0); give the "
                                                   "sample rate with --rate (the clock column is then not read)")
    rec = read_recording(path, rate=50.0)
    assert "t" not in rec.columns and rec.rate == 50.0 and rec.t[1] == pytest.approx(0.02)


def test_gyroscope_units_the_names_contradict_or_do_not_give_are_refused(tmp_path, capsys):
    from optcal.core.gyro.recording import read_gyro, units_from_names

    assert units_from_names(["wx(deg/s)", "wy(°/s)", "wz(dps)"]) == "deg/s"
    assert units_from_names(["gx [rad/s]", "gy [rad/s]", "gz [rad/s]"]) == "rad/s"
    assert units_from_names(["gx(deg/s)", "gy(rad/s)", "gz(rad/s)"]) is None
    assert units_from_names(["gx", "gy", "gz"]) is None and units_from_names(["GyrX(raw)"] * 3) is None
    rows = _imu_rows()
    path = _wit(tmp_path / "wit.csv", "time,AccX(g),AccY(g),AccZ(g),AsX(°/s),AsY(°/s),AsZ(°/s),A,B,C,T(°)", rows,
                lambda i: f"{i / 100.0:.2f}")
    _refused(["imu", path, "--gyro-units", "rad/s", "-o", tmp_path / "i.json"], capsys,
             "--gyro-units rad/s, but the gyroscope's columns in")
    assert not (tmp_path / "i.json").exists()
    acc = read_recording(path)
    assert read_gyro(path, acc, units="counts").reading["gyro_units"] == "counts"  # counts: the names cannot say
    plain = _write(tmp_path / "plain.csv", "t,ax,ay,az,gx,gy,gz", rows[:, [1, 3, 4, 5, 6, 7, 8]])
    with pytest.raises(InputError, match=r"give the gyroscope's units with `gyro_units` .* \(the names of its "):
        read_gyro(plain, read_recording(plain), units=None)


# == 7. the accelerometer's units from its columns' names ========================================================
@pytest.mark.parametrize("names,units,factor", [
    ("t,ax(g),ay(g),az(g)", "g", 1.0),
    ('"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)","Acceleration z (m/s^2)"', "m/s2", 9.81),
    ("time [s],Acc X [m/s²],Acc Y [m/s²],Acc Z [m/s²]", "m/s2", 9.81),
    ("t,AccX(mg),AccY(mg),AccZ(mg)", "mg", 1000.0),
    ("t,ax,ay,az", "g", 1.0),  # no unit named: g, as before
])
def test_the_accelerometers_units_come_from_its_names_when_not_given(tmp_path, capsys, names, units, factor):
    """A phone's log (phyphox writes "Acceleration x (m/s^2)") is read in m/s² without --units, and the report says
    where the units came from; given units are taken as given (and checked against the data as always)."""
    rows = _imu_rows()
    data = np.column_stack([rows[:, 1], rows[:, 3:6] * factor])
    path = _write(tmp_path / "acc.csv", names, data)
    rec = read_recording(path, units=None)
    assert rec.units == units and rec.reading.get("units_from_names", False) == (units != "g" or "(g)" in names)
    if factor == 1.0:
        assert read_recording(path).units == "g"
    else:  # the library's default stays g: the data are then refused as not in g
        with pytest.raises(InputError, match="the outputs. norms are about"):
            read_recording(path)


def test_calibrate_reads_a_phone_log_in_the_units_its_names_give(tmp_path, capsys, poses):
    rec, _ = poses
    path = _write(tmp_path / "phone.csv", '"Time (s)","Acceleration x (m/s^2)","Acceleration y (m/s^2)",'
                                          '"Acceleration z (m/s^2)"', np.column_stack([rec.t, rec.N * 9.80665]))
    code, out, err = _cli(["calibrate", path, "--raw", "-o", tmp_path / "cal.json"], capsys)
    assert code == 0, err
    assert "units m/s2 (as the columns' names give them)" in out.splitlines()[0]
    assert json.loads((tmp_path / "cal.json").read_text())["units"]["raw"] == "m/s2"


def test_accelerometer_units_from_names():
    from optcal.core.recording.sniff import units_from_names

    assert units_from_names(["ax(g)", "ay (g)", "az [g]"]) == "g"
    assert units_from_names(["a_x [m/s^2]", "a_y [m/s2]", "a_z (m/s²)"]) == "m/s2"
    assert units_from_names(["AccX(LSB)", "AccY(lsb)", "AccZ(counts)"]) == "counts"
    assert units_from_names(["ax(g)", "ay(g)", "az(m/s^2)"]) is None  # not one unit
    assert units_from_names(["ax", "ay", "az"]) is None and units_from_names(["ax(raw)"] * 3) is None


@pytest.mark.parametrize("units_line", ["s,g,g,g", "[s],[g],[g],[g]", "(s),(g),(g),(g)", "s,g,g,", "-,g,g,g"])
def test_a_line_of_units_under_the_names_is_not_the_header(tmp_path, units_line):
    """A logger's header of names, then a line of their units: the names are the header (the units line was
    taken for it, and refused as naming column 'g' twice)."""
    rows = _imu_rows()
    body = "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows[:, [1, 3, 4, 5]])
    (tmp_path / "u.csv").write_text("t,ax,ay,az\n" + units_line + "\n" + body + "\n")
    rec = read_recording(tmp_path / "u.csv")
    assert rec.columns == {"t": "t", "ax": "ax", "ay": "ay", "az": "az"}
    np.testing.assert_allclose(rec.N, rows[:, 3:6], atol=1e-6)
    # a second line of other words is still refused as a header of its own
    (tmp_path / "w.csv").write_text("t,ax,ay,az\nfoo,bar,baz,qux\n" + body + "\n")
    with pytest.raises(InputError, match="cannot tell which columns are ax, ay, az"):
        read_recording(tmp_path / "w.csv")


@pytest.mark.parametrize("device,values", [("DeviceName", ("WT901(AA:01)", "WT901(AA:02)")), ("imu", (0, 1)),
                                           ("Sensor ID", ("left", "right"))])
def test_rows_of_several_devices_are_refused(tmp_path, capsys, device, values):
    """WitMotion's app logs several sensors into one file, a row each in turn (its DeviceName column): no
    calibration fits them as one sensor, and a clock that stands still would have pointed to --rate, which
    would then have fitted them anyway. One device's rows are read."""
    rows = _imu_rows()
    lines = [f"time,{device},ax,ay,az"] + [f"{r[1]:.2f},{values[i % 2]},{r[3]:.6f},{r[4]:.6f},{r[5]:.6f}"
                                           for i, r in enumerate(rows)]
    (tmp_path / "two.csv").write_text("\n".join(lines) + "\n")
    line = _refused(["calibrate", tmp_path / "two.csv", "--raw", "--rate", "100"], capsys, "rows come from 2 devices")
    assert str(values[0]) in line and "keep one device's rows in a file of their own" in line
    one = [ln for i, ln in enumerate(lines) if i == 0 or i % 2 == 1]
    (tmp_path / "one.csv").write_text("\n".join(one) + "\n")
    assert len(read_recording(tmp_path / "one.csv")) == len(one) - 1


def test_the_chips_clock_is_read_before_the_pcs(tmp_path):
    """WitMotion's PC software writes the PC's time (which stamps packets of samples alike) and the chip's; the
    chip's is read."""
    rows = _imu_rows()
    lines = ["Time,Chip Time(),ax(g),ay(g),az(g)"] + [
        f"10:00:{(i // 3) * 0.03:06.3f},2024-5-{1 + (i >= 150)} {_hms(i)},{r[3]:.6f},{r[4]:.6f},{r[5]:.6f}"
        for i, r in enumerate(rows)]
    (tmp_path / "pc.csv").write_text("\n".join(lines) + "\n")
    rec = read_recording(tmp_path / "pc.csv")
    assert rec.columns["t"] == rec.reading["clock_column"] == "Chip Time()"
    np.testing.assert_allclose(rec.t, rows[:, 1], atol=1e-6)


def test_noise_reads_a_witmotion_export_with_its_clock_and_units(tmp_path, capsys):
    """optcal noise takes the gyroscope's units from the --gyro-columns named (AsX(°/s)) and its times from the
    clock column, as optcal imu does."""
    rows = _imu_rows()
    path = _wit(tmp_path / "wit.txt", "Time\tax(g)\tay(g)\taz(g)\tAsX(°/s)\tAsY(°/s)\tAsZ(°/s)\tA\tB\tC\tT(°)", rows,
                _hms, "\t")
    code, out, err = _cli(["noise", path, "--gyro-columns", "AsX(°/s),AsY(°/s),AsZ(°/s)"], capsys)
    assert code == 0, err
    assert "gyroscope, " in out and "units deg/s, 57.2958 deg/s per rad/s (deg/s, exact)" in out
    assert "accelerometer, " in out and "at 100 Hz" in out


def test_several_accelerometers_side_by_side_are_refused_with_the_columns_of_one(tmp_path, capsys):
    """Six IMUs on one bar logged into one file (imu1_ax … imu6_gz): refused in one line that counts them and gives
    the --columns of the first, which then reads."""
    rows = _imu_rows()
    names = ["time"] + [f"imu{k}_{a}" for k in range(1, 7) for a in ("ax", "ay", "az", "gx", "gy", "gz")]
    table = np.column_stack([rows[:, 1]] + [rows[:, 3:9]] * 6)
    path = _write(tmp_path / "six.csv", ",".join(names), table)
    line = _refused(["calibrate", path, "--raw"], capsys, "its columns hold 6 accelerometers (imu1, imu2, imu3, "
                                                          "imu4, … (2 more)); calibrate one at a time: --columns "
                                                          "t=time,ax=imu1_ax,ay=imu1_ay,az=imu1_az")
    rec = read_recording(path, columns=line.rsplit("--columns ", 1)[1])
    np.testing.assert_allclose(rec.N, rows[:, 3:6], rtol=1e-9)
    # one accelerometer under a prefix: the usual refusal naming the columns, with its columns as the example
    one = _write(tmp_path / "one.csv", "time,imu1_ax,imu1_ay,imu1_az,other", np.column_stack([rows[:, [1, 3, 4, 5]],
                                                                                          rows[:, 6]]))
    with pytest.raises(InputError, match="cannot tell which columns are ax, ay, az .* name them with `columns`, e.g. "
                                         "t=time,ax=imu1_ax,ay=imu1_ay,az=imu1_az$"):
        read_recording(one)


@pytest.mark.parametrize("typed", ["dps", "°/s", "DPS", "deg/sec"])
def test_gyro_units_spelt_otherwise_are_deg_s(typed):
    from optcal.app.commands._dataopts import gyro_units_arg

    assert gyro_units_arg(typed) == "deg/s" and gyro_units_arg("rad/sec") == "rad/s"
    assert gyro_units_arg("counts") == "counts" and gyro_units_arg("degs") == "degs"  # argparse's choices refuse it


def test_bare_x_y_z_are_named_in_the_refusals_example(tmp_path, capsys):
    """A phone logger's accelerometer file (time, seconds_elapsed, z, y, x): x, y, z are not taken for the axes
    unasked (too generic), but the refusal gives them as the example, which then reads."""
    rows = _imu_rows()
    path = _write(tmp_path / "Accelerometer.csv", "time,seconds_elapsed,z,y,x",
                  np.column_stack([rows[:, 1] * 1e9, rows[:, 1], rows[:, [5, 4, 3]]]))
    line = _refused(["calibrate", path, "--raw"], capsys, "name them with --columns, e.g. t=time,ax=x,ay=y,az=z")
    rec = read_recording(path, columns=line.rsplit("e.g. ", 1)[1])
    np.testing.assert_allclose(rec.N, rows[:, 3:6], rtol=1e-9)
    assert rec.rate == pytest.approx(100.0) and rec.reading["time_unit"] == "ns"


# == a log that repeats the sensor's samples ==========================================================
def test_a_log_that_repeats_the_sensors_samples_reads_each_sample_once(tmp_path, capsys):
    """A 400-Hz logging loop over a 100-Hz IMU writes each sample on four rows (a lab's FXOS8700 log: 74 % of
    its rows repeat the one before). Read as is, the noise measured from the rows' differences was the
    quantisation floor (0.7 mg where the sensor has 10-20). Each sample is now read once, at the sensor's rate:
    `calibrate` and `imu` (accelerometer and gyroscope in one file, no time column) give the same calibration,
    bit for bit, as the 100-Hz file; the report says how many rows were left out. A quantised axis that
    repeats at rest is not such a log (HELD_FRACTION)."""
    from optcal.core.recording.reading import held_rows
    from optcal.core.synthetic_imu import handheld_imu

    s = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    table = np.column_stack([s.acc.N, s.gyro.N])
    plain = _write(tmp_path / "imu100.csv", "ax,ay,az,gx,gy,gz", table)
    held = _write(tmp_path / "imu400.csv", "ax,ay,az,gx,gy,gz", np.repeat(table, 4, axis=0))
    rec = read_recording(held, rate=400.0, units="g")
    assert len(rec) == len(table) and rec.rate == pytest.approx(100.0) and rec.reading["held_rows"] == 3 * len(table)
    np.testing.assert_array_equal(rec.N, read_recording(plain, rate=100.0, units="g").N)
    outs = []
    for path, rate in ((plain, 100), (held, 400)):
        code, out, err = _cli(["calibrate", path, "--raw", "--units", "g", "--rate", rate, "--json"], capsys)
        assert code == 0, err
        cal = json.loads(out)
        code, out, err = _cli(["imu", path, "--units", "g", "--gyro-units", "deg/s", "--rate", rate, "--json"],
                              capsys)
        assert code == 0, err
        outs.append((cal["parameters"], json.loads(out)["gyroscope"]))
    assert outs[0] == outs[1]
    code, out, _ = _cli(["calibrate", held, "--raw", "--units", "g", "--rate", 400], capsys)
    assert f"{3 * len(table)} row(s) that repeat the row before on every axis left out" in out
    # a sensor so coarse that its noise (0.15-1 codes) repeats all three axes at rest in up to half the rows, but
    # not in a turn: not such a log; the same held over two rows is
    rng = np.random.default_rng(1)
    for sd in (0.15, 0.3, 1.0):
        x = np.cumsum(rng.normal(0, 1, (4000, 3)), axis=0) * 0.05
        x[1000:1400] += np.linspace(0, 200, 400)[:, None]  # a turn
        coarse = np.round(x + rng.normal(0, sd, (4000, 3)))
        assert held_rows(coarse) is None and held_rows(np.repeat(coarse, 2, axis=0)) is not None


# == a host's time stamps ==============================================================================
def test_a_hosts_jittering_stamps_of_evenly_spaced_samples_are_taken_evenly_spaced(tmp_path):
    """A serial link's host stamps 100-Hz samples on a 1.024-ms tick, with catch-ups (a lab's AHRS board: median
    step 10.24 ms, some of 5 ms, an even 10.000 ms through them): the samples are taken on the even grid (the
    rate 100 Hz, not the median step's 97.7 Hz), and the report says so. Stamps within 0.1 step of a grid are
    kept as they are, and so are stamps with a lost sample (a gap of a step)."""
    from optcal.core.recording.reading import even_times

    n = 3000
    true = 100.0 + np.arange(n) * 0.01
    host = np.floor((true + np.random.default_rng(4).uniform(0, 0.004, n)) / 0.001024) * 0.001024
    t, off = even_times(host)
    np.testing.assert_allclose(np.diff(t), 0.01, rtol=1e-5)  # even, at the true rate
    assert np.ptp(t - true) < 3e-4 and 1e-3 < off < 5e-3  # a constant latency aside, the true times (0.03 step)
    assert even_times(true + 5e-4 * np.sin(np.arange(n)))[1] == 0.0  # 0.05 step: kept
    gap = np.delete(true, 1500)
    assert even_times(gap)[1] == 0.0 and even_times(gap)[0] is gap
    rng = np.random.default_rng(0)
    rows = np.column_stack([host, rng.normal(0, 0.01, (n, 3)) + [0, 0, 1]])
    path = _write(tmp_path / "host.csv", "t,ax,ay,az", rows)
    rec = read_recording(path)
    assert np.median(np.diff(host)) == pytest.approx(0.01024, rel=1e-3)
    assert rec.rate == pytest.approx(100.0, rel=1e-4) and 1e-3 < rec.reading["stamps_jitter_s"] < 5e-3
    np.testing.assert_allclose(np.diff(rec.t), 0.01, rtol=1e-4)


def test_unix_times_are_shown_from_the_first_sample(tmp_path, poses, capsys):
    """A time column of Unix times (a host's clock) is read as it is, and shown from the first sample in the
    report (intervals, notes), which says so; a file whose times start near 0 is shown as it is."""
    rec, _ = poses
    rows = np.column_stack([rec.t + 1535630275.916, rec.N])
    path = tmp_path / "epoch.csv"
    np.savetxt(path, rows, delimiter=",", fmt=["%.6f", "%.8g", "%.8g", "%.8g"], header="t,ax,ay,az", comments="")
    back = read_recording(path)
    assert back.t[0] == pytest.approx(1535630275.916) and back.origin == back.t[0]
    np.testing.assert_allclose(back.shown_t, rec.t, atol=1e-6)
    code, out, err = _cli(["calibrate", path, "--raw", "--model", "diag6"], capsys)
    assert code == 0, err
    assert "times shown from the first sample's stamp, 1535630275.916 s" in out
    assert "    0: samples 0–" in out and "(0.00–" in out and "15356302" not in out.split("\n", 2)[2]
    assert read_recording(_write(tmp_path / "zero.csv", "t,ax,ay,az", np.column_stack([rec.t, rec.N]))).origin == 0


def test_a_loggers_prompts_between_the_data_rows_are_named_by_their_line(tmp_path, capsys):
    """A serial monitor's capture: a banner, then blocks of samples with the firmware's prompts between them. The
    refusal names the first prompt's line in the file (not its data row), quotes it, counts the others and says
    what to do, in one line."""
    rng = np.random.default_rng(2)
    lines = ["--- Terminal on /dev/ttyUSB0 | 115200 8-N-1", "--- Quit: Ctrl+C"]
    for _ in range(3):
        lines.append(">>> Gathering data for 10 seconds...")
        lines += [", ".join(f"{v:.6f}" for v in row) for row in rng.normal(0, 0.01, (300, 3)) + [0, 0, 9.8]]
        lines.append(">>> Type key when ready...")
    path = tmp_path / "monitor.csv"
    path.write_text("\n".join(lines) + "\n")
    line = _refused(["calibrate", path, "--raw", "--units", "m/s2", "--rate", 100], capsys,
                    "line 304 holds text between the data rows ('>>> Type key when ready...'), and 4 more such line(s)")
    assert "remove them" in line


def test_a_refused_pose_is_named_by_its_time(poses):
    """A pose the detection refuses (without a gyroscope, one that shakes at 10 times the noise) is named in the
    note with its times and the reason, so that a user finds it without a figure."""
    from dataclasses import replace

    from optcal.core.recording import segment_static

    rec, rests = poses
    s, e = rests[5]
    N = rec.N.copy()
    N[s:e] += 0.01 * np.random.default_rng(0).standard_normal((e - s, 3))
    det = segment_static(replace(rec, N=N))
    note = next(n for n in det.notes if "not at rest" in n)
    assert "as long as a pose: " in note and "(noisy)" in note
    t0, t1 = (float(v) for v in note.split("as long as a pose: ")[1].split(" s (noisy)")[0].split("-"))
    assert abs(t0 - rec.t[s]) < 0.2 and abs(t1 - rec.t[e - 1]) < 0.2, (note, rec.t[s], rec.t[e - 1])


def test_apply_writes_every_row_at_its_own_time(tmp_path, capsys):
    """apply turns each row as written into a calibrated row: a log that repeats its samples keeps all its rows, and
    a host's jittering stamps are written as they were (the fits read the sensor's samples on an even grid)."""
    from optcal.core.synthetic_imu import handheld_imu

    s = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    n = 4 * len(s.acc.N)
    t = np.floor((np.arange(n) * 0.0025 + np.random.default_rng(3).uniform(0, 0.001, n)) / 0.000256) * 0.000256
    rows = np.column_stack([t, np.repeat(s.acc.N, 4, axis=0)])
    path = tmp_path / "log.csv"
    np.savetxt(path, rows, delimiter=",", fmt=["%.6f", "%.8g", "%.8g", "%.8g"], header="t,ax,ay,az", comments="")
    rec = read_recording(path, units="g")
    assert rec.reading["held_rows"] > 0 and rec.reading["stamps_jitter_s"] > 0
    code, _, err = _cli(["calibrate", path, "--raw", "--units", "g", "--model", "diag6", "-o", tmp_path / "c.json"],
                        capsys)
    assert code == 0, err
    code, _, err = _cli(["apply", tmp_path / "c.json", path, "-o", tmp_path / "out.csv"], capsys)
    assert code == 0, err
    out = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    assert len(out) == n
    np.testing.assert_allclose(out[:, 0], rows[:, 0], atol=1e-9)


def test_at_a_low_rate_a_pose_has_at_least_eight_samples():
    """At 5 Hz the default shortest pose, 0.5 s, would be 3 samples, too few to tell a rest from a piece of a slow
    turn (a turntable log at 5 Hz gave 27 "rests" of 1-5 samples inside its turns): a pose is never shorter than
    8 samples. 12 poses held 10 s, turned at 5 °/s: every pose found, and no interval from a turn."""
    from optcal.core.recording import segment_static

    syn = poses_recording(np.random.default_rng(8), n_poses=12, hold_s=10.0, rate=5.0, turn_rate_dps=5.0,
                          noise_g=2e-3)
    det = segment_static(syn.recording)
    assert det.min_samples == 8
    iv = det.intervals
    inside = (iv[:, None, 0] >= syn.rests[None, :, 0] - 2) & (iv[:, None, 1] <= syn.rests[None, :, 1] + 2)
    assert inside.any(axis=1).all(), iv  # no interval outside a pose
    assert len(np.unique(np.argmax(inside, axis=1))) == 12  # every pose


@pytest.mark.parametrize("first", [1, 0])
def test_a_header_of_column_numbers_is_no_sample(tmp_path, first):
    """A logger's header that numbers the columns (``1,2,…,9``, a six-face log of another lab; or from 0): it was
    read as the first sample, (1, 2, 3) m/s². Now skipped; the columns go by index as without a header."""
    rng = np.random.default_rng(0)
    data = np.column_stack([rng.normal(0, 0.01, (200, 2)), 9.81 + rng.normal(0, 0.01, 200), rng.normal(0, 1, (200, 3))])
    path = tmp_path / "numbered.csv"
    np.savetxt(path, data, delimiter=",", header=",".join(str(first + k) for k in range(6)), comments="", fmt="%.5f")
    rec = read_recording(path, columns="ax=0,ay=1,az=2", rate=100.0, units="m/s2")
    assert len(rec) == 200 and np.allclose(rec.N[0], data[0, :3], atol=1e-5)
    # a data row that merely starts with small integers stays a sample
    np.savetxt(path, np.vstack([[1.0, 2.0, 9.0, 0.0, 0.0, 0.0], data]), delimiter=",", fmt="%.5f")
    assert len(read_recording(path, columns="ax=0,ay=1,az=2", rate=100.0, units="m/s2")) == 201


def test_a_trailing_delimiter_is_no_column(tmp_path):
    """Every row ending with the delimiter (``t,ax,ay,az,``): an empty field, not a fifth column named ''."""
    from optcal.core.recording.sniff import sniff_layout

    rng = np.random.default_rng(0)
    path = tmp_path / "trail.csv"
    rows = [f"{i * 0.01:.2f},{rng.normal(0, 0.01):.5f},{rng.normal(0, 0.01):.5f},{1 + rng.normal(0, 0.01):.5f},"
            for i in range(300)]
    path.write_text("t,ax,ay,az,\n" + "\n".join(rows) + "\n")
    lay = sniff_layout(path)
    assert lay.ncol == 4 and lay.header == ["t", "ax", "ay", "az"]
    rec = read_recording(path, units="g")
    assert len(rec) == 300 and rec.rate == pytest.approx(100.0)


def test_a_unix_time_in_nanoseconds_is_read_as_such(tmp_path):
    """A logger's epoch stamps in ns at 1 kHz (1.73e18): in µs they would also give a rate above 1 Hz (1.0 Hz) and were
    taken for it (a rocket club's IMU log: 16,618 s at 1 Hz, 452 "rests" of 3-10 samples). A first value that is a
    date in one unit only settles it: ns, 1 kHz."""
    rng = np.random.default_rng(1)
    t = 1_730_000_000_000_000_000 + np.arange(3000, dtype=np.int64) * 1_000_000
    path = tmp_path / "epoch_ns.csv"
    acc = np.array([0.0, 0.0, 1.0]) + 1e-3 * rng.standard_normal((3000, 3))
    path.write_text("timestamp,ax,ay,az\n" + "\n".join(f"{ti},{a:.6f},{b:.6f},{c:.6f}" for ti, (a, b, c)
                                                       in zip(t.tolist(), acc)) + "\n")
    rec = read_recording(path, units="g")
    assert rec.reading["time_unit"] == "ns" and rec.rate == pytest.approx(1000.0, rel=1e-3)
