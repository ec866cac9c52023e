"""The layout of a text table as instruments and other labs write it (docs/design.md, "Positions CSV", "Raw
recordings"), shared by the positions reader (:func:`optcal.core.data.read_positions`) and the raw-recording reader
(:mod:`optcal.core.recording.sniff`):
compression by suffix (``.gz``, ``.bz2``, ``.xz``), a UTF-8 byte-order mark, comment lines (``#``, and ``%`` as
MATLAB and Octave write them) of which the last before the data may be the header (``# t ax ay az``), the
delimiter (comma, semicolon, tab or whitespace) and decimal mark, a header line, and leading ``key,value``
lines.

It lives outside :mod:`optcal.core.recording` because :mod:`optcal.core.data` reads with it and that package imports
:mod:`optcal.core.data` (no cycle between the parts of a package, CONTRIBUTING.md "Layers").
"""

from __future__ import annotations

import bz2
import gzip
import io
import itertools
import lzma
import re
from collections import Counter
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from optcal.core.errors import InputError, listing

COMPRESSED = {".gz": gzip.open, ".bz2": bz2.open, ".xz": lzma.open}
COMMENT = ("#", "%")  # a line starting with one of these is a comment (or a commented header)
SNIFF_LINES = 200
TAIL = 20  # the last lines sniffed that set the data's delimiter and pattern
DECODE_ERRORS = (OSError, EOFError, lzma.LZMAError)  # what reading a (compressed) file may raise


@dataclass
class Layout:
    delimiter: str | None
    skiprows: int  # physical lines before the first data row
    ncol: int
    numeric: tuple[bool, ...]
    header: list[str] | None
    meta: dict
    first: list[str]  # the fields of the first data row (to check a fast reader started there)
    decimal: str = "."  # "," for a decimal comma (then the delimiter is not a comma)
    commented_header: bool = False  # the header was a comment line (``# t ax ay az``)
    sparse: bool = False  # rows of several record types interleaved: a number column may be empty in a row


def is_number(s: str, decimal: str = ".") -> bool:
    try:
        float(s.replace(",", ".") if decimal == "," else s)
    except ValueError:
        return False
    return True


def compression(path: Path) -> str | None:
    """The compression suffix of ``path`` (``.gz``, ``.bz2``, ``.xz``), or None."""
    suffix = path.suffix.lower()
    return suffix if suffix in COMPRESSED else None


def inner_suffix(path: Path) -> str:
    """The suffix that names the format, under any compression suffix (``x.mat.gz`` → ``.mat``)."""
    return Path(path.stem).suffix.lower() if compression(path) else path.suffix.lower()


def open_binary(path: Path):
    """The file's bytes as a stream, decompressed by its suffix."""
    try:
        return COMPRESSED.get(compression(path), open)(path, "rb")
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None


def open_text(path: Path, errors: str = "replace"):
    """The file as text, decompressed, without a UTF-8 byte-order mark."""
    return io.TextIOWrapper(open_binary(path), encoding="utf-8-sig", errors=errors)


def head_lines(path: Path, n: int | None = SNIFF_LINES, kind: str = "a raw recording") -> list[str]:
    """The first ``n`` lines of the file (all with None), as text; a file that cannot be read, or one that is
    binary, is an InputError (naming what ``kind`` of file was expected)."""
    try:
        with open_text(path) as fh:
            head = list(itertools.islice(fh, n))
    except DECODE_ERRORS as exc:
        raise InputError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    if "\x00" in "".join(head[:5]):
        raise InputError(f"cannot read {path}: it is a binary file, not text; {kind} is a text table or a MAT file")
    return head


def is_comment(line: str) -> bool:
    return line.lstrip().startswith(COMMENT)


def uncomment(line: str) -> str:
    """A comment line's text after its comment marks (``# t ax ay az`` → ``t ax ay az``)."""
    return line.strip().lstrip("".join(COMMENT)).strip()


def delimiter_of(line: str) -> tuple[str | None, str]:
    """Delimiter and decimal mark of a data line: semicolon or tab first (they leave a comma free to be a
    decimal comma), whitespace when it splits the line into numbers (``1,5 2,25``), else a comma."""
    for d in (";", "\t"):
        if d in line:
            return d, "," if any("," in f and is_number(f, ",") for f in split_fields(line, d)) else "."
    ws = line.split()
    if len(ws) > 1 and "," in line and all(is_number(f, ",") for f in ws):
        return None, ","
    return ("," if "," in line else None), "."


def split_fields(line: str, delim: str | None) -> list[str]:
    """The fields of one line, unquoted; ``delim`` None splits on whitespace."""
    return [f.strip().strip('"').strip("'") for f in (line.split(delim) if delim else line.split())]


def csv_fields(line: str, delim: str | None) -> list[str]:
    """The fields of one line as a CSV reader sees them (a quoted field may hold the delimiter); ``delim``
    None splits on whitespace."""
    if delim is None:
        return split_fields(line, None)
    import csv  # here: a whitespace-separated file's reading does not need it

    try:
        (fields,) = csv.reader([line], delimiter=delim, skipinitialspace=True)
    except (csv.Error, ValueError):  # an unbalanced quote: the plain split names the cells
        return split_fields(line, delim)
    return [f.strip() for f in fields]


def header_fields(line: str, delim: str | None, width: int) -> list[str] | None:
    """The names of a header line that has ``width`` fields split by the data's delimiter or, failing that, by
    whitespace, a comma, a semicolon or a tab (``# t ax ay az`` over comma-separated data; ``% t, ax, ay, az``
    over whitespace-separated data: a comma or semicolon at a name's end goes with the whitespace); else None."""
    for d in dict.fromkeys((delim, None, ",", ";", "\t")):
        fields = [g for f in split_fields(line, d) if (g := f.strip(",;"))] if d is None else split_fields(line, d)
        if len(fields) == width:
            return fields
    return None


_UNIT_SUFFIX = re.compile(r"\s*[(\[]([^()\[\]]*)[)\]]\s*$")  # ``Timestamp(Ms)``, ``acc_x [m/s^2]``
# what a line of units under the names holds in each field (``s,g,g,g``; ``[s] [m/s^2] ...``), lower case
UNIT_WORDS = frozenset({"", "-", "s", "sec", "ms", "us", "µs", "ns", "g", "mg", "m/s^2", "m/s2", "m/s²", "m s-2",
                        "deg/s", "°/s", "dps", "rad/s", "counts", "count", "lsb", "adc", "raw", "°c", "c", "degc",
                        "deg", "°", "ut", "µt", "gauss", "mgauss", "v", "mv", "hz", "%", "k"})
_SEPARATORS = re.compile(r"[\s_.\-]+")


def column_key(name: str) -> str:
    """A column's name as names are compared with a role's aliases: lower case, without a trailing unit in
    parentheses or brackets and without spaces, underscores, dots or hyphens (``Acc_X``, ``acc x``,
    ``ACCX (g)`` → ``accx``; ``Timestamp(Ms)`` → ``timestamp``)."""
    return _SEPARATORS.sub("", _UNIT_SUFFIX.sub("", str(name))).lower()


def unit_of(name: str) -> str | None:
    """The unit a column's name gives in parentheses or brackets at its end (``Temp(Raw)`` → ``raw``), or None."""
    m = _UNIT_SUFFIX.search(str(name))
    return m.group(1).strip().lower() if m else None


def _units_line(fields: list[str]) -> bool:
    """Whether a line's fields are all units (:data:`UNIT_WORDS`, bare or in parentheses or brackets), one at
    least not empty."""
    words = [str(f).strip().strip("()[]").strip().lower() for f in fields]
    return all(w in UNIT_WORDS for w in words) and any(words)


def commented_header(line: str, delim: str | None, width: int, known: Collection[str]) -> list[str] | None:
    """The header a comment line holds, or None: its text has ``width`` fields, none of them a number, and
    names at least one column of ``known`` (compared as :func:`column_key`s: case, units and separators
    aside), so that a remark of that many words is not taken for names."""
    fields = header_fields(uncomment(line), delim, width)
    if not fields or any(is_number(f) for f in fields):
        return None
    keys = {column_key(k) for k in known}
    return fields if any(column_key(f) in keys for f in fields) else None


def _most_common(items: list):
    """The most common of ``items``; of equally common ones, the one that occurs last."""
    counts = Counter(items)
    top = max(counts.values())
    return next(x for x in reversed(items) if counts[x] == top)


def refuse_duplicates(header: list[str], path: Path) -> None:
    """Two columns of one name (case-insensitive) would make the name ambiguous: refused, naming it."""
    low = [h.lower() for h in header]
    for j, h in enumerate(low):
        if h and h in low[:j]:
            raise InputError(f"{path}: the header names column {header[j]!r} twice (columns {low.index(h)} and "
                             f"{j}); rename one of them")


def _column_numbers(fields) -> bool:
    """Whether a row of numbers is a header numbering the columns, 1, 2, …, k or 0, 1, …, k − 1 (a logger's: read
    as a sample, it put the first at (1, 2, 3) m/s²)."""
    try:
        v = [float(x) for x in fields]
    except ValueError:
        return False
    return v == list(range(1, len(v) + 1)) or v == list(range(len(v)))


def _fits(fields: list[str], ref: tuple, dec: str) -> bool:
    """Whether a row of ``fields`` belongs to the sparse table ``ref`` (width, number columns): its width, and a
    number or nothing in each number column."""
    return len(fields) == ref[0] and all(not num or x.strip() == "" or is_number(x, dec)
                                         for x, num in zip(fields, ref[1]))


def _interleaved(rows: list, pattern: list, ref: tuple) -> tuple | None:
    """The table of a logger that writes several record types in one file (a MicroStrain IMU's CSV: its raw
    packets' rows leave the filter's cells empty and the filter's rows the raw ones), from the last lines' ``rows``
    and their patterns: (width, the columns a number is in on some row) when rows of ``ref``'s width but another
    pattern, a tenth of them at least, differ from it only in empty cells; else None."""
    width = ref[0]
    same = [(f, p) for (_, f), p in zip(rows, pattern) if p[0] == width]
    kinds = {p for _, p in same}
    if len(kinds) < 2 or sum(1 for _, p in same if p != ref) < max(2, len(rows) // 10):
        return None
    union = tuple(any(p[1][j] for _, p in same) for j in range(width))
    # where a row has no number in a number column, the cell is empty: another record's column, not text
    if not all(f[j].strip() == "" for f, p in same for j in range(width) if union[j] and not p[1][j]):
        return None
    return width, union


def sniff_layout(path: Path, known: Collection[str] = (), what: str = "a raw recording needs one row per "
                 "sample (t, ax, ay, az)") -> Layout:
    """Delimiter, header, leading key/value lines and the first data line, from the file's first lines. The
    data are the last run of rows of the most common width and pattern of numbers among the last
    :data:`TAIL` lines (a broken row after them is the loader's to name); the line before them is the
    header when it has text where they have numbers, else the last comment line before them when it is a
    header of ``known`` names (:func:`commented_header`). ``what`` ends the message for a file without
    data."""
    head = head_lines(path)
    lines = [(i, ln.strip()) for i, ln in enumerate(head) if ln.strip() and not is_comment(ln)]
    comments = [(i, ln) for i, ln in enumerate(head) if is_comment(ln)]
    if not lines:
        raise InputError(f"{path} is empty; {what}")
    # The data's delimiter and pattern (width, which cells are numbers) are the most common among the last
    # TAIL lines (ties: the later), so a broken last row is left to the loader, which names it.
    tail = lines[-TAIL:]
    delim, dec = _most_common([delimiter_of(ln) for _, ln in tail])
    rows = [(i, split_fields(ln, delim)) for i, ln in lines]
    pattern = [(len(f), tuple(is_number(x, dec) for x in f)) for _, f in rows]
    ref = _most_common(pattern[-TAIL:])
    sparse = _interleaved(rows[-TAIL:], pattern[-TAIL:], ref) if delim is not None else None
    if sparse is not None:  # several record types whose rows leave each other's cells empty: one table
        ref = sparse
        pattern = [ref if _fits(f, ref, dec) else p for (_, f), p in zip(rows, pattern)]
    if not any(ref[1]):
        raise InputError(f"{path} has no numeric rows; {what}")
    start = max(k for k, p in enumerate(pattern) if p == ref)
    while start > 0 and pattern[start - 1] == ref:
        start -= 1
    # a header of column numbers (1,2,…,9 or 0,1,…,8) is no sample, and no names: the columns go by index
    numbered = start + 1 < len(rows) and ref[0] >= 3 and _column_numbers(rows[start][1])
    header, commented = None, False
    before = rows[:start]
    start += numbered
    # A header has text wherever the data have numbers; a line with the data's width and numbers in it is
    # a data row that does not parse (an empty or text cell), and must not be skipped silently.
    if before and len(before[-1][1]) == ref[0] and not any(
            d and is_number(x, dec) for x, d in zip(before[-1][1], ref[1])):
        header = before[-1][1]
        before = before[:-1]
        # a line of units under the names (``t,ax,ay,az`` then ``s,g,g,g``): the names are the line above it
        if (before and _units_line(header) and len(before[-1][1]) == ref[0]
                and not any(d and is_number(x, dec) for x, d in zip(before[-1][1], ref[1]))):
            header = before[-1][1]
            before = before[:-1]
    elif known:  # the last comment line above the data that is a header (a units line may follow it)
        after = before[-1][0] if before else -1
        above = [ln for i, ln in comments if after < i < rows[start][0]]
        header = next((h for ln in reversed(above) if (h := commented_header(ln, delim, ref[0], known))), None)
        commented = header is not None
    if header is not None:
        refuse_duplicates(header, path)
    runs = [k for k in range(len(before)) if pattern[k] == ref]  # before[k] is rows[k]
    if runs:  # data rows above a line that breaks them: name that line
        i, f = before[runs[-1] + 1] if runs[-1] + 1 < len(before) else rows[start - 1]
        why = (f"{len(f)} field(s) where they have {ref[0]}" if len(f) != ref[0]
               else "a cell that is not a number where they have one (an empty or text cell?)")
        raise InputError(f"{path}: line {i + 1} ({listing(f, 12, ',')}) breaks the data rows: {why}; fix or remove it")
    for i, f in reversed(before):  # the last such line is the one that breaks the run of data rows
        if len(f) == ref[0] and any(is_number(x, dec) for x in f):
            raise InputError(
                f"{path}: line {i + 1} ({listing(f, 12, ',')}) has the width of a data row but not its numbers "
                "(an empty or text cell?); fix or remove it"
            )
    meta = {f[0].strip().lower(): f[1].strip() for _, f in before if len(f) >= 2}
    width, numeric = ref[0], ref[1]
    if (delim is not None and width > 1 and not numeric[-1] and all(f[-1].strip() == "" for _, f in rows[start:])
            and (header is None or not header[-1].strip())):
        # every row ends with the delimiter, the header too if any: an empty field, not a column (a column the
        # header names that is empty on every row stays one)
        width, numeric = width - 1, numeric[:-1]
        header = None if header is None else header[:width]
    return Layout(delim, rows[start][0], width, numeric, header, meta, rows[start][1], dec, commented,
                  sparse is not None)
