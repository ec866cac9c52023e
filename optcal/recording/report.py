"""What static detection found, as text: the recording, the intervals, the threshold and its search, the
notes (docs/design.md §9.2)."""

from __future__ import annotations

from ..data import PositionsData
from .detection import DetectionResult


def describe_detection(obj: DetectionResult | PositionsData) -> str:
    """What detection found (a :class:`DetectionResult`, or positions made from one): intervals, samples,
    the threshold chosen and the notes. Times in s, the search's scores in µg."""
    det: DetectionResult = obj.extra["detection"] if isinstance(obj, PositionsData) else obj
    rec = det.recording
    frac = det.n_static_samples / max(len(rec), 1)
    squared = f"({rec.units})²" if "/" in rec.units else f"{rec.units}²"  # ς is a norm of variances
    head = (f"recording {rec.path}: {len(rec)} samples, {rec.duration:.1f} s at {rec.rate:.6g} Hz, units {rec.units}"
            + (f", {int(rec.saturated.sum())} saturated sample(s)" if rec.saturated.any() else ""))
    if det.method == "variance":
        how = (f"variance detector (Tedaldi et al. 2014): window {det.window} samples, initial rest "
               f"{det.init_samples} samples (ς_init = {det.init_variance:.4g} {squared}), "
               f"threshold k = {det.k:g} × ς_init, minimum {det.min_samples} samples")
        if det.search:
            tried = ", ".join(f"{r['k']:g}:{r['n_intervals']}" + (f"/{r['score'] * 1e6:.1f}"
                              if r["score"] is not None else "") for r in det.search)
            how += f"\n  k searched (k:intervals/score σ_up/√n in µg, smallest kept): {tried}"
    else:
        how = "intervals given by hand" if det.method == "given" else "intervals from the label column"
    lines = [head, f"{det.n_intervals} static interval(s), {det.n_static_samples} samples ({100 * frac:.0f}%); {how}"]
    for i, (s, e) in enumerate(det.intervals):
        name = f" {det.names[i]}" if det.names else ""
        lines.append(f"  {i:3d}{name}: samples {s}–{e - 1} ({rec.t[s]:.2f}–{rec.t[e - 1]:.2f} s, n = {e - s})")
    lines += [f"  note: {n}" for n in det.notes]
    return "\n".join(lines)
