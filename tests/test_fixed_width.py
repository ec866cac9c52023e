"""The fixed-width reader (optcal.core.fixed_width, issue #29's speed): the same bits as numpy.loadtxt on every
table whose lines share one layout, None on anything else, and the raw reader's result unchanged."""

import gzip

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optcal.core.fixed_width import read_fixed_width
from optcal.core.recording import reading
from optcal.core.recording.reading import read_recording

ALWAYS = ["%15.7e", "% .6e", "%+.4E"]  # printf keeps one layout whatever the value (exponents of two digits)
MAYBE = ["%12.6f", "%+10.3f", "%.3e", "%9.1f"]  # the layout moves with the value's sign or magnitude


def _bits(a):
    return np.ascontiguousarray(a, float).view(np.int64)


def _table(values: np.ndarray, fmt: str, sep: str = " ") -> bytes:
    return "".join(sep.join(fmt % v for v in row) + "\n" for row in values).encode()


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(ALWAYS + MAYBE), st.integers(1, 40), st.integers(1, 6), st.integers(0, 2**32 - 1),
       st.sampled_from([1.0, 1e-3, 1e3, 33000.0]), st.booleans())
def test_same_bits_as_loadtxt_or_none(fmt, n, ncol, seed, scale, signed):
    rng = np.random.default_rng(seed)
    values = rng.uniform(-1 if signed else 0, 1, (n, ncol)) * scale
    raw = _table(values, fmt)
    out = read_fixed_width(raw, ncol, list(range(ncol)))
    expected = np.loadtxt(raw.decode().splitlines(), ndmin=2)
    if out is None:
        assert fmt in MAYBE, f"{fmt} keeps one layout, yet the fast path refused it"
        return
    assert out.shape == expected.shape
    assert (_bits(out) == _bits(expected)).all()


@pytest.mark.parametrize("fmt", MAYBE)
def test_a_moving_format_is_read_while_its_layout_holds(fmt):
    values = np.random.default_rng(1).uniform(0.5, 0.9, (50, 3))  # one sign, one magnitude
    out = read_fixed_width(_table(values, fmt), 3, [0, 1, 2])
    assert out is not None
    assert (_bits(out) == _bits(np.loadtxt(_table(values, fmt).decode().splitlines()))).all()


def test_imu_tk_layout_reads_exactly():
    values = np.array([[2.984e-02, 33108, 33329, 36429], [3.9857e-02, -33096, 33336, 36437]])
    raw = _table(values, "%15.7e", sep="")
    out = read_fixed_width(raw, 4, [0, 2, 3])
    assert out.tolist() == [[2.984e-02, 33329.0, 36429.0], [3.9857e-02, 33336.0, 36437.0]]
    assert read_fixed_width(raw, 4, [1]).ravel().tolist() == [33108.0, -33096.0]


@pytest.mark.parametrize("text, why", [
    (b"1.5 2.5\n1.5 2.50\n", "a line longer than the others"),
    (b"1.5 2.5\n\n1.5 2.5\n", "a blank line"),
    (b"1.5 2.5\n# 1 2.5\n", "a comment"),
    (b"1.5 2.5\nnan 2.5\n", "nan"),
    (b" 1.5 2.5\n12.5 2.5\n", "a digit padded with a space"),
    (b"1.5 2.5\n1.5-2.5\n", "fields run together"),
    (b"1.5 2.5\n", "a different number of columns"),
    (b"1.5e99 2.5\n", "an exponent past the exact powers of ten"),
    (b"1234567890123456 1\n", "more digits than binary64 holds exactly"),
    (b"", "no data"),
])
def test_anything_else_is_left_to_loadtxt(text, why):
    ncol = 3 if why == "a different number of columns" else 2
    assert read_fixed_width(text, ncol, list(range(ncol))) is None, why


def test_windows_line_ends_and_no_final_newline():
    out = read_fixed_width(b" 1.25 -3.5\r\n-2.00 +4.0\r\n 0.50 -0.0", 2, [0, 1])
    assert out.tolist() == [[1.25, -3.5], [-2.0, 4.0], [0.5, -0.0]]
    assert np.signbit(out[2, 1])


def test_the_raw_reader_gives_the_same_recording(tmp_path, monkeypatch):
    """A whitespace-separated recording (imu_tk's layout, compressed too) reads to the same samples with the
    fast path as with numpy.loadtxt alone."""
    rng = np.random.default_rng(3)
    n = 5000
    t = 0.01 * np.arange(n) + 0.02984
    table = np.column_stack([t, rng.integers(30000, 36000, (n, 3))])
    plain = tmp_path / "acc.txt"
    plain.write_bytes(_table(table, "%15.7e", sep=""))
    packed = tmp_path / "acc.txt.gz"
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    fast_path = reading._load_fixed_width
    for path in (plain, packed):
        took = []
        monkeypatch.setattr(reading, "_load_fixed_width", lambda *a, took=took: took.append(fast_path(*a)) or took[-1])
        fast = read_recording(path, units="counts")
        monkeypatch.setattr(reading, "_load_fixed_width", lambda *a: None)  # numpy.loadtxt alone
        slow = read_recording(path, units="counts")
        monkeypatch.undo()
        assert took and all(v is not None for v in took), "the fast path did not read the recording"
        assert (_bits(fast.N) == _bits(slow.N)).all() and (_bits(fast.t) == _bits(slow.t)).all()
