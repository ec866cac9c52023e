"""The layout of a raw recording's file (docs/design.md §9.2), from its first lines: the delimiter, a header,
leading ``key,value`` lines (an ``Fs,100`` line gives the rate) and which column holds which role.

Errors name the parameters of :func:`optcal.recording.read_recording` in backquotes (`` `columns` ``); the
command line puts its option names there (optcal/commands/_dataopts.py).
"""

from __future__ import annotations

import difflib
import itertools
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError

ROLES = ("t", "ax", "ay", "az", "temp")
ALIASES = {
    "t": ("t", "time", "timestamp", "time_s", "t_s", "seconds"),
    "ax": ("ax", "acc_x", "accx", "a_x", "accel_x", "acc_x_raw"),
    "ay": ("ay", "acc_y", "accy", "a_y", "accel_y", "acc_y_raw"),
    "az": ("az", "acc_z", "accz", "a_z", "accel_z", "acc_z_raw"),
    "temp": ("temp", "temperature", "temp_c", "t_degc"),
}
POSITIONAL = {3: ("ax", "ay", "az"), 4: ("t", "ax", "ay", "az"), 5: ("t", "ax", "ay", "az", "temp")}
RATE_KEYS = ("fs", "rate", "sample rate", "sampling rate", "sample_rate", "sampling_rate", "fs_hz", "rate_hz")
SNIFF_LINES = 200


@dataclass
class Layout:
    delimiter: str | None
    skiprows: int  # physical lines before the first data row
    ncol: int
    numeric: tuple[bool, ...]
    header: list[str] | None
    meta: dict
    first: list[str]  # the fields of the first data row (to check a fast reader started there)


def is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def split_fields(line: str, delim: str | None) -> list[str]:
    """The fields of one line, unquoted; ``delim`` None splits on whitespace."""
    return [f.strip().strip('"').strip("'") for f in (line.split(delim) if delim else line.split())]


def sniff_layout(path: Path) -> Layout:
    """Delimiter, header, leading key/value lines and the first data line, from the file's first lines."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = list(itertools.islice(fh, SNIFF_LINES))
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    lines = [(i, ln.strip()) for i, ln in enumerate(head) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path} is empty; a raw recording needs one row per sample (t, ax, ay, az)")
    last = lines[-1][1]
    delim = next((d for d in (",", ";", "\t") if d in last), None)
    rows = [(i, split_fields(ln, delim)) for i, ln in lines]
    pattern = [(len(f), tuple(is_number(x) for x in f)) for _, f in rows]
    ref = pattern[-1]
    if not any(ref[1]):
        raise InputError(f"{path} has no numeric rows; a raw recording needs one row per sample (t, ax, ay, az)")
    start = len(rows) - 1
    while start > 0 and pattern[start - 1] == ref:
        start -= 1
    header = None
    before = rows[:start]
    # A header has text wherever the data have numbers; a line with the data's width and numbers in it is
    # a data row that does not parse (an empty or text cell), and must not be skipped silently.
    if before and len(before[-1][1]) == ref[0] and not any(
            d and is_number(x) for x, d in zip(before[-1][1], ref[1])):
        header = before[-1][1]
        before = before[:-1]
    for i, f in reversed(before):  # the last such line is the one that breaks the run of data rows
        if len(f) == ref[0] and any(is_number(x) for x in f):
            raise InputError(
                f"{path}: line {i + 1} ({','.join(f)}) has the width of a data row but not its numbers "
                "(an empty or text cell?); fix or remove it"
            )
    meta = {f[0].strip().lower(): f[1].strip() for _, f in before if len(f) >= 2}
    return Layout(delim, rows[start][0], ref[0], ref[1], header, meta, rows[start][1])


def resolve_column(ref: str, lay: Layout, path: Path) -> int:
    """The 0-based index of a column given by header name (exact, then case-insensitive) or by index."""
    ref = ref.strip()
    if lay.header is not None:
        if ref in lay.header:
            return lay.header.index(ref)
        low = [h.lower() for h in lay.header]
        if ref.lower() in low:
            return low.index(ref.lower())
    if ref.lstrip("-").isdigit():
        j = int(ref)
        if not 0 <= j < lay.ncol:
            raise InputError(f"{path}: column index {j} is out of range; the file has {lay.ncol} columns (0-based)")
        return j
    names = lay.header or []
    close = difflib.get_close_matches(ref, names, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    where = f"its columns are {', '.join(names)}" if names else "it has no header, so give column indices"
    raise InputError(f"{path}: no column {ref!r}{hint}; {where}")


def role_columns(spec, lay: Layout, path: Path) -> dict[str, int]:
    """Role → column index from ``spec`` (positional ``t,ax,ay,az`` or ``role=column`` items, a string or a
    sequence), or, when ``spec`` is None, from the header's names or the number of numeric columns."""
    if spec is None:
        if lay.header is not None:
            low = [h.lower() for h in lay.header]
            found = {r: low.index(a) for r in ROLES for a in ALIASES[r] if a in low}
            out = {r: found[r] for r in ROLES if r in found}
            if all(r in out for r in ("ax", "ay", "az")):
                return out
            raise InputError(
                f"{path}: cannot tell which columns are ax, ay, az (columns: {', '.join(lay.header)}); "
                "name them with `columns`, e.g. t,ax,ay,az with names or 0-based indices"
            )
        numeric = [j for j, isnum in enumerate(lay.numeric) if isnum]
        if len(numeric) in POSITIONAL:
            return dict(zip(POSITIONAL[len(numeric)], numeric))
        raise InputError(
            f"{path}: {lay.ncol} columns and no header; name them with `columns` "
            "(0-based indices for t,ax,ay,az or ax,ay,az)"
        )
    items = [s for s in (spec.split(",") if isinstance(spec, str) else list(spec)) if str(s).strip()]
    if all("=" in str(s) for s in items):
        pairs = [str(s).split("=", 1) for s in items]
        bad = [r for r, _ in pairs if r.strip() not in ROLES]
        if bad:
            raise InputError(f"`columns`: unknown role(s) {', '.join(bad)}; roles are {', '.join(ROLES)}")
        out = {r.strip(): resolve_column(c, lay, path) for r, c in pairs}
    elif len(items) in POSITIONAL:
        out = {r: resolve_column(str(c), lay, path) for r, c in zip(POSITIONAL[len(items)], items)}
    else:
        raise InputError(
            f"`columns` {spec!r}: give 3 (ax,ay,az), 4 (t,ax,ay,az) or 5 (t,ax,ay,az,temp) columns, "
            "or role=column items"
        )
    missing = [r for r in ("ax", "ay", "az") if r not in out]
    if missing:
        raise InputError(f"`columns` lacks {', '.join(missing)}")
    for r, j in out.items():
        if not lay.numeric[j]:
            name = lay.header[j] if lay.header else j
            raise InputError(f"{path}: column {name!r} (for {r}) is not numeric; choose another with `columns`")
    return out


def rate_from_meta(meta: dict) -> float | None:
    """The sample rate (Hz) from a leading ``key,value`` line such as ``Fs,100``, or None."""
    for k in RATE_KEYS:
        if k in meta and is_number(meta[k]):
            return float(meta[k])
    return None
