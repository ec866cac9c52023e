"""The layout of a raw recording's file (docs/design.md, "Raw recordings"): the text table's delimiter, decimal mark,
header (a commented one too), ``key,value`` lines (an ``Fs,100`` line gives the rate), byte-order mark and
compression are read by :mod:`optcal.core.tablefile`, which the positions reader shares; here, which column
holds which role (time, the accelerometer's ax, ay, az, the gyroscope's gx, gy, gz, temperature: by
:data:`ALIASES`, names compared as :func:`~optcal.core.tablefile.column_key`s, so ``ACCELX``, ``Acc_X``, ``accX`` and
``acc x (g)`` are all ax), a MATLAB ``.mat`` file's table (:func:`mat_table`: level 5 through scipy.io.loadmat, a
bad zlib checksum read with a warning; v7.3, which is HDF5, through h5py; anything unreadable one line), and
whether a table holds positions or a recording's samples (:func:`table_kind`, by its data, one decision for both
readers).

Errors name the parameters of :func:`optcal.core.recording.read_recording` in backquotes (`` `columns` ``); the
command line puts its option names there (optcal/app/commands/_dataopts.py).
"""

from __future__ import annotations

import io
import logging
import struct
import zlib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from optcal.core.columns import ACC_STEMS, ALIAS_KEYS, ALIASES, GYRO, GYRO_STEMS  # noqa: F401 - re-exported
from optcal.core.data import MANY_POSITIONS
from optcal.core.errors import InputError, listing
from optcal.core.tablefile import (  # noqa: F401 - the layout's names, re-exported for the recording path
    COMPRESSED,
    DECODE_ERRORS,
    SNIFF_LINES,
    Layout,
    column_key,
    compression,
    inner_suffix,
    is_number,
    open_binary,
    refuse_duplicates,
    split_fields,
    unit_of,
)
from optcal.core.tablefile import sniff_layout as sniff_table

log = logging.getLogger(__name__)
_WARNED: set[str] = set()  # files whose damaged-checksum warning was given (one process, one warning per file)

ROLES = ("t", "ax", "ay", "az", "gx", "gy", "gz", "temp")

# prefixes under which a sensor's own outputs go (MicroStrain's scaledAccelX, scaledGyroX; rawAccX; imu_ax):
# not a filter's or an estimate's (linearAccel, estLinearAccel: gravity taken out)
SENSOR_PREFIXES = ("scaled", "raw", "imu", "sensor", "measured", "uncalibrated", "uncal")
CELSIUS = ("c", "°c", "degc", "deg c", "celsius", "degrees c")  # a temperature column's unit, if its name gives one
# a column named t in degrees is a temperature, not the time (WitMotion's exports: T(°) beside a clock-time column)
T_IN_DEGREES = (*CELSIUS, "°", "deg", "℃")
# columns by position when a file has no header (or `columns` lists bare columns): 3, 4 and 5 as always; 7 is
# an IMU's row, time, the accelerometer's three axes and the gyroscope's three
POSITIONAL = {3: ("ax", "ay", "az"), 4: ("t", "ax", "ay", "az"), 5: ("t", "ax", "ay", "az", "temp"),
              7: ("t", "ax", "ay", "az", "gx", "gy", "gz")}
KNOWN = {a for names in ALIASES.values() for a in names}  # the names a commented header line may hold
# the accelerometer's units as its columns' names give them (ax(g), Acc X [m/s^2], AccX(mg)), lower case
NAMED_UNITS = {"g": "g", "mg": "mg", **{u: "m/s2" for u in ("m/s2", "m/s^2", "m/s²", "m s-2", "m s^-2", "ms-2",
                                                             "ms^-2", "m/s/s", "m/sec^2", "m/sec2")},
               **{u: "counts" for u in ("counts", "count", "lsb", "adc")}, **{u: "volts" for u in ("v", "volts")}}
NUMERIC_MAT_CLASSES = {"double", "single", "logical", *(f"{u}int{b}" for u in ("", "u") for b in (8, 16, 32, 64))}
RATE_KEYS = ("fs", "rate", "sample rate", "sampling rate", "sample_rate", "sampling_rate", "fs_hz", "rate_hz")
# columns only a positions file has (docs/design.md, "Positions CSV"): a raw recording has one row per sample
POSITIONS_ONLY = ("position", "n", "sx", "sy", "sz", "ref_x", "ref_y", "ref_z")
MANY_ROWS = MANY_POSITIONS  # a table this long is samples when its data say so, whatever its columns are called
# Positions or samples (table_kind), from the median jump between consecutive rows as a fraction of the rows'
# magnitude: turns between positions of 12° or more make 0.2 or more; a recording's samples at 100 Hz differ by
# noise (1 mg of noise on each axis: 0.0022, the median of a 3-D difference being 2.2 σ) except while the
# sensor turns, a minority of the samples. Measured on the real corpus's recordings (real_data.md): 0.0001 (imu_tk's
# Xsens) to 0.022 (TWLogger's LSM303); on the position means kept there: 0.40 and 0.78 (Hassan & Bao's 49, 24).
POSITION_JUMP = 0.2
SAMPLE_JUMP = 0.05
KIND_ROWS = 2000  # the rows the decision reads (a raw recording given as positions need not be read whole)


def is_mat(path: Path) -> bool:
    """A MATLAB level 5 (or 7.3) MAT file: its 128-byte header starts with ``MATLAB``. A text matrix that
    MATLAB's ``save -ascii`` wrote under a ``.mat`` name (imu_tk's recordings) is not."""
    if inner_suffix(path) != ".mat":
        return False
    with open_binary(path) as fh:
        try:
            return fh.read(6) == b"MATLAB"
        except DECODE_ERRORS as exc:
            raise InputError(f"cannot read {path}: {exc}") from None


def mat_table(path: Path) -> tuple[list[str] | None, np.ndarray]:
    """A MAT file's numeric variables (:func:`load_mat`) as one table: a single matrix is returned as it is,
    without a header (columns by position, as a headerless text file; a k × n matrix with k < n and k up to
    7 is transposed); several variables of one length n are columns named by the variables (an n × k
    matrix ``acc`` giving ``acc_0`` … ``acc_{k-1}``)."""
    try:
        with open_binary(path) as fh:
            raw = fh.read()
    except DECODE_ERRORS as exc:
        raise InputError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    m = load_mat(raw, path)
    found = {k: np.asarray(v) for k, v in m.items() if not k.startswith("__")}
    wide = max(POSITIONAL)  # rows stored as columns (3 × n, as Hassan & Bao store positions, up to 7 × n)
    arrays = {k: (v.T if v.ndim == 2 and v.shape[0] < v.shape[1] and v.shape[0] <= wide else v).astype(float)
              for k, v in found.items() if v.dtype.kind in "iufb" and v.ndim <= 2 and v.size > 1}
    if not arrays:
        raise InputError(f"{path} holds no numeric matrix (variables: {listing(found) or 'none'}); "
                         "save the samples as an n × 3 or n × 4 matrix")
    if len(arrays) == 1:
        (a,) = arrays.values()
        return None, a.reshape(len(a), -1)
    lengths = {k: max(v.shape) if v.ndim == 1 or 1 in v.shape else v.shape[0] for k, v in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise InputError(f"{path}: its variables have different lengths "
                         f"({listing(f'{k} {n}' for k, n in lengths.items())}); keep one table of samples")
    names, cols = [], []
    for k, v in arrays.items():
        v = v.reshape(lengths[k], -1)
        names += [k] if v.shape[1] == 1 else [f"{k}_{j}" for j in range(v.shape[1])]
        cols.append(v)
    return names, np.hstack(cols)


def load_mat(raw: bytes, path) -> dict:
    """The variables of a MAT file's bytes (scipy.io.loadmat), every failure one line. A level 5 file whose
    compressed variables fail their zlib checksum, which MATLAB reads, is read when their data inflate in
    full (:func:`inflate_ignoring_checksums`), with a warning; a v7.3 file (HDF5), which scipy does not
    read, is read by :func:`load_mat73`."""
    from scipy.io import loadmat

    try:
        return loadmat(io.BytesIO(raw))
    except NotImplementedError:  # scipy's answer to a v7.3 file
        return load_mat73(raw, path)
    except zlib.error as exc:
        repaired = inflate_ignoring_checksums(raw)
        if repaired is None:
            raise InputError(f"cannot read MAT file {path}: a compressed variable is damaged ({exc}); save it "
                             "again from MATLAB") from None
        try:
            m = loadmat(io.BytesIO(repaired[0]))
        except Exception as exc2:  # noqa: BLE001 - scipy's parser on damaged bytes: one line, whatever it raises
            raise InputError(f"cannot read MAT file {path}: a compressed variable is damaged ({exc2}); save it "
                             "again from MATLAB") from None
        if str(path) not in _WARNED:  # said once, though the file is read for its layout and again for its data
            _WARNED.add(str(path))
            log.warning("%s: %d compressed variable(s) fail their zlib checksum but inflate in full; read as MATLAB "
                        "reads them: check the values, or save the file again", path, repaired[1])
        return m
    except Exception as exc:  # noqa: BLE001 - scipy's parser raises many kinds on bytes it does not expect
        raise InputError(f"cannot read MAT file {path}: {exc or type(exc).__name__}; save it again from MATLAB "
                         "(save(FILE, ..., '-v7')) or as a text table") from None


def load_mat73(raw: bytes, path) -> dict:
    """The variables of a MATLAB v7.3 file's bytes, read with h5py: v7.3 is HDF5 behind a 512-byte MATLAB
    header. Each top-level numeric variable (its ``MATLAB_class`` double, single, an integer or logical) is
    returned as MATLAB shows it: HDF5 stores MATLAB's column-major arrays with their dimensions reversed, so
    the array read is transposed. Anything else (text, structs, cells, sparse or empty arrays) is returned as
    an empty object array, so that it is named but not read as data; HDF5's own groups (``#refs#``) are left
    out. A file h5py cannot open is one line."""
    try:
        import h5py
    except ImportError:  # pragma: no cover - h5py is a dependency
        raise InputError(f"{path} is a MATLAB v7.3 (HDF5) file, which needs h5py: install it (pip install h5py), "
                         "or save the file with save(FILE, ..., '-v7')") from None
    out: dict = {}
    try:
        with h5py.File(io.BytesIO(raw), "r") as f:
            for name, obj in f.items():
                if name.startswith("#"):
                    continue
                cls = obj.attrs.get("MATLAB_class", b"")
                cls = cls.decode(errors="replace") if isinstance(cls, bytes) else str(cls)
                numeric = (isinstance(obj, h5py.Dataset) and cls in NUMERIC_MAT_CLASSES and obj.dtype.kind in "iufb"
                           and not obj.attrs.get("MATLAB_empty", 0))
                out[name] = np.asarray(obj[()]).T if numeric else np.empty(0, object)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path} is a MATLAB v7.3 (HDF5) file that cannot be read ({exc}); save it again from "
                         "MATLAB, with save(FILE, ..., '-v7') or '-v7.3'") from None
    return out


def inflate_ignoring_checksums(raw: bytes) -> tuple[bytes, int] | None:
    """A level 5 MAT file's bytes with each compressed data element (miCOMPRESSED, type 15) replaced by its
    inflated content, and the number whose zlib (Adler-32) checksum failed; None when the file's structure
    or a deflate stream is broken, or a variable inflates to less than its tag declares. The deflate stream
    is fed without its 4-byte checksum, so zlib never compares it (MATLAB does not either)."""
    if len(raw) < 136 or raw[126:128] not in (b"IM", b"MI"):
        return None
    order = "<" if raw[126:128] == b"IM" else ">"
    out, pos, bad = [raw[:128]], 128, 0
    while pos + 8 <= len(raw):
        typ, nbytes = struct.unpack(order + "II", raw[pos:pos + 8])
        if typ >> 16:  # a small data element: type and size in 4 bytes, data in the other 4
            out.append(raw[pos:pos + 8])
            pos += 8
            continue
        body = raw[pos + 8:pos + 8 + nbytes]
        if len(body) < nbytes:
            return None
        if typ == 15:
            try:
                data = zlib.decompress(body)
            except zlib.error:
                try:
                    data = zlib.decompressobj().decompress(body[:-4])
                except zlib.error:
                    return None
                if len(data) < 8 or len(data) < 8 + struct.unpack(order + "II", data[:8])[1]:
                    return None
                bad += 1
            out.append(data)
        else:
            out.append(raw[pos:pos + 8 + nbytes])
        pos += 8 + nbytes
    return b"".join(out), bad


def mat_layout(path: Path) -> tuple[Layout, np.ndarray]:
    """The :class:`Layout` of a MAT file's table (:func:`mat_table`) and the table itself."""
    header, table = mat_table(path)
    if header is not None:
        refuse_duplicates(header, path)
    lay = Layout(None, 0, table.shape[1], (True,) * table.shape[1], header, {}, [])
    return lay, table


def sniff_layout(path: Path) -> Layout:
    """The layout of a raw recording's text file (:func:`optcal.core.tablefile.sniff_layout`); a commented header
    line (``# t ax ay az``, ``% time acc_x ...``) is one that names a column by a role's name or alias."""
    return sniff_table(path, KNOWN)


def jump_ratio(N: np.ndarray) -> float | None:
    """The median distance between consecutive rows of ``N`` (its first :data:`KIND_ROWS`), as a fraction
    of the rows' median magnitude, or None when that cannot be measured (fewer than 2 finite rows, zero
    outputs). Positions were turned between, so consecutive ones differ by a large fraction of g (√2 g for
    the 90° turns of the 24-position scheme); consecutive samples of a recording mostly differ by noise."""
    N = np.asarray(N, float)[:KIND_ROWS]
    N = N[np.all(np.isfinite(N), axis=1)]
    if len(N) < 2:
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        scale = float(np.median(np.linalg.norm(N, axis=1)))
        jump = float(np.median(np.linalg.norm(np.diff(N, axis=0), axis=1)))
    if not (np.isfinite(scale) and np.isfinite(jump) and scale > 0):
        return None
    return jump / scale


def table_kind(names, N: np.ndarray, nrows: int, ncol: int | None = None) -> tuple[str | None, str]:
    """Whether a table holds ``"positions"`` (docs/design.md, "Positions CSV") or ``"samples"`` of a raw recording
    ("Raw recordings"), or None when neither is clear, with the evidence in words. The data decide first
    (:func:`jump_ratio`:
    :data:`POSITION_JUMP` or more is positions, :data:`SAMPLE_JUMP` or less samples); columns only a
    positions file has (:data:`POSITIONS_ONLY`) decide positions for a table of fewer than
    :data:`MANY_ROWS` rows when the data say samples (a sensor left in one pose while the temperature
    changed). ``N`` holds the ax, ay, az columns; ``ncol``, given for a table without a header, is said in
    the evidence. Both readers refuse the other kind through this one decision (:func:`positions_file_reason`,
    :func:`optcal.core.recording.reading.raw_file_reason`), so their advice cannot send a user round in a loop."""
    low = [str(h).lower() for h in names or []]
    only = [c for c in POSITIONS_ONLY if c in low]
    r = jump_ratio(N)
    named = (f"its column{'s' * (len(only) > 1)} {', '.join(only)} {'are' if len(only) > 1 else 'is'} a positions "
             "file's") if only else ""
    if r is not None and r >= POSITION_JUMP:
        said = (f"consecutive rows differ by a median {r:.0%} of the outputs' magnitude, as positions the "
                "sensor was turned between do")
        return "positions", said + (f"; {named}" if named else "")
    if named and nrows < MANY_ROWS:
        return "positions", named
    if r is not None and r <= SAMPLE_JUMP:
        shape = f" of {ncol} numbers and no header" if ncol is not None else ""
        return "samples", (f"{nrows} rows{shape}, one per sample: consecutive rows differ by a median {r:.2%} of "
                           "the outputs' magnitude, where positions differ by a large fraction of g")
    return None, ""


def positions_file_reason(lay: Layout, N: np.ndarray) -> str | None:
    """Why a file read as a raw recording is a positions file (:func:`table_kind`), or None."""
    kind, why = table_kind(lay.header, N, len(N))
    return why if kind == "positions" else None


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
    import difflib  # here: only a refusal names a close column

    names = lay.header or []
    close = difflib.get_close_matches(ref, names, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    where = f"its columns are {listing(names)}" if names else "it has no header, so give column indices"
    raise InputError(f"{path}: no column {ref!r}{hint}; {where}")


def _named(lay: Layout, keys: list[str], role: str) -> list[int]:
    """The numeric columns whose names are an alias of ``role`` (:data:`ALIASES`; a temperature only in °C or
    without a unit). ``tx`` is a time only when no ``ty`` and ``tz`` stand beside it (then it is the x of an
    axis triple, as in a header ``time tx ty tz wx wy wz``)."""
    found = [j for j, k in enumerate(keys) if lay.numeric[j]
             and (k in ALIAS_KEYS[role] or role == "temp" and k == "t" and unit_of(lay.header[j]) in T_IN_DEGREES)
             and (role != "temp" or unit_of(lay.header[j]) in (None, *T_IN_DEGREES))]
    if role == "t":
        found = [j for j in found if not (keys[j] == "tx" and {"ty", "tz"} <= set(keys))
                 and unit_of(lay.header[j]) not in T_IN_DEGREES]
    if not found and role in ("ax", "ay", "az", *GYRO):  # a sensor's own outputs under a prefix (scaledAccelX)
        found = [j for j, k in enumerate(keys) if lay.numeric[j]
                 and any(k.startswith(p) and k[len(p):] in ALIAS_KEYS[role] for p in SENSOR_PREFIXES)]
    return found


def units_from_names(names, table=NAMED_UNITS) -> str | None:
    """The units a sensor's three columns' names give, the same for all three (``table``: a unit as a name writes
    it, lower case, to the units it is; the accelerometer's :data:`NAMED_UNITS` by default); else None."""
    found = {table.get(unit_of(str(n)) or "") for n in names}
    return found.pop() if len(found) == 1 and None not in found else None


def header_gyro(lay: Layout) -> dict[str, int]:
    """The gyroscope's columns the header names (all three axes, one column each), or none."""
    if lay.header is None:
        return {}
    keys = [column_key(h) for h in lay.header]
    found = {r: _named(lay, keys, r) for r in GYRO}
    return {r: j[0] for r, j in found.items()} if all(len(j) == 1 for j in found.values()) else {}


def header_roles(lay: Layout, path: Path) -> dict[str, int]:
    """Role → column index from the header's names (:data:`ALIASES`, compared as
    :func:`~optcal.core.tablefile.column_key`s), among the numeric columns (a ``Time(hh:mm:ss)`` text column is not
    a time). A role two columns could hold is refused for t, ax, ay, az, and left out for the gyroscope and
    the temperature, as is a gyroscope without all three axes and a temperature whose name gives a unit other
    than °C (``Temp(Raw)``). Columns that do not give ax, ay, az are refused, named (the first few)."""
    keys = [column_key(h) for h in lay.header]
    out: dict[str, int] = header_gyro(lay)  # a gyroscope is three named axes, or none
    for r in ROLES:
        if r in GYRO:
            continue
        found = _named(lay, keys, r)
        if len(found) == 1:
            out[r] = found[0]
        elif len(found) > 1 and r != "temp":
            raise InputError(f"{path}: columns {listing(lay.header[j] for j in found)} could each be {r}; name "
                             "the columns with `columns`, e.g. t,ax,ay,az with names or 0-based indices")
    if all(r in out for r in ("ax", "ay", "az")):
        return out
    sensors = _prefixed_triples(lay, keys)  # imu1_ax … imu6_az: sensors side by side; say how to take one
    bare = {r: keys.index(r[1]) for r in ("ax", "ay", "az") if keys.count(r[1]) == 1 and lay.numeric[keys.index(r[1])]}
    triple = sensors[0][1] if sensors else bare if len(bare) == 3 else None  # a phone logger's bare x, y, z
    example = ",".join(f"{r}={lay.header[j]}" for r, j in
                       (({"t": out["t"]} if "t" in out else {}) | triple).items()) if triple else None
    if len(sensors) > 1:
        raise InputError(f"{path}: its columns hold {len(sensors)} accelerometers "
                         f"({listing((p for p, _ in sensors), 4)}); calibrate one at a time: `columns` {example}")
    raise InputError(
        f"{path}: cannot tell which columns are ax, ay, az (columns: {listing(lay.header)}); "
        "name them with `columns`, e.g. " + (example or "t,ax,ay,az with names or 0-based indices")
    )


def _prefixed_triples(lay: Layout, keys: list[str]) -> list[tuple[str, dict[str, int]]]:
    """The accelerometers a header holds side by side under prefixes (``imu1_ax``, ``IMU2 Acc X``, ``s3.acc_x``):
    for each prefix whose columns end in an alias of each of ax, ay and az (numeric columns, one each), the
    prefix and those columns, in the order of the header."""
    found: dict[str, dict[str, list[int]]] = {}
    for j, key in enumerate(keys):
        if not lay.numeric[j]:
            continue
        for r in ("ax", "ay", "az"):
            for alias in ALIAS_KEYS[r]:
                if len(key) > len(alias) and key.endswith(alias) and len(alias) > 1:
                    prefix = key[: -len(alias)]
                    found.setdefault(prefix, {}).setdefault(r, []).append(j)
    triples = [(p, {r: js[0] for r, js in roles.items()}) for p, roles in found.items()
               if set(roles) == {"ax", "ay", "az"} and all(len(js) == 1 for js in roles.values())]
    return sorted(triples, key=lambda pr: min(pr[1].values()))


def _spec_items(spec) -> list[str]:
    """``columns`` as a list of items: a string split at commas, a mapping {role: column} as role=column."""
    if isinstance(spec, Mapping):
        return [f"{r}={c}" for r, c in spec.items()]
    return [str(s) for s in (spec.split(",") if isinstance(spec, str) else list(spec)) if str(s).strip()]


def role_columns(spec, lay: Layout, path: Path) -> dict[str, int]:
    """Role → column index from ``spec`` (positional ``t,ax,ay,az`` or ``role=column`` items, a string, a
    sequence or a mapping {role: column}), or, when ``spec`` is None, from the header's names
    (:func:`header_roles`) or the number of numeric columns. A role given twice, or one column given for two
    roles, is refused."""
    if spec is None:
        if lay.header is not None:
            return header_roles(lay, path)
        numeric = [j for j, isnum in enumerate(lay.numeric) if isnum]
        if len(numeric) in POSITIONAL:
            return dict(zip(POSITIONAL[len(numeric)], numeric))
        raise InputError(
            f"{path}: {lay.ncol} columns and no header; name them with `columns` "
            "(0-based indices for t,ax,ay,az or ax,ay,az)"
        )
    items = _spec_items(spec)
    if items and all("=" in s for s in items):
        pairs = [[p.strip() for p in s.split("=", 1)] for s in items]
        bad = [r for r, _ in pairs if r not in ROLES]
        if bad:
            raise InputError(f"`columns`: unknown role(s) {listing(bad)}; roles are {', '.join(ROLES)}")
        roles = [r for r, _ in pairs]
        twice = next((r for j, r in enumerate(roles) if r in roles[:j]), None)
        if twice is not None:
            given = listing(c for r, c in pairs if r == twice)
            raise InputError(f"`columns` gives {twice} more than once ({given}); give each role one column")
        out = {r: resolve_column(c, lay, path) for r, c in pairs}
    elif len(items) in POSITIONAL:
        out = {r: resolve_column(c, lay, path) for r, c in zip(POSITIONAL[len(items)], items)}
    else:
        raise InputError(
            f"`columns` {listing(items)!r}: give 3 (ax,ay,az), 4 (t,ax,ay,az), 5 (t,ax,ay,az,temp) or 7 "
            "(t,ax,ay,az,gx,gy,gz) columns, or role=column items"
        )
    by_column: dict[int, str] = {}
    for r, j in out.items():
        if j in by_column:
            name = lay.header[j] if lay.header else j
            raise InputError(f"`columns` gives column {name!r} for both {by_column[j]} and {r}; each role needs a "
                             "column of its own")
        by_column[j] = r
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
