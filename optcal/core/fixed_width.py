"""Whitespace-separated numeric text whose every line has the same layout, parsed in a few NumPy passes.

Loggers that print with a fixed format (``"%15.7e"`` per column, as imu_tk's recordings, or ``"%+9.4f"``)
write every line with the same length and every character class in the same column: a sign (or a space for
+), digits, a decimal point, an exponent. Such a table is read here as an (n, L) byte matrix: two reductions
over the columns (their smallest and largest byte) proves the layout holds on every line, and each field's
digits are summed with their weights. :func:`numpy.loadtxt` parses the same numbers one by one (about 40 ms
for imu_tk's 51,000 lines of four columns on the project's machine, against a few here; docs/performance.md,
"Reading a recording"). Anything else (a ragged line, a blank line, a comment, ``nan``, digits padded with
spaces) returns None and the caller falls back to loadtxt.

The values are exactly those of ``float(text)``: a field's digits make an integer mantissa m < 2^53 and a
power of ten 10^k with |k| ≤ 22, both exact in binary64, so m·10^k or m/10^-k is one correctly rounded
operation, as a correctly rounded parse of the text (Clinger, "How to read floating point numbers
accurately", PLDI 1990: the fast path); fields outside that range return None.
"""

from __future__ import annotations

import re

import numpy as np

SPACES = (ord(" "), ord("\t"), ord("\r"))
DIGITS = (ord("0"), ord("9"))
PLUS, MINUS = ord("+"), ord("-")
CONSTANT = {ord("."): ".", ord("e"): "e", ord("E"): "e"}

# a field's columns as letters: s sign (or space), d digit, . point, e exponent mark, x the exponent's sign
_FIELD = re.compile(r"s?(?:d+\.?d*|\.d+)(?:ex?d+)?")
_POW10 = 10.0 ** np.arange(23)  # exact in binary64 up to 10**22
MAX_DIGITS = 15  # mantissa digits: 10**15 < 2**53, so every mantissa is exact


def _letters(M: np.ndarray) -> str | None:
    """Each column's letter (``" "`` a separator) over every row of M (the lines without their newline), or
    None when a column mixes characters no layout allows. A column's smallest and largest byte decide it,
    except a sign's, whose every byte is checked."""
    lo, hi = M.min(axis=0).tolist(), M.max(axis=0).tolist()
    out = []
    for c, (a, b) in enumerate(zip(lo, hi)):
        if DIGITS[0] <= a and b <= DIGITS[1]:
            out.append("d")
        elif a == b and a in SPACES:
            out.append(" ")
        elif a == b and a in CONSTANT:
            out.append(CONSTANT[a])
        elif a in (ord(" "), PLUS, MINUS) and b in (PLUS, MINUS) and np.isin(M[:, c], (ord(" "), PLUS, MINUS)).all():
            # a sign, or a space for +; right after the exponent's mark, the exponent's own sign (never a space)
            out.append("s" if a == ord(" ") or not out or out[-1] != "e" else "x")
        else:
            return None
    return "".join(out)


def read_fixed_width(raw: bytes, ncol: int, usecols: list[int]) -> np.ndarray | None:
    """The columns ``usecols`` of the ``ncol``-column table in ``raw`` (the data lines' bytes, from the first
    data line to the end), as floats (n, len(usecols)); None unless every line has one layout."""
    if not raw:
        return None
    L = raw.find(b"\n") + 1
    if not raw.endswith(b"\n"):  # the last line without its line end: give it the first line's
        raw += b"\r\n" if L > 1 and raw[L - 2:L] == b"\r\n" else b"\n"
        L = L or len(raw)
    buf = np.frombuffer(raw, np.uint8)
    n = len(buf) // L
    if n * L != len(buf) or L < 2:
        return None
    M = buf.reshape(n, L)
    # n rows ending in a newline, and no other newline in the buffer: every line is L bytes long (a newline
    # elsewhere fails the layout, no column's letter takes it)
    if not (M[:, -1] == 10).all():
        return None
    letters = _letters(M[:, :-1])
    if letters is None:
        return None
    fields = [(m.start(), m.end()) for m in re.finditer(r"[^ ]+", letters)]
    if len(fields) != ncol or any(not _FIELD.fullmatch(letters[a:b]) for a, b in fields):
        return None
    out = _values(M, letters, [fields[c] for c in usecols])
    if out is None:
        return None
    first = [float(f) for f in raw[:L].split()]
    last = [float(f) for f in raw[-L:].split()]
    if out[0].tolist() != [first[c] for c in usecols] or out[-1].tolist() != [last[c] for c in usecols]:
        return None  # never expected; a guard on the layout logic
    return out


def _values(M: np.ndarray, letters: str, spans: list[tuple[int, int]]) -> np.ndarray | None:
    """The fields spanning columns [a, b) of ``spans``, each with its layout ``letters[a:b]``, on every row.

    The digit columns are gathered once as contiguous rows; each field's mantissa and exponent are then
    summed digit by digit (Horner) in binary64, exact, since every partial sum is an integer below 2^53."""
    layout = []
    for a, b in spans:
        e = letters.find("e", a, b)
        end = b if e < 0 else e
        digits = [c for c in range(a, end) if letters[c] == "d"]
        if len(digits) > MAX_DIGITS:
            return None
        point = letters.find(".", a, end)
        frac = 0 if point < 0 else sum(1 for c in digits if c > point)
        exp_digits = [] if e < 0 else [c for c in range(e + 1, b) if letters[c] == "d"]
        exp_sign = e + 1 if e >= 0 and letters[e + 1] == "x" else None
        layout.append((digits, frac, exp_digits, exp_sign, a if letters[a] == "s" else None))
    cols = sorted({c for f in layout for c in f[0] + f[2]})
    row = {c: i for i, c in enumerate(cols)}
    D = np.ascontiguousarray(M.T[cols])  # (digit columns, n): each a contiguous row

    def number(columns):
        v = np.zeros(M.shape[0])
        for c in columns:
            v *= 10.0
            v += D[row[c]]
        return v - 48.0 * sum(10.0 ** i for i in range(len(columns)))

    out = np.empty((M.shape[0], len(spans)))
    for f, (digits, frac, exp_digits, exp_sign, lead_sign) in enumerate(layout):
        k = number(exp_digits) if exp_digits else np.zeros(M.shape[0])
        if exp_sign is not None:
            k = np.where(M[:, exp_sign] == MINUS, -k, k)
        k -= frac
        if len(k) and np.abs(k).max() > 22:
            return None
        m = number(digits)
        p = _POW10[np.abs(k).astype(np.int64)]
        value = np.where(k >= 0, m * p, m / p)
        out[:, f] = np.where(M[:, lead_sign] == MINUS, -value, value) if lead_sign is not None else value
    return out
