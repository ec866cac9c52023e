"""The layout of a raw recording's file (docs/design.md §9.2), from its first lines: the delimiter (comma,
semicolon, tab or whitespace) and decimal mark, a header, leading ``key,value`` lines (an ``Fs,100`` line
gives the rate) and which column holds which role. Compressed files (``.gz``, ``.bz2``, ``.xz``) are read
through the standard library's decompressors by their suffix, a UTF-8 byte-order mark is dropped, and a
MATLAB level 5 ``.mat`` file (:func:`mat_table`, scipy.io.loadmat) gives a table of its numeric variables.

Errors name the parameters of :func:`optcal.recording.read_recording` in backquotes (`` `columns` ``); the
command line puts its option names there (optcal/commands/_dataopts.py).
"""

from __future__ import annotations

import bz2
import difflib
import gzip
import io
import itertools
import lzma
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError

ROLES = ("t", "ax", "ay", "az", "gx", "gy", "gz", "temp")
GYRO = ("gx", "gy", "gz")  # angular rate, in the file's units (rad/s, °/s or counts): optional, all three or none
# header names of the gyroscope's axes: gx, gyr_x, gyro_x, wx, omega_x, ... (and gy, gz alike)
GYRO_STEMS = ("g", "gyr_", "gyro_", "gyr", "gyro", "gyroscope_", "w", "w_", "omega_", "angvel_", "ang_vel_", "rate_")
ALIASES = {
    "t": ("t", "time", "timestamp", "time_s", "t_s", "seconds"),
    "ax": ("ax", "acc_x", "accx", "a_x", "accel_x", "acc_x_raw"),
    "ay": ("ay", "acc_y", "accy", "a_y", "accel_y", "acc_y_raw"),
    "az": ("az", "acc_z", "accz", "a_z", "accel_z", "acc_z_raw"),
    **{g: tuple(stem + g[1] for stem in GYRO_STEMS) + (f"gyr_{g[1]}_raw", f"gyro_{g[1]}_raw") for g in GYRO},
    "temp": ("temp", "temperature", "temp_c", "t_degc"),
}
# columns by position when a file has no header (or `columns` lists bare columns): 3, 4 and 5 as always; 7 is
# an IMU's row, time, the accelerometer's three axes and the gyroscope's three
POSITIONAL = {3: ("ax", "ay", "az"), 4: ("t", "ax", "ay", "az"), 5: ("t", "ax", "ay", "az", "temp"),
              7: ("t", "ax", "ay", "az", "gx", "gy", "gz")}
RATE_KEYS = ("fs", "rate", "sample rate", "sampling rate", "sample_rate", "sampling_rate", "fs_hz", "rate_hz")
SNIFF_LINES = 200
COMPRESSED = {".gz": gzip.open, ".bz2": bz2.open, ".xz": lzma.open}
# columns only a positions file has (docs/design.md §9.1): a raw recording has one row per sample
POSITIONS_ONLY = ("position", "n", "sx", "sy", "sz", "ref_x", "ref_y", "ref_z")
FEW_ROWS = 100  # a raw recording this short cannot hold the static intervals of a calibration
MANY_ROWS = 1000  # a file of samples this long, with none of a positions file's own columns, is a recording


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


def is_mat(path: Path) -> bool:
    """A MATLAB level 5 (or 7.3) MAT file: its 128-byte header starts with ``MATLAB``. A text matrix that
    MATLAB's ``save -ascii`` wrote under a ``.mat`` name (imu_tk's recordings) is not."""
    if inner_suffix(path) != ".mat":
        return False
    with open_binary(path) as fh:
        try:
            return fh.read(6) == b"MATLAB"
        except (OSError, EOFError, lzma.LZMAError) as exc:
            raise InputError(f"cannot read {path}: {exc}") from None


def mat_table(path: Path) -> tuple[list[str] | None, np.ndarray]:
    """A MAT file's numeric variables as one table (scipy.io.loadmat): a single matrix is returned as it
    is, without a header (columns by position, as a headerless text file; a 3 × n or 4 × n matrix is
    transposed); several variables of one length n are columns named by the variables (an n × k matrix
    ``acc`` giving ``acc_0`` … ``acc_{k-1}``)."""
    from scipy.io import loadmat

    try:
        with open_binary(path) as fh:
            m = loadmat(io.BytesIO(fh.read()))
    except NotImplementedError:
        raise InputError(f"{path} is a MATLAB v7.3 (HDF5) file; save it with save(..., '-v7') to read it") from None
    except (ValueError, TypeError, OSError) as exc:
        raise InputError(f"cannot read MAT file {path}: {exc}") from None
    found = {k: np.asarray(v) for k, v in m.items() if not k.startswith("__")}
    arrays = {k: (v.T if v.ndim == 2 and v.shape[0] < v.shape[1] and v.shape[0] <= 5 else v).astype(float)
              for k, v in found.items() if v.dtype.kind in "iufb" and v.ndim <= 2 and v.size > 1}
    if not arrays:
        raise InputError(f"{path} holds no numeric matrix (variables: {', '.join(found) or 'none'}); "
                         "save the samples as an n × 3 or n × 4 matrix")
    if len(arrays) == 1:
        (a,) = arrays.values()
        return None, a.reshape(len(a), -1)
    lengths = {k: max(v.shape) if v.ndim == 1 or 1 in v.shape else v.shape[0] for k, v in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"{path}: its variables have different lengths "
                         f"({', '.join(f'{k} {n}' for k, n in lengths.items())}); keep one table of samples")
    names, cols = [], []
    for k, v in arrays.items():
        v = v.reshape(lengths[k], -1)
        names += [k] if v.shape[1] == 1 else [f"{k}_{j}" for j in range(v.shape[1])]
        cols.append(v)
    return names, np.hstack(cols)


def mat_layout(path: Path) -> tuple[Layout, np.ndarray]:
    """The :class:`Layout` of a MAT file's table (:func:`mat_table`) and the table itself."""
    header, table = mat_table(path)
    if header is not None:
        refuse_duplicates(header, path)
    lay = Layout(None, 0, table.shape[1], (True,) * table.shape[1], header, {}, [])
    return lay, table


def refuse_duplicates(header: list[str], path: Path) -> None:
    """Two columns of one name (case-insensitive) would make the name ambiguous: refused, naming it."""
    low = [h.lower() for h in header]
    for j, h in enumerate(low):
        if h and h in low[:j]:
            raise InputError(f"{path}: the header names column {header[j]!r} twice (columns {low.index(h)} and "
                             f"{j}); rename one of them")


def _delimiter(line: str) -> tuple[str | None, str]:
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


def sniff_layout(path: Path) -> Layout:
    """Delimiter, header, leading key/value lines and the first data line, from the file's first lines."""
    try:
        with io.TextIOWrapper(open_binary(path), encoding="utf-8-sig", errors="replace") as fh:
            head = list(itertools.islice(fh, SNIFF_LINES))
    except (OSError, EOFError, lzma.LZMAError) as exc:
        raise InputError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    lines = [(i, ln.strip()) for i, ln in enumerate(head) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{path} is empty; a raw recording needs one row per sample (t, ax, ay, az)")
    if "\x00" in "".join(ln for _, ln in lines[:5]):
        raise InputError(f"{path} is a binary file, not text; a raw recording is a text table or a MAT file")
    delim, dec = _delimiter(lines[-1][1])
    rows = [(i, split_fields(ln, delim)) for i, ln in lines]
    pattern = [(len(f), tuple(is_number(x, dec) for x in f)) for _, f in rows]
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
            d and is_number(x, dec) for x, d in zip(before[-1][1], ref[1])):
        header = before[-1][1]
        before = before[:-1]
        refuse_duplicates(header, path)
    for i, f in reversed(before):  # the last such line is the one that breaks the run of data rows
        if len(f) == ref[0] and any(is_number(x, dec) for x in f):
            raise InputError(
                f"{path}: line {i + 1} ({','.join(f)}) has the width of a data row but not its numbers "
                "(an empty or text cell?); fix or remove it"
            )
    meta = {f[0].strip().lower(): f[1].strip() for _, f in before if len(f) >= 2}
    return Layout(delim, rows[start][0], ref[0], ref[1], header, meta, rows[start][1], dec)


def positions_file_reason(lay: Layout, nrows: int, timed: bool) -> str | None:
    """Why a file read as a raw recording looks like a positions file (docs/design.md §9.1), or None: its
    header names columns only positions files have, or it has no time column (``timed`` False) and too few
    rows for a recording."""
    names = [h.lower() for h in lay.header or []]
    only = [c for c in POSITIONS_ONLY if c in names]
    if only and all(c in names for c in ("ax", "ay", "az")):
        return f"its columns {', '.join(only)} are those of a positions file"
    if nrows < FEW_ROWS and not timed:
        return f"it has {nrows} rows, too few for a recording with one row per sample"
    return None


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
            if not all(r in out for r in GYRO):  # a gyroscope is three named axes, or none
                out = {r: j for r, j in out.items() if r not in GYRO}
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
            f"`columns` {spec!r}: give 3 (ax,ay,az), 4 (t,ax,ay,az), 5 (t,ax,ay,az,temp) or 7 "
            "(t,ax,ay,az,gx,gy,gz) columns, or role=column items"
        )
    missing = [r for r in ("ax", "ay", "az") if r not in out]
    if missing:
        raise InputError(f"`columns` lacks {', '.join(missing)}")
    gyro = [r for r in GYRO if r in out]
    if gyro and len(gyro) < 3:
        raise InputError(f"`columns` names {', '.join(gyro)} but not {', '.join(r for r in GYRO if r not in out)}; "
                         "a gyroscope needs gx, gy and gz")
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


def raw_file_reason(path: Path) -> str | None:
    """Why a file given as a positions file (docs/design.md §9.1) looks like a raw recording, or None: a
    MAT file's matrix or a table with :data:`MANY_ROWS` rows or more and none of the columns only positions
    files have, or a table whose columns are named as a recording's (``acc_x``, ``time``) or not at all."""
    try:
        if is_mat(path):
            header, table = mat_table(path)
            names, nrows = [h.lower() for h in header or []], len(table)
        else:
            lay = sniff_layout(path)
            names = [h.lower() for h in lay.header or []]
            with io.TextIOWrapper(open_binary(path), encoding="utf-8-sig", errors="replace") as fh:
                nrows = sum(1 for _ in fh) - lay.skiprows
            if lay.header is None and lay.ncol in POSITIONAL and all(lay.numeric):
                return f"{nrows} rows of {lay.ncol} numbers and no header"
            if any(c in names for c in POSITIONS_ONLY):
                return None  # a positions file, perhaps with misnamed columns: its reader says which
            if lay.header is not None and not all(c in names for c in ("ax", "ay", "az")):
                role_columns(None, lay, path)  # names a recording's columns (acc_x, ...): else not a recording
                return f"its columns {', '.join(lay.header)} are a recording's"
    except InputError:
        return None
    if nrows >= MANY_ROWS and not any(c in names for c in POSITIONS_ONLY):
        return f"{nrows} rows, one per sample, and no position, n or sx column"
    return None
