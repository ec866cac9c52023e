"""Static intervals given by hand (docs/design.md, "Raw recordings"): from a file of [start, end) sample indices (JSON,
imucal's section list, CSV, ImuCalibration's two-row file) or of times (a JSON object ``{"intervals": [[start,
end], ...]}``, seconds from the recording's first sample), or from a label column of the recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from optcal.core.errors import InputError, listing
from optcal.core.recording.detection import DetectionResult, drop_saturated
from optcal.core.recording.reading import Recording
from optcal.core.recording.sniff import is_number, split_fields

TIME_UNIT_KEYS = {"s": "s", "seconds": "s", "samples": "samples"}  # the object form's "unit"


class IntervalTimes(np.ndarray):
    """(r, 2) [start, end) intervals in seconds from the recording's first sample, as the JSON object form
    ``{"intervals": ...}`` gives them (:func:`read_intervals`); :func:`given_intervals` turns them into
    sample indices on the recording's own time axis."""


def _pairs(items) -> np.ndarray:
    return np.array([[o["start"], o["end"]] if isinstance(o, dict) else list(o) for o in items], float)


def _object_form(obj: dict, path: Path) -> np.ndarray:
    """The intervals of ``{"intervals": [[start, end], ...], "unit": "s"}`` (pairs or {start, end} items):
    seconds from the recording's first sample by default (as ``optcal noise --interval`` takes them), or
    sample indices with ``"unit": "samples"``."""
    unit = TIME_UNIT_KEYS.get(str(obj.get("unit", "s")).strip().lower())
    if unit is None:
        raise InputError(f"intervals file {path}: \"unit\" {obj['unit']!r} is not one of s, samples (the intervals' "
                         "unit: seconds from the first sample, or sample indices)")
    other = [k for k in obj if k not in ("intervals", "unit")]
    if other:
        raise InputError(f"intervals file {path}: unknown key(s) {listing(other)} beside \"intervals\"; the object "
                         "form holds \"intervals\" and, optionally, \"unit\" (s or samples)")
    iv = _pairs(obj["intervals"])
    return iv if unit == "samples" else iv.view(IntervalTimes)


def read_intervals(path) -> tuple[np.ndarray, list[str] | None]:
    """[start, end) sample indices from a file: JSON (a list of [start, end] or {start, end}, or imucal's
    section list {name: {start, end}}, whose ``*_rot`` rotation sections are skipped), or CSV/text with a
    ``start,end`` header, rows of start,end, or two rows (starts, ends) as in ImuCalibration's
    static_intervals.csv. A JSON object ``{"intervals": [[start, end], ...]}`` gives seconds from the
    recording's first sample (``"unit": "samples"`` beside it: sample indices), returned as
    :class:`IntervalTimes` for :func:`given_intervals` to place on the recording. Returns the intervals and
    the section names (None when the file has none)."""
    import json  # here: a recording's path that reads no intervals file does not import it

    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read intervals file {path}: {getattr(exc, 'strerror', None) or exc}") from None
    names = None
    try:
        if path.suffix.lower() == ".json":
            obj = json.loads(text)
            if isinstance(obj, dict) and isinstance(obj.get("intervals"), list):
                iv = _object_form(obj, path)
            elif isinstance(obj, dict):
                obj = {k: v for k, v in obj.items() if not str(k).endswith("_rot")}
                names = list(obj)
                iv = _pairs(obj.values())
            else:
                iv = _pairs(obj)
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
    if not np.all(np.isfinite(iv)):
        raise InputError(f"intervals file {path}: start and end must be finite numbers")
    if isinstance(iv, IntervalTimes):
        return iv, names
    if np.any(iv != np.round(iv)):
        raise InputError(f"intervals file {path}: start and end must be whole sample indices (for seconds, write "
                         "{\"intervals\": [[start, end], ...]})")
    return iv.astype(np.int64), names


def _samples_of(recording: Recording, iv: np.ndarray) -> np.ndarray:
    """[start, end) sample indices of [start, end) times ``iv`` (s from the first sample): the samples whose
    time lies in each; an interval outside the recording, or holding no sample, is refused in seconds."""
    if not np.isfinite(recording.rate):
        raise InputError("intervals in seconds need the recording's times: give its time column or `rate`")
    t = recording.t - recording.t[0]
    step = 1.0 / recording.rate
    tol = 1e-6 * step  # a time written to fewer digits than the clock's is still that sample's
    start = np.searchsorted(t, iv[:, 0] - tol)
    end = np.searchsorted(t, iv[:, 1] - tol)
    bad = (iv[:, 0] < 0) | (iv[:, 1] > t[-1] + step + tol) | (end <= start)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"interval {k} ({iv[k, 0]:g} s to {iv[k, 1]:g} s) is empty or outside the recording's "
                         f"{t[-1] + step:.6g} s; intervals given as {{\"intervals\": ...}} are [start, end) in seconds "
                         "from the first sample (add \"unit\": \"samples\" for sample indices)")
    return np.column_stack([start, end])


def given_intervals(recording: Recording, iv, names=None, method: str = "given") -> DetectionResult:
    """A detection result from intervals given by hand ([start, end) sample indices); an interval holding
    a saturated sample is dropped with a note. :class:`IntervalTimes` (seconds from the first sample) are
    placed on the recording's time axis first."""
    if isinstance(iv, IntervalTimes):
        iv = _samples_of(recording, np.asarray(iv, float).reshape(-1, 2))
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
            raise InputError(f"label(s) {listing(unknown)} do not occur; labels are {listing(sorted(set(names)))}")
    iv = np.column_stack([starts, ends])[keep]
    return given_intervals(recording, iv, [str(x) for x in names[keep]], method="labels")
