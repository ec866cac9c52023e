"""Positions data sets and the positions CSV of docs/design.md, "Positions CSV" (any delimiter, decimal mark, header
form or compression :mod:`optcal.core.tablefile` reads).

One row per static position: ``position``, the mean raw output ``ax, ay, az``, and optionally ``t`` (s),
``temp`` (°C), ``n`` (samples averaged), ``sx, sy, sz`` (sample standard deviation per axis), ``se_x, se_y,
se_z`` (standard error of the mean per axis, correlated noise included, output units) and, for turntable data,
``ref_x, ref_y, ref_z`` (reference specific force in g, body frame). Extra columns are kept and ignored.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.tablefile import (
    COMMENT,
    column_key,
    commented_header,
    csv_fields,
    delimiter_of,
    head_lines,
    header_fields,
    is_number,
)

REQUIRED = ("ax", "ay", "az")
OPTIONAL = ("position", "t", "temp", "n", "sx", "sy", "sz", "se_x", "se_y", "se_z", "ref_x", "ref_y", "ref_z")
G0 = 9.80665
# More rows than a positions file has in practice (one per pose): a table this long that the positions reader
# cannot read is said to be perhaps a raw recording, and the raw reader's decision (optcal.core.recording.sniff.
# table_kind) takes it for samples whatever its columns are called when its data say so
MANY_POSITIONS = 1000



def residuals_per_position(reference: bool) -> int:
    """Residuals each position contributes (docs/design.md, "The calibration problem"): one, ‖A‖ − g, in the field;
    three, A − ref per axis, against a turntable's reference."""
    return 3 if reference else 1


@dataclass(frozen=True)
class PositionsData:
    """Static-position means of a triaxial accelerometer, in the sensor's output units."""

    N: np.ndarray  # (n, 3) mean raw output
    position: np.ndarray | None = None
    t: np.ndarray | None = None
    temp: np.ndarray | None = None
    n_samples: np.ndarray | None = None
    std: np.ndarray | None = None  # (n, 3) per-axis sample SD of the samples averaged
    # (n, 3) per-axis standard error of each mean, correlated noise included (output units); when None, the
    # white-noise value std/√n stands in (noise_of_mean)
    sem: np.ndarray | None = None
    ref: np.ndarray | None = None  # (n, 3) reference specific force in g (turntable)
    units: str = "g"
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        N = np.asarray(self.N, float)
        if N.ndim != 2 or N.shape[1] != 3:
            raise InputError(f"positions must have three output columns ax, ay, az; got shape {N.shape}")
        bad = np.flatnonzero(~np.all(np.isfinite(N), axis=1))
        if bad.size:
            rows = ", ".join(str(int(i) + 1) for i in bad[:5]) + (" …" if bad.size > 5 else "")
            raise InputError(f"positions row(s) {rows} have a missing or non-finite output (ax, ay, az); fix or "
                             "remove them")
        object.__setattr__(self, "N", N)
        if self.position is None:
            object.__setattr__(self, "position", np.arange(len(N)))

    def __len__(self) -> int:
        return len(self.N)

    @property
    def columns(self) -> set[str]:
        cols = {"ax", "ay", "az", "position"}
        for name in ("t", "temp"):
            if getattr(self, name) is not None:
                cols.add(name)
        if self.n_samples is not None:
            cols.add("n")
        if self.std is not None:
            cols |= {"sx", "sy", "sz"}
        if self.sem is not None:
            cols |= {"se_x", "se_y", "se_z"}
        if self.ref is not None:
            cols |= {"ref_x", "ref_y", "ref_z"}
        return cols

    def noise_of_mean(self) -> np.ndarray | None:
        """Standard error of each position's mean per axis, (n, 3): ``sem`` when known (correlated noise
        included), else the white-noise value std/√n when ``n`` and ``s*`` are known, else None."""
        if self.sem is not None:
            return self.sem
        if self.std is None or self.n_samples is None:
            return None
        return self.std / np.sqrt(self.n_samples)[:, None]

    def subset(self, idx) -> PositionsData:
        idx = np.asarray(idx)
        pick = {k: (None if getattr(self, k) is None else np.asarray(getattr(self, k))[idx])
                for k in ("position", "t", "temp", "n_samples", "std", "sem", "ref")}
        return replace(self, N=self.N[idx], **pick)

    # -- CSV -------------------------------------------------------------------------------
    def to_csv(self, path: str | Path | None = None) -> str:
        cols: list[tuple[str, np.ndarray]] = [("position", self.position)]
        cols += [(c, self.N[:, i]) for i, c in enumerate(REQUIRED)]
        if self.t is not None:
            cols.append(("t", self.t))
        if self.temp is not None:
            cols.append(("temp", self.temp))
        if self.n_samples is not None:
            cols.append(("n", self.n_samples))
        if self.std is not None:
            cols += [(f"s{a}", self.std[:, i]) for i, a in enumerate("xyz")]
        if self.sem is not None:
            cols += [(f"se_{a}", self.sem[:, i]) for i, a in enumerate("xyz")]
        if self.ref is not None:
            cols += [(f"ref_{a}", self.ref[:, i]) for i, a in enumerate("xyz")]
        import csv  # here: reading positions or a recording does not need it

        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow([c for c, _ in cols])
        for r in range(len(self)):
            w.writerow([_fmt(v[r]) for _, v in cols])
        text = buf.getvalue()
        if path is not None:  # whole or not at all: a temporary file beside it, renamed (optcal.core.atomicfile)
            from optcal.core.atomicfile import write_atomic

            write_atomic(path, text, overwrite=True)
        return text


def _fmt(v) -> str:
    v = float(v)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def read_positions(path: str | Path, units: str = "g") -> PositionsData:
    """Read and validate a positions CSV (docs/design.md, "Positions CSV"). Every problem is an :class:`InputError`.

    The layout is read as the raw reader reads it (:mod:`optcal.core.tablefile`): a comma, semicolon, tab or
    whitespace between the cells (from the last line), a decimal comma with the last three, compression by
    suffix, a UTF-8 byte-order mark, ``#`` and ``%`` comment lines. The header is the first line that is not
    a comment; when that line is all numbers, the last comment line before it if it names the columns
    (``# position ax ay az``), else the columns go by position (:func:`_positional_names`)."""
    path = Path(path)
    lines = [(i + 1, ln.strip()) for i, ln in enumerate(head_lines(path, None, "a positions file")) if ln.strip()]
    data = [(i, ln) for i, ln in lines if not ln.startswith(COMMENT)]
    if not data:
        raise InputError(f"{path} is empty; a positions CSV needs a header with ax, ay, az and one row per position")
    delim, dec = delimiter_of(data[-1][1])
    rows = [(i, csv_fields(ln, delim)) for i, ln in data]
    first_line, first = rows[0]
    if all(is_number(c, dec) for c in first):  # no header line: a commented one, or columns by position
        known = REQUIRED + OPTIONAL
        notes = [ln for i, ln in lines if i < first_line]
        header = commented_header(notes[-1], delim, len(first), known) if notes else None
        if header is None:
            header = _positional_names(path, rows, _perhaps_samples(len(rows)))
        body = rows
    else:
        header, body = [h.strip() for h in first], rows[1:]
        if body and len(header) != len(body[0][1]):  # a header written with another delimiter than the data
            header = header_fields(data[0][1], delim, len(body[0][1])) or header
    for name in dict.fromkeys(header):
        where = [i + 1 for i, h in enumerate(header) if h == name]
        if len(where) > 1 and name:
            raise InputError(f"{path}: the header names column {name!r} {len(where)} times (columns "
                             f"{', '.join(map(str, where))}); keep one, or rename the others")
    header = _named_axes(header)
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        import difflib  # here: only a refusal names close columns

        hints = []
        for m in missing:
            close = difflib.get_close_matches(m, header, n=1, cutoff=0.5)
            if close:
                hints.append(f"{close[0]!r} → {m!r}")
        hint = f" (rename {', '.join(hints)})" if hints else ""
        raise InputError(
            f"{path}: missing column(s) {', '.join(missing)}; the header must name ax, ay, az{hint}"
            + _perhaps_samples(len(body))
        )
    if not body:
        raise InputError(f"{path} has a header but no positions")
    wanted = [c for c in REQUIRED + OPTIONAL if c in header]
    cols: dict[str, np.ndarray] = {}
    for c in wanted:
        j = header.index(c)
        cells = [row[j].strip() if j < len(row) else "" for _, row in body]
        if dec == ",":
            cells = [x.replace(",", ".") for x in cells]
        try:  # the whole column at once; cell by cell only to name a bad one
            vals = np.array(cells, dtype=float)
        except ValueError:
            vals = None
        if vals is None or not np.all(np.isfinite(vals)):
            vals = np.array([_cell(path, line, c, x) for (line, _), x in zip(body, cells)])
        cols[c] = vals
    N = np.stack([cols[c] for c in REQUIRED], 1)
    std = np.stack([cols[c] for c in ("sx", "sy", "sz")], 1) if all(c in cols for c in ("sx", "sy", "sz")) else None
    sem = (np.stack([cols[c] for c in ("se_x", "se_y", "se_z")], 1)
           if all(c in cols for c in ("se_x", "se_y", "se_z")) else None)
    ref = (np.stack([cols[c] for c in ("ref_x", "ref_y", "ref_z")], 1)
           if all(c in cols for c in ("ref_x", "ref_y", "ref_z")) else None)
    if std is not None and np.any(std < 0):
        raise InputError(f"{path}: negative standard deviation in sx/sy/sz")
    if sem is not None and np.any(sem < 0):
        raise InputError(f"{path}: negative standard error in se_x/se_y/se_z")
    if "n" in cols and np.any(cols["n"] < 1):
        raise InputError(f"{path}: column 'n' (samples averaged) must be at least 1")
    if "t" in cols and np.any(np.diff(cols["t"]) < 0):
        raise InputError(f"{path}: column 't' decreases; positions must be in time order")
    extra = {h: [row[i] if i < len(row) else "" for _, row in body]
             for i, h in enumerate(header) if h not in REQUIRED + OPTIONAL}
    return PositionsData(
        N=N,
        position=cols["position"].astype(int) if "position" in cols else None,
        t=cols.get("t"),
        temp=cols.get("temp"),
        n_samples=cols.get("n"),
        std=std,
        sem=sem,
        ref=ref,
        units=units,
        extra=extra,
    )


def _cell(path: Path, line: int, column: str, cell: str) -> float:
    """One cell as a finite number, else the InputError that names its line and column."""
    try:
        value = float(cell)
    except ValueError:
        raise InputError(f"{path}: line {line}, column {column!r}: {cell!r} is not a number; fix or remove that "
                         "row") from None
    if not math.isfinite(value):
        raise InputError(f"{path}: line {line}, column {column!r} is {cell}; remove the position or re-average it")
    return value


def _named_axes(header: list[str]) -> list[str]:
    """``header`` with the accelerometer's axes under the names the raw reader knows them by (acc_x, AccX, ACCELX,
    ``acc_x [m/s^2]``: :data:`optcal.core.columns.ALIASES`) renamed ax, ay, az, when the header has no ax, ay, az
    of its own and one column each answers to them (a lab's pose table of acc_x, acc_y, acc_z was refused)."""
    from optcal.core.columns import ALIAS_KEYS

    if any(c in header for c in REQUIRED):
        return header
    keys = [column_key(h) for h in header]
    found = {a: [j for j, k in enumerate(keys) if k in ALIAS_KEYS[a]] for a in REQUIRED}
    if not all(len(j) == 1 for j in found.values()):
        return header
    out = list(header)
    for a, (j,) in found.items():
        out[j] = a
    return out


def _perhaps_samples(n: int) -> str:
    """The end of a message for a table the positions reader cannot read: with :data:`MANY_POSITIONS` rows or
    more, it may be a raw recording, which the raw reader reads once its columns are named."""
    return (f" (or, if its {n} rows are a raw recording's samples, read it with `raw` and name its columns with "
            "`columns`)") if n >= MANY_POSITIONS else ""


def _positional_names(path: Path, rows: list[tuple[int, list[str]]], perhaps: str = "") -> list[str]:
    """The columns of a positions file without a header, by their number: three are ax, ay, az; four are
    position, ax, ay, az when the first column numbers the rows 0, 1, 2, ... or 1, 2, 3, ... Anything else
    (a time or temperature column, per-axis SDs) cannot be told apart by position: refused, asking for a
    header."""
    width = len(rows[0][1])
    if width == 3:
        return list(REQUIRED)
    if width == 4:
        try:
            first = np.array([float(r[0]) for _, r in rows])
        except ValueError:
            first = None
        if first is not None and len(first) and first[0] in (0, 1) and np.array_equal(
                first, first[0] + np.arange(len(first))):
            return ["position", *REQUIRED]
    raise InputError(f"{path}: {width} columns and no header; a positions file without a header has 3 columns "
                     "(ax, ay, az) or 4 (position 0, 1, 2, ... or 1, 2, 3, ..., then ax, ay, az): add a header "
                     "line naming the columns, e.g. position,ax,ay,az,t,temp,n,sx,sy,sz" + perhaps)


UNITS = ("g", "m/s2", "counts", "volts", "mg")


def guess_units(magnitude: float) -> str | None:
    """The output units a static sensor's typical output magnitude suggests (docs/design.md, "Units and frames"):
    about 1 is g, 9.8 m/s², 1000 mg, and a power of two from 128 up (16384 for a ±2 g 16-bit ADC) counts; else None."""
    m = float(magnitude)
    if not math.isfinite(m) or m <= 0:
        return None
    if 0.9 <= m <= 1.1:
        return "g"
    if 9.70 <= m <= 9.90:
        return "m/s2"
    if 960 <= m <= 1040:
        return "mg"
    if m >= 100 and abs(m / 2.0 ** round(math.log2(m)) - 1) <= 0.12:
        return "counts"
    return None


# The range of the median output magnitude each unit allows (a sensor at rest reads 1 g, within a factor 2).
_PLAUSIBLE = {"mg": (500.0, 2000.0)}


def check_units(data: PositionsData, units: str) -> None:
    """Refuse data whose output magnitudes contradict the units declared: norms that look like m/s², g, mg
    or counts (a power of two per g) while other units are declared (docs/design.md, "Units and frames")."""
    if units not in UNITS:
        raise InputError(f"unknown units {units!r}; use one of {', '.join(UNITS)}")
    with np.errstate(over="ignore"):  # a wild value overflows to inf: the problem names that position later
        med = float(np.median(np.linalg.norm(data.N, axis=1)))
    looks = guess_units(med)
    if units != "m/s2" and looks == "m/s2":
        raise InputError(
            f"the outputs' norms are about {med:.3f}, which looks like m/s², but the units are {units!r}; "
            "pass --units m/s2 (and --gravity-ms2 for your local g if you know it)"
        )
    if units == "g" and not 0.5 <= med <= 2.0:
        like = f"look like {looks}" if looks else "are not in g"
        raise InputError(
            f"the outputs' norms are about {med:.4g}, not about 1, so they {like}; "
            f"pass --units {looks or 'counts'} (or m/s2, volts) to say what they are"
        )
    lo_hi = _PLAUSIBLE.get(units)
    if lo_hi is not None and math.isfinite(med) and not lo_hi[0] <= med <= lo_hi[1]:
        like = f"which looks like {looks}" if looks else "which no static sensor reads"
        raise InputError(f"the outputs' magnitude is about {med:.5g}, {like}, not {units} (a sensor at rest reads "
                         f"{lo_hi[0]:g} to {lo_hi[1]:g} {units}); pass --units {looks or 'counts'} or convert the data")
    if units == "counts" and looks in ("g", "m/s2"):
        raise InputError(f"the outputs' magnitude is about {med:.4g}, which looks like {looks}, not {units}; "
                         f"pass --units {looks}")
