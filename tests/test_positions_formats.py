"""Positions files as other labs write them (issue #20, docs/design.md, "Positions CSV"): the same 24 positions with a
comma, semicolon, tab or spaces between the numbers, a decimal comma, a byte-order mark, a commented header
line (``#``, ``%``), no header at all, compressed; the checks and messages of the comma-separated reader kept;
and a positions file and a raw recording given for each other, told apart by their data, with advice that,
followed once, reads the file (never a loop)."""

import gzip
import json
import logging
import struct
from argparse import Namespace

import numpy as np
import pytest

from optcal.app.cli import main
from optcal.core.data import read_positions
from optcal.core.errors import InputError
from optcal.core.recording import read_recording
from optcal.core.recording.sniff import POSITION_JUMP, SAMPLE_JUMP, jump_ratio, mat_table
from optcal.core.schemes import scheme
from optcal.core.simulate import simulate


@pytest.fixture(scope="module")
def P():
    """24 positions of a linear9 sensor, 20 µg of noise on each mean, rounded to 7 decimals (so that every
    layout below holds the same numbers exactly)."""
    sim = simulate("linear9", {"K_x": 1.01, "K_y": 0.99, "K_z": 1.02, "b_x": 0.01, "b_y": -0.02, "b_z": 0.03,
                               "S_yz": 1e-3, "S_zy": -2e-3, "S_zx": 1.5e-3}, np.random.default_rng(20),
                   scheme="24", noise_g=20e-6)
    return np.round(sim.data.N, 7)


def _table(P, delim=",", decimal=".", position=False):
    rows = [([str(i)] if position else []) + [f"{v:.7f}".replace(".", decimal) for v in p] for i, p in enumerate(P)]
    return "\n".join(delim.join(r) for r in rows) + "\n"


LAYOUTS = {  # name: (text before the table, delimiter, decimal mark, position column, encoding's BOM)
    "comma": ("position,ax,ay,az\n", ",", ".", True),
    "semicolon": ("position;ax;ay;az\n", ";", ".", True),
    "tab": ("position\tax\tay\taz\n", "\t", ".", True),
    "spaces": ("position ax ay az\n", " ", ".", True),
    "semicolon-decimal-comma": ("ax;ay;az\n", ";", ",", False),
    "tab-decimal-comma": ("ax\tay\taz\n", "\t", ",", False),
    "spaces-decimal-comma": ("ax ay az\n", " ", ",", False),
    "bom": ("\ufeffax,ay,az\n", ",", ".", False),
    "hash-header": ("# bench 3, 2026-11-24\n# position ax ay az\n", ",", ".", True),
    "percent-header": ("% written by Octave\n%   ax   ay   az\n", " ", ".", False),
    "no-header-3": ("", " ", ".", False),
    "no-header-4": ("", ",", ".", True),
    "remark-of-four-words": ("# mean outputs per pose\n", ",", ".", True),  # not names: columns by position
}


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_the_same_positions_in_every_layout(tmp_path, P, name):
    pre, delim, dec, position = LAYOUTS[name]
    path = tmp_path / f"{name}.csv"
    path.write_text(pre + _table(P, delim, dec, position), encoding="utf-8")
    data = read_positions(path)
    np.testing.assert_array_equal(data.N, P)
    np.testing.assert_array_equal(data.position, np.arange(24))
    assert data.extra == {}
    gz = tmp_path / f"{name}.csv.gz"
    gz.write_bytes(gzip.compress(path.read_bytes()))
    np.testing.assert_array_equal(read_positions(gz).N, P)


def test_every_layout_calibrates_alike_from_the_command_line(tmp_path, P, capsys):
    fits = []
    for name in ("comma", "tab-decimal-comma", "hash-header", "no-header-3"):
        pre, delim, dec, position = LAYOUTS[name]
        path = tmp_path / f"{name}.txt"
        path.write_text(pre + _table(P, delim, dec, position))
        assert main(["calibrate", str(path), "--model", "linear9", "--json"]) == 0, capsys.readouterr().err
        fits.append(json.loads(capsys.readouterr().out)["parameters"])
    assert all(f == fits[0] for f in fits)  # the same numbers give the same fit, to the last bit
    assert fits[0]["K_x"] == pytest.approx(1.01, abs=1e-4)


def test_header_less_positions_other_than_3_or_4_numbered_columns_are_refused(tmp_path, P):
    t = np.arange(24) * 12.5
    path = tmp_path / "t_first.txt"
    path.write_text("\n".join(" ".join(f"{v:.7f}" for v in (ti, *p)) for ti, p in zip(t, P)) + "\n")
    with pytest.raises(InputError, match=r"4 columns and no header; a positions file without a header has 3 "
                                         r"columns \(ax, ay, az\) or 4 \(position 0, 1, 2"):
        read_positions(path)
    path.write_text("# t ax ay az\n" + path.read_text())  # named in a comment line, it is read
    data = read_positions(path)
    np.testing.assert_array_equal(data.t, t)
    np.testing.assert_array_equal(data.N, P)
    five = tmp_path / "five.csv"
    five.write_text("\n".join(",".join(f"{v:.7f}" for v in (*p, 20.0, 30.0)) for p in P) + "\n")
    with pytest.raises(InputError, match="5 columns and no header; .* add a header line naming the columns"):
        read_positions(five)


def test_the_checks_and_messages_stay_with_every_delimiter(tmp_path, P):
    """Duplicates, a misnamed column, a word or nan in a cell (named by its physical line, comment lines
    counted), negative SDs: the comma-separated reader's messages, now for each layout."""
    body = _table(P, ";", ",", True).splitlines()
    cases = {
        "dup": ("position;ax;ay;az;ax\n" + "\n".join(r + ";1" for r in body), "names column 'ax' 2 times"),
        "misnamed": ("position;accx1;accy1;accz1\n" + "\n".join(body), "rename 'accx1' → 'ax'"),
        "word": ("# one remark\nposition;ax;ay;az\n" + "\n".join(body[:3] + ["3;0,1;abc;0,9"] + body[4:]),
                 "line 6, column 'ay': 'abc' is not a number"),
        "nan": ("position;ax;ay;az\n" + "\n".join(body[:2] + ["2;nan;0;1"] + body[3:]), "line 4, column 'ax' is nan"),
        "negative sd": ("position;ax;ay;az;n;sx;sy;sz\n" + "\n".join(r + ";100;-1e-4;1e-4;1e-4" for r in body),
                        "negative standard deviation"),
        "header only": ("position;ax;ay;az\n", "has a header but no positions"),
        "comments only": ("# nothing here\n% nor here\n", "is empty"),
    }
    for name, (text, fragment) in cases.items():
        path = tmp_path / f"{name.replace(' ', '_')}.csv"
        path.write_text(text)
        with pytest.raises(InputError) as exc:
            read_positions(path)
        assert fragment in str(exc.value), (name, str(exc.value))
    # the raw reader's names of the axes read here too (a lab's pose table of acc_x, acc_y, acc_z was refused)
    aliased = tmp_path / "aliased.csv"
    aliased.write_text("pose_name;acc_x;Acc_Y;ACCELZ\n" + "\n".join(body))
    plain = tmp_path / "plain.csv"
    plain.write_text("position;ax;ay;az\n" + "\n".join(body))
    np.testing.assert_array_equal(read_positions(aliased).N, read_positions(plain).N)
    binary = tmp_path / "bin.csv"
    binary.write_bytes(b"\x00\x01\x02MATLAB\x00")
    with pytest.raises(InputError, match="cannot read .* binary file, not text"):
        read_positions(binary)


def test_commented_header_lines_in_raw_recordings(tmp_path):
    rng = np.random.default_rng(5)
    n = 1500
    A = np.round(rng.standard_normal((n, 3)) * 1e-3 + [0.0, 0.0, 1.0], 6)
    t = np.arange(n) / 200.0
    table = "\n".join(f"{ti:.3f},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f}" for ti, a in zip(t, A))
    (tmp_path / "hash.csv").write_text("# logger v2\n# time,acc_x,acc_y,acc_z\n" + table + "\n")
    (tmp_path / "percent.txt").write_text("% t ax ay az\n" + table.replace(",", " ") + "\n")
    for name in ("hash.csv", "percent.txt"):
        rec = read_recording(tmp_path / name)
        np.testing.assert_array_equal(rec.N, A)
        assert rec.rate == pytest.approx(200.0)
        assert list(rec.columns) == ["t", "ax", "ay", "az"] and rec.reading["header"] == "comment line"
    assert read_recording(tmp_path / "hash.csv").columns["ax"] == "acc_x"
    (tmp_path / "plain.txt").write_text("# t ax ay az, but not here\n" + table.replace(",", " ") + "\n")
    rec = read_recording(tmp_path / "plain.txt")  # a remark of another width: columns by position
    assert rec.reading["header"] == "none" and rec.columns == {"t": 0, "ax": 1, "ay": 2, "az": 3}


# -- positions or samples: by the data, and advice that never loops ------------------------------------------
def _recording(rng, rate=100.0, dwell_s=3.0, move_s=1.0):
    """A sensor (in g) held still in each of the 24 poses for ``dwell_s`` and turned smoothly between them."""
    dirs = scheme("24")
    nd, nm = int(dwell_s * rate), int(move_s * rate)
    parts = [np.repeat(dirs[:1], 2 * nd, 0)]
    for a, b in zip(dirs[:-1], dirs[1:]):
        s = (0.5 - 0.5 * np.cos(np.linspace(0, np.pi, nm)))[:, None]
        v = (1 - s) * a + s * b + 1e-3
        parts += [v / np.linalg.norm(v, axis=1, keepdims=True), np.repeat(b[None], nd, 0)]
    A = np.concatenate(parts) * [1.01, 0.99, 1.02] + [0.01, -0.02, 0.03]
    return A + 1e-3 * rng.standard_normal(A.shape)


@pytest.fixture(scope="module")
def files(tmp_path_factory, P):
    """One file of each kind, with what the wrong reader must say and the options that read it."""
    from scipy.io import savemat

    d = tmp_path_factory.mktemp("kinds")
    rng = np.random.default_rng(21)
    A = _recording(rng)
    t = np.arange(len(A)) / 100.0
    np.savetxt(d / "rec.csv", np.column_stack([t, A]), delimiter=",", fmt="%.6f", header="t,ax,ay,az", comments="")
    np.savetxt(d / "rec4.txt", np.column_stack([t, A]), fmt="%.6f")
    np.savetxt(d / "rec3.txt", A, fmt="%.6f")
    savemat(d / "rec.mat", {"log": np.column_stack([t, A])})
    np.savetxt(d / "pos3.txt", P, fmt="%.7f")
    (d / "pos_named.csv").write_text("position,ax,ay,az,n,sx,sy,sz\n" + "\n".join(
        f"{i},{p[0]:.7f},{p[1]:.7f},{p[2]:.7f},300,0.001,0.001,0.001" for i, p in enumerate(P)) + "\n")
    savemat(d / "pos.mat", {"V": P.T})
    # a thermal test: the six faces, each kept while the chamber steps through five temperatures; consecutive
    # rows differ by noise (the data say samples), the columns say positions, and 30 rows are not a recording
    six = scheme("6")
    T = np.repeat(six, 5, 0) * 1.01 + 0.01 + 2e-5 * rng.standard_normal((30, 3))
    (d / "thermal.csv").write_text("position,ax,ay,az,temp,n,sx,sy,sz\n" + "\n".join(
        f"{i},{p[0]:.7f},{p[1]:.7f},{p[2]:.7f},{20 + 5 * (i % 5)},500,0.001,0.001,0.001"
        for i, p in enumerate(T)) + "\n")
    positions = ["--model", "diag6"]
    return {  # file: (options that misread it, what they say, options that read it)
        "rec.csv": (positions, "pass --raw", ["--raw", *positions]),
        "rec4.txt": (positions, "pass --raw", ["--raw", *positions]),
        "rec3.txt": (positions, "pass --raw with --rate HZ (it has no time column)",
                     ["--raw", "--rate", "100", *positions]),
        "rec.mat": (positions, "pass --raw", ["--raw", *positions]),
        "pos3.txt": (["--raw", "--rate", "50", *positions], "read it as positions (drop --raw)", positions),
        "pos_named.csv": (["--raw", *positions], "read it as positions (drop --raw)", positions),
        "pos.mat": (["--raw", "--rate", "50", *positions], "read it as positions (drop --raw)", positions),
        "thermal.csv": (["--raw", *positions], "read it as positions (drop --raw)", positions),
    }, d


@pytest.mark.parametrize("name", ["rec.csv", "rec4.txt", "rec3.txt", "rec.mat", "pos3.txt", "pos_named.csv",
                                  "pos.mat", "thermal.csv"])
def test_the_wrong_reader_says_which_and_its_advice_reads_the_file(files, name, capsys):
    cases, d = files
    wrong, advice, right = cases[name]
    code = main(["calibrate", str(d / name), *wrong])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "looks like" in err, err
    assert err.rstrip().endswith(advice), err
    code = main(["calibrate", str(d / name), *right, "--json"])
    err = capsys.readouterr().err
    assert code == 0 and "looks like" not in err, err


def test_the_decision_is_the_data_s(P):
    """Consecutive positions of the 24-position scheme are a median 76 % of g apart; a recording's samples
    (1 mg of noise, turns between 3 s rests) 0.24 %; a sweep in 5° steps, 8.7 %, is neither, and each reader
    then reads it as asked (no refusal, so no loop)."""
    rec = _recording(np.random.default_rng(22))
    assert jump_ratio(P) == pytest.approx(0.765, abs=0.01) and jump_ratio(P) >= POSITION_JUMP
    assert jump_ratio(rec) == pytest.approx(0.0023, abs=3e-4) and jump_ratio(rec) <= SAMPLE_JUMP
    a = np.radians(np.arange(24) * 5.0)
    sweep = np.column_stack([np.sin(a), np.zeros(24), np.cos(a)])
    assert jump_ratio(sweep) == pytest.approx(2 * np.sin(np.radians(2.5)), rel=1e-9)
    assert SAMPLE_JUMP < jump_ratio(sweep) < POSITION_JUMP
    assert jump_ratio(np.ones((1, 3))) is None and jump_ratio(np.zeros((5, 3))) is None


def test_a_file_of_neither_kind_is_read_as_asked(tmp_path, capsys):
    a = np.radians(np.arange(24) * 5.0)
    sweep = np.column_stack([np.sin(a), 0.02 * np.cos(3 * a), np.cos(a)])
    path = tmp_path / "sweep.txt"
    np.savetxt(path, sweep, fmt="%.7f")
    from optcal.app.commands._dataopts import load_positions

    data = load_positions(Namespace(raw=False, units="g"), path)
    np.testing.assert_allclose(data.N, sweep, atol=1e-7)
    assert read_recording(path, rate=10.0, refuse_positions=True).N.shape == (24, 3)


# -- MATLAB files MATLAB reads and scipy refuses ---------------------------------------------------------
def test_mat_file_with_a_wrong_zlib_checksum_is_read_with_a_warning(tmp_path, P, caplog):
    """The Adler-32 checksum of a compressed variable flipped: scipy refuses the file, MATLAB reads it; the
    data inflate in full, so they are read, with a warning. A deflate stream cut short is refused in one line."""
    import io

    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, {"V": P}, do_compression=True)
    raw = bytearray(buf.getvalue())
    typ, nbytes = struct.unpack("<II", raw[128:136])
    assert typ == 15  # miCOMPRESSED
    end = 136 + nbytes
    raw[end - 4:end] = bytes(b ^ 0xFF for b in raw[end - 4:end])
    path = tmp_path / "checksum.mat"
    path.write_bytes(bytes(raw))
    with caplog.at_level(logging.WARNING, logger="optcal"):
        header, table = mat_table(path)
    assert header is None
    np.testing.assert_array_equal(table, P)
    assert "1 compressed variable(s) fail their zlib checksum but inflate in full" in caplog.text
    # read again (as a command reads a file for its layout and then its data): said once per file, not each time
    mat_table(path)
    assert caplog.text.count("fail their zlib checksum") == 1
    cut = bytearray(raw)
    cut[150:end] = bytes(end - 150)  # the deflate stream zeroed from its 15th byte on
    (tmp_path / "cut.mat").write_bytes(bytes(cut))
    with pytest.raises(InputError, match=r"^cannot read MAT file .*cut\.mat: a compressed variable is damaged "
                                         r"\(.*\); save it again from MATLAB$"):
        mat_table(tmp_path / "cut.mat")


def test_unreadable_mat_files_are_one_line(tmp_path, P, capsys):
    import io

    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, {"V": P})
    raw = buf.getvalue()
    v73 = (b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Tue Nov 24 2026 HDF5 schema 1.00 .".ljust(116)
           + bytes(8) + b"\x00\x02IM" + b"\x89HDF\r\n\x1a\n" + bytes(64))
    bad = {"v73.mat": (v73, "is a MATLAB v7.3 (HDF5) file that cannot be read"),  # an HDF5 signature, no HDF5
           "truncated.mat": (raw[:180], "cannot read MAT file"),
           "junk.mat": (raw[:128] + b"\x01" * 64, "cannot read MAT file"),
           "header_only.mat": (raw[:60], "cannot read MAT file")}
    for name, (data, fragment) in bad.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError) as exc:
            mat_table(tmp_path / name)
        assert fragment in str(exc.value) and "\n" not in str(exc.value), (name, str(exc.value))
        for argv in (["calibrate", str(tmp_path / name)], ["calibrate", str(tmp_path / name), "--raw"]):
            assert main(argv) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and fragment in err, (name, err)


def test_a_long_table_the_positions_reader_cannot_read_may_be_a_recording(tmp_path, capsys):
    """Columns the readers do not recognise (six without a header, or names of their own) leave the raw or
    positions question open; with 1000 rows or more, the positions reader's message offers both readings."""
    rng = np.random.default_rng(7)
    table = np.column_stack([np.arange(1500) / 100.0, rng.standard_normal((1500, 3)) * 1e-3 + [0, 0, 1],
                             rng.standard_normal((1500, 2))])
    six = tmp_path / "six.txt"
    np.savetxt(six, table, fmt="%.6f")
    named = tmp_path / "named.csv"
    np.savetxt(named, table[:, :4], fmt="%.6f", delimiter=",", header="T,U,V,W", comments="")
    for path, fragment in ((six, "6 columns and no header"), (named, "missing column(s) ax, ay, az")):
        assert main(["calibrate", str(path)]) == 2
        err = capsys.readouterr().err
        assert fragment in err and err.count("\n") == 1, err
        assert err.rstrip().endswith("(or, if its 1500 rows are a raw recording's samples, read it with --raw and "
                                     "name its columns with --columns)"), err
        short = tmp_path / f"short_{path.name}"
        short.write_text("\n".join(path.read_text().splitlines()[:30]) + "\n")
        assert main(["calibrate", str(short)]) == 2
        assert "raw recording" not in capsys.readouterr().err  # 30 rows: a positions file with a wrong header
    rec = read_recording(named, columns="t=T,ax=U,ay=V,az=W", refuse_positions=True)
    assert len(rec) == 1500  # read as the message says


def test_the_corpus_files_are_told_apart(corpus):
    """Position means (Hassan & Bao's 24 and 49, MAT files) against recordings (imu_tk's Xsens, the phone, the
    MPU-6050, imucal's session, CK-Explorer; the real corpus, tests/corpus.py): the margins to the two
    thresholds are a factor of about 2 or more."""
    from optcal.core.recording.reading import raw_file_reason
    from optcal.core.recording.sniff import table_kind

    hb = corpus / "hassan_bao"
    for name, ratio in (("CalibrationOfLowCostTriaxialInertialSensors.mat", 0.78),
                        ("CalibrationOfLowCostTriaxialInertialSensors50.mat", 0.40)):
        header, table = mat_table(hb / name)
        assert jump_ratio(table) == pytest.approx(ratio, abs=0.01) and jump_ratio(table) > 1.9 * POSITION_JUMP
        assert table_kind(header, table, len(table))[0] == "positions" and raw_file_reason(hb / name) is None
    for name, ratio in (("imu_tk/xsens_acc.mat.gz", 0.0001), ("hassan_bao/MobileAccData30orientationRawSample01.mat",
                        0.0153), ("mpu6050/example_data_calibration.csv", 0.0087),
                        ("imucal/annotated_session.csv", 0.0073), ("ck_explorer/acc_log.csv", 0.0037)):
        reason, _ = raw_file_reason(corpus / name)
        assert f"a median {ratio:.2%} of the outputs' magnitude" in reason and ratio <= SAMPLE_JUMP / 2, reason
