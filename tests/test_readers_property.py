"""Property tests of the readers (issue #20): whatever the layout (delimiter, decimal mark, header, commented
header, byte-order mark, comment and blank lines, ragged rows, words, empty cells, non-finite numbers) the
positions reader, the raw reader, the raw-or-positions decision and the MAT reader end in a result or a
one-line InputError, never another exception; a well-formed table in any layout reads back the numbers
written; and no file is refused by both readers as the other's kind (the advice never loops)."""

import io
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optcal.core.data import read_positions
from optcal.core.errors import InputError
from optcal.core.recording.reading import raw_file_reason, read_recording
from optcal.core.recording.sniff import mat_table

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
NAMES = ["ax", "ay", "az", "position", "t", "temp", "n", "sx", "sy", "sz", "se_x", "ref_x", "time", "acc_x",
         "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z", "label", "AX", "Fs", ""]
MESSY = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32).map(repr),
    st.integers(-70000, 70000).map(str),
    st.sampled_from(["", "nan", "inf", "-", "abc", "1,5", "1.5.2", '"3"', "'x'", "1e400", "0x10", " ", "#", "%"]),
)
NUMBER = st.floats(-40000, 40000, allow_nan=False).map(lambda v: f"{v:.6g}")
CELLS = st.integers(0, 39).flatmap(lambda k: NUMBER if k else MESSY)  # one cell in 40 messy
DELIMS = [",", ";", "\t", " ", "  "]


@st.composite
def messy_tables(draw):
    """Text that looks more or less like a table."""
    ncol = draw(st.integers(1, 8))
    delim = draw(st.sampled_from(DELIMS))
    lines = []
    if draw(st.booleans()):
        lines.append(draw(st.sampled_from(["#", "%", "# ", "%% "])) + " ".join(draw(st.lists(
            st.sampled_from(NAMES), min_size=ncol, max_size=ncol))))
    if draw(st.booleans()):
        lines.append(delim.join(draw(st.lists(st.sampled_from(NAMES), min_size=ncol, max_size=ncol))))
    for _ in range(draw(st.integers(0, 25))):
        width = ncol if draw(st.integers(0, 9)) else draw(st.integers(0, ncol + 2))  # now and then ragged
        lines.append(delim.join(draw(st.lists(CELLS, min_size=width, max_size=width))))
        if not draw(st.integers(0, 12)):
            lines.append(draw(st.sampled_from(["", "# note", "% note", "Fs,100", "   "])))
    text = "\n".join(lines) + draw(st.sampled_from(["", "\n", "\r\n"]))
    return ("\ufeff" if draw(st.booleans()) else "") + text


def _check_one_line_error(call):
    """Run ``call``; an InputError must be one line. Anything else propagates (and fails the test)."""
    try:
        return call()
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc), repr(str(exc))
        return None


@SETTINGS
@given(messy_tables())
def test_messy_text_is_read_or_refused_in_one_line(text):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "table.csv"
        path.write_text(text, encoding="utf-8")
        _check_one_line_error(lambda: read_positions(path))
        _check_one_line_error(lambda: read_recording(path, rate=100.0, need_time=False, refuse_positions=True))
        _check_one_line_error(lambda: read_recording(path, units="counts", need_time=False))
        found = raw_file_reason(path)  # never raises: a file it cannot place is left to the reader
        assert found is None or (isinstance(found[0], str) and "\n" not in found[0])


@st.composite
def positions_tables(draw):
    """A well-formed positions table in a random layout, and the numbers it holds."""
    n = draw(st.integers(1, 30))
    N = np.array(draw(st.lists(st.lists(st.floats(-2.0, 2.0, allow_nan=False), min_size=3, max_size=3),
                               min_size=n, max_size=n)))
    N = np.round(N, draw(st.integers(0, 9)))
    delim = draw(st.sampled_from(DELIMS))
    decimal = draw(st.sampled_from([".", ","])) if delim != "," else "."
    form = draw(st.sampled_from(["header", "position-header", "commented", "percent", "none", "numbered"]))
    numbered = form in ("position-header", "numbered")
    first = draw(st.integers(0, 1))
    rows = [([str(first + i)] if numbered else []) + [repr(float(v)).replace(".", decimal) for v in p]
            for i, p in enumerate(N)]
    names = (["position"] if numbered else []) + ["ax", "ay", "az"]
    head = {"header": delim.join(names), "position-header": delim.join(names), "commented": "# " + " ".join(names),
            "percent": "%\t" + "\t".join(names), "none": None, "numbered": None}[form]
    comments = draw(st.lists(st.sampled_from(["# a remark", "% made by a script", "#"]), max_size=2))
    lines = comments + ([head] if head else []) + [delim.join(r) for r in rows]
    bom = "\ufeff" if draw(st.booleans()) else ""
    return bom + "\n".join(lines) + "\n", N, (first + np.arange(n)) if numbered else np.arange(n)


@SETTINGS
@given(positions_tables())
def test_well_formed_positions_read_back_in_every_layout(case):
    text, N, position = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "positions.txt"
        path.write_text(text, encoding="utf-8")
        data = read_positions(path)
    np.testing.assert_array_equal(data.N, N)
    np.testing.assert_array_equal(data.position, position)


@st.composite
def numeric_tables(draw):
    """A numeric table of 3 or 4 columns (time first) with or without a header: a recording's samples, a
    positions file's means or anything between, written with a random delimiter."""
    n = draw(st.integers(2, 120))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    kind = draw(st.sampled_from(["rest", "poses", "random", "steps"]))
    if kind == "rest":
        A = np.array([0.0, 0.0, 1.0]) + draw(st.sampled_from([1e-4, 1e-2, 0.1])) * rng.standard_normal((n, 3))
    elif kind == "poses":
        A = np.repeat(rng.standard_normal((n // 10 + 1, 3)), 10, 0)[:n] + 1e-3 * rng.standard_normal((n, 3))
    elif kind == "random":
        A = rng.standard_normal((n, 3))
    else:
        a = np.radians(np.arange(n) * draw(st.floats(0.5, 40.0)))
        A = np.column_stack([np.sin(a), np.zeros(n), np.cos(a)])
    timed = draw(st.booleans())
    table = np.column_stack([np.arange(n) / 100.0, A]) if timed else A
    header = draw(st.sampled_from([None, "names", "aliases", "position"]))
    if header == "position":
        table, names = np.column_stack([np.arange(n), A]), ["position", "ax", "ay", "az"]
    else:
        names = (["t", "time"][header == "aliases"],) * timed + (("ax", "ay", "az"), ("acc_x", "acc_y", "acc_z"))[
            header == "aliases"]
    delim = draw(st.sampled_from([",", ";", "\t", " "]))
    buf = io.StringIO()
    if header:
        buf.write(delim.join(names) + "\n")
    np.savetxt(buf, table, delimiter=delim, fmt="%.7g")
    return buf.getvalue()


@SETTINGS
@given(numeric_tables())
def test_no_file_is_sent_back_and_forth(text):
    """The positions reader's "pass --raw" and the raw reader's "drop --raw" never meet on one file."""
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "table.txt"
        path.write_text(text)
        to_raw = raw_file_reason(path) is not None
        try:
            read_recording(path, rate=100.0, refuse_positions=True)
            to_positions = False
        except InputError as exc:
            to_positions = "looks like a positions file" in str(exc)
    assert not (to_raw and to_positions)


def _mat_bytes():
    """A compressed MAT file of a recording and a text variable, made once."""
    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, {"log": np.column_stack([np.arange(50) / 100.0, np.ones((50, 3))]), "note": "bench"},
            do_compression=True)
    return buf.getvalue()


MAT = _mat_bytes()


@SETTINGS
@given(st.lists(st.tuples(st.integers(0, len(MAT) - 1), st.integers(0, 255)), max_size=6),
       st.integers(60, len(MAT)))
def test_damaged_mat_files_are_read_or_refused_in_one_line(changes, length):
    raw = bytearray(MAT)
    for pos, value in changes:
        raw[pos] = value
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "damaged.mat"
        path.write_bytes(bytes(raw[:length]))
        _check_one_line_error(lambda: mat_table(path))
        _check_one_line_error(lambda: read_recording(path, need_time=False))
        _check_one_line_error(lambda: read_positions(path))
        raw_file_reason(path)


@st.composite
def recordings(draw):
    """A well-formed raw recording (t, ax, ay, az in counts) in a random layout, and its samples."""
    n = draw(st.integers(3, 60))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    N = np.round(rng.standard_normal((n, 3)) * 40 + [0, 0, 16384])
    t = np.arange(n) / 100.0
    delim = draw(st.sampled_from([",", ";", "\t", " "]))
    decimal = draw(st.sampled_from([".", ","])) if delim != "," else "."
    names = draw(st.sampled_from([("t", "ax", "ay", "az"), ("time", "acc_x", "acc_y", "acc_z")]))
    form = draw(st.sampled_from(["header", "hash", "percent", "none", "fs-line"]))
    lines = {"header": [delim.join(names)], "hash": ["# " + " ".join(names)], "percent": ["% " + delim.join(names)],
             "none": [], "fs-line": [f"Fs{delim}100", delim.join(names)]}[form]
    lines = draw(st.lists(st.sampled_from(["# logger 2.1", "% bench"]), max_size=2)) + lines
    lines += [delim.join([f"{ti:.2f}".replace(".", decimal), *(f"{v:.0f}" for v in row)]) for ti, row in zip(t, N)]
    bom = "\ufeff" if draw(st.booleans()) else ""
    return bom + "\n".join(lines) + "\n", t, N


@SETTINGS
@given(recordings())
def test_well_formed_recordings_read_back_in_every_layout(case):
    text, t, N = case
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "rec.txt"
        path.write_text(text, encoding="utf-8")
        rec = read_recording(path, units="counts")
    np.testing.assert_array_equal(rec.N, N)
    np.testing.assert_allclose(rec.t, t, atol=1e-12)
    assert list(rec.columns) == ["t", "ax", "ay", "az"]
