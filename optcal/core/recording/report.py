"""What static detection found, as text (:func:`describe_detection`) and as a dict for JSON
(:func:`detection_summary`): how the recording was read (format, time unit, ADC and its rails, samples set
aside as saturated), the intervals, how they were found (segmentation's noise and rest test, or the variance
detector's threshold and its search), the notes (docs/design.md, "Raw recordings"; docs/segmentation.md)."""

from __future__ import annotations

from optcal.core.data import PositionsData
from optcal.core.recording.clock import CLOCK_TIME
from optcal.core.recording.detection import DetectionResult


def describe_detection(obj: DetectionResult | PositionsData) -> str:
    """What detection found (a :class:`DetectionResult`, or positions made from one): intervals, samples,
    the threshold chosen and the notes. Times in s, the search's scores in µg."""
    det: DetectionResult = obj.extra["detection"] if isinstance(obj, PositionsData) else obj
    rec = det.recording
    frac = det.n_static_samples / max(len(rec), 1)
    squared = f"({rec.units})²" if "/" in rec.units else f"{rec.units}²"  # ς is a norm of variances
    head = (f"recording {rec.path}: {len(rec)} samples, {rec.duration:.1f} s at {rec.rate:.6g} Hz, units {rec.units}"
            + (" (as the columns' names give them)" if rec.reading.get("units_from_names") else "")
            + (f", {int(rec.saturated.sum())} saturated sample(s)" if rec.saturated.any() else ""))
    read = reading_line(rec.reading, int(rec.saturated.sum()))
    if det.method == "variance":
        ref = (f"initial rest {det.init_samples} samples" if det.init_samples is not None
               else "no rest at the start: the quietest windows' noise floor")
        how = (f"variance detector (Tedaldi et al. 2014): window {det.window} samples, {ref} "
               f"(ς_init = {det.init_variance:.4g} {squared}), "
               f"threshold k = {det.k:g} × ς_init, minimum {det.min_samples} samples")
        if det.search:
            tried = ", ".join(f"{r['k']:g}:{r['n_intervals']}" + (f"/{r['score'] * 1e6:.1f}"
                              if r["score"] is not None else "") for r in det.search)
            how += f"\n  k searched (k:intervals/score σ_up/√n in µg, smallest kept): {tried}"
    elif det.method == "segment":
        sg = det.segmentation
        noise = ", ".join(f"{v:.3g}" for v in det.noise)
        how = (f"change-point segmentation (PELT on {det.block}-sample block means) and a rest test: "
               f"noise SD per sample {noise} {rec.units} (x, y, z, from the recording), poses of at least "
               f"{det.min_samples} samples (each kept without its edges, which may hold the motion's samples: "
               f"{max(det.min_samples // 2, 3)} or more remain), rest tested in windows of up to {det.window} "
               f"samples; "
               f"{len(sg.segments)} segment(s), {int(sg.rest.sum())} at rest")
        if sg.turning is not None:
            gyro = ", ".join(str(rec.columns[r]) for r in ("gx", "gy", "gz") if r in rec.columns)
            how += f"; stillness judged on the gyroscope too{f' ({gyro})' if gyro else ''}"
    else:
        how = "intervals given by hand" if det.method == "given" else "intervals from the label column"
    lines = [head, *([read] if read else [])]
    lines += [f"{det.n_intervals} static interval(s), {det.n_static_samples} samples ({100 * frac:.0f}%); {how}"]
    t = rec.shown_t
    for i, (s, e) in enumerate(det.intervals):
        name = f" {det.names[i]}" if det.names else ""
        lines.append(f"  {i:3d}{name}: samples {s}–{e - 1} ({t[s]:.2f}–{t[e - 1]:.2f} s, n = {e - s})")
    lines += [f"  note: {n}" for n in det.notes]
    return "\n".join(lines)


def reading_line(how: dict, n_saturated: int) -> str:
    """How the file was read (:attr:`~optcal.core.recording.reading.Recording.reading`), in one line."""
    parts = []
    if how.get("format"):
        what = how["format"] + (f", {how['compression']}-compressed" if how.get("compression") else "")
        if how.get("delimiter"):
            names = {",": "comma", ";": "semicolon", "\t": "tab"}
            what += f", {names.get(how['delimiter'], how['delimiter'])}-separated"
        if how.get("decimal") == ",":
            what += ", decimal comma"
        parts.append(what)
    if how.get("time_unit") == CLOCK_TIME:
        parts.append(f"times of day (hh:mm:ss) in column {how.get('clock_column', 'time')}, in s from the first "
                     "sample")
    elif how.get("time_unit"):
        parts.append(f"time column in {how['time_unit'].replace('us', 'µs')}")
    if how.get("time_origin_s"):
        parts.append(f"times shown from the first sample's stamp, {how['time_origin_s']:.3f} s (a date's)")
    if how.get("stamps_jitter_s"):
        parts.append(f"its stamps wander by up to {how['stamps_jitter_s'] * 1e3:.3g} ms about an even rate, as a "
                     "host's arrival times do: the samples are taken evenly spaced")
    if "adc" in how:
        lo, hi = how["rails"]
        parts.append(f"counts {how['adc']} ({'inferred from the data' if how.get('adc_inferred') else 'declared'}; "
                     f"rails {lo:.0f} and {hi:.0f} counts)")
    if "saturation" in how:
        parts.append(f"saturation at |output| ≥ {how['saturation']:g}")
    if how.get("joined_files"):
        parts.append(f"{how['joined_files']} files joined in turn, a missing sample between two (no rest spans them)")
    if how.get("other_record_rows"):
        parts.append(f"{how['other_record_rows']} row(s) of another record type, interleaved, without the chosen "
                     "columns' values, left out")
    if how.get("held_rows"):
        parts.append(f"{how['held_rows']} row(s) that repeat the row before on every axis left out (the log runs "
                     "faster than the sensor outputs; the rate is the sensor's)")
    for axis, vals in how.get("stuck", {}).items():
        parts.append(f"{axis} sticks at {', '.join(f'{v:g}' for v in vals)} (its extreme)")
    if not parts:
        return ""
    return "read as " + "; ".join(parts) + f"; {n_saturated} sample(s) set aside as saturated"


def detection_summary(obj: DetectionResult | PositionsData) -> dict:
    """What :func:`describe_detection` prints, as a dict for JSON output: the rate in Hz, the time unit,
    the counts' format and rails, the samples set aside as saturated, the intervals and the threshold."""
    det: DetectionResult = obj.extra["detection"] if isinstance(obj, PositionsData) else obj
    rec = det.recording
    return {
        "path": rec.path, "n_samples": len(rec), "duration_s": rec.duration, "rate_hz": rec.rate, "units": rec.units,
        "reading": dict(rec.reading), "n_saturated_samples": int(rec.saturated.sum()),
        "method": det.method, "n_intervals": det.n_intervals, "n_static_samples": det.n_static_samples,
        "intervals": det.intervals.tolist(), "k": det.k,
        "reference": det.reference if det.method == "variance" else None,
        "noise_per_sample": None if det.noise is None else [float(v) for v in det.noise],
        "notes": list(det.notes),
    }
