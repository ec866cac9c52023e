"""Static intervals given by hand (docs/design.md §9.2): from a file of [start, end) sample indices (JSON,
imucal's section list, CSV, ImuCalibration's two-row file) or from a label column of the recording."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import InputError
from .detection import DetectionResult, drop_saturated
from .reading import Recording
from .sniff import is_number, split_fields


def read_intervals(path) -> tuple[np.ndarray, list[str] | None]:
    """[start, end) sample indices from a file: JSON (a list of [start, end] or {start, end}, or imucal's
    section list {name: {start, end}}, whose ``*_rot`` rotation sections are skipped), or CSV/text with a
    ``start,end`` header, rows of start,end, or two rows (starts, ends) as in ImuCalibration's
    static_intervals.csv. Returns the intervals and the section names (None when the file has none)."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read intervals file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    names = None
    try:
        if path.suffix.lower() == ".json":
            obj = json.loads(text)
            if isinstance(obj, dict):
                obj = {k: v for k, v in obj.items() if not str(k).endswith("_rot")}
                names = list(obj)
                obj = list(obj.values())
            iv = np.array([[o["start"], o["end"]] if isinstance(o, dict) else list(o) for o in obj], float)
        else:
            lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
            delim = "," if "," in lines[0] else None
            first = split_fields(lines[0], delim)
            if not all(is_number(x) for x in first):
                low = [x.lower() for x in first]
                if "start" not in low or "end" not in low:
                    raise InputError(f"intervals file {path}: its header needs columns start and end")
                rows = np.array([[float(v) for v in split_fields(ln, delim)] for ln in lines[1:]], ndmin=2)
                iv = rows[:, [low.index("start"), low.index("end")]]
            else:
                rows = np.array([[float(v) for v in split_fields(ln, delim)] for ln in lines], ndmin=2)
                transposed = rows.shape[0] == 2 and rows.shape[1] != 2
                iv = rows.T if transposed else rows
    except InputError:
        raise
    except (ValueError, KeyError, TypeError, IndexError, json.JSONDecodeError):
        raise InputError(
            f"intervals file {path} is not a list of start,end sample indices (JSON or CSV)"
        ) from None
    if iv.ndim != 2 or iv.shape[1] != 2 or not len(iv):
        raise InputError(f"intervals file {path} holds no start,end pairs")
    if np.any(iv != np.round(iv)):
        raise InputError(f"intervals file {path}: start and end must be whole sample indices")
    return iv.astype(np.int64), names


def given_intervals(recording: Recording, iv, names=None, method: str = "given") -> DetectionResult:
    """A detection result from intervals given by hand ([start, end) sample indices); an interval holding
    a saturated sample is dropped with a note."""
    iv = np.asarray(iv, np.int64).reshape(-1, 2)
    n = len(recording)
    bad = (iv[:, 0] < 0) | (iv[:, 1] > n) | (iv[:, 1] <= iv[:, 0])
    if bad.any():
        s, e = iv[np.flatnonzero(bad)[0]]
        raise InputError(
            f"interval {int(np.flatnonzero(bad)[0])} (start {s}, end {e}) is empty or outside the "
            f"recording's {n} samples; intervals are [start, end) sample indices"
        )
    notes: list[str] = []
    iv, names = drop_saturated(recording, iv, notes, names)
    return DetectionResult(recording, iv, method, names, notes=notes)


def label_intervals(recording: Recording, values=None) -> DetectionResult:
    """Intervals from a label column: each contiguous run of one of ``values`` (all labels if None)."""
    lab = recording.labels
    if lab is None:
        raise InputError("no label column was read; name one with `labels`")
    change = np.flatnonzero(lab[1:] != lab[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(lab)]])
    names = lab[starts]
    keep = np.ones(len(starts), bool) if values is None else np.isin(names, list(values))
    if values is not None:
        unknown = sorted(set(values) - set(names.tolist()))
        if unknown:
            raise InputError(f"label(s) {', '.join(unknown)} do not occur; labels are {', '.join(sorted(set(names)))}")
    iv = np.column_stack([starts, ends])[keep]
    return given_intervals(recording, iv, [str(x) for x in names[keep]], method="labels")
