"""Raw recordings (docs/design.md, "Raw recordings") → static intervals → positions, one job per module.

The core of it, one job per module:

- :mod:`~optcal.core.recording.sniff`: the file's layout (delimiter, header, ``key,value`` lines, columns);
- :mod:`~optcal.core.recording.reading`: :func:`read_recording` → :class:`Recording`;
- :mod:`~optcal.core.recording.segment`: the default detector, change points (ruptures' PELT) and a rest test,
  :func:`segment_static` → :class:`DetectionResult` (docs/segmentation.md), with the precision and recall
  of detected intervals, :func:`interval_scores` (the simulated recordings they are measured on:
  :mod:`optcal.core.synthetic_recording`);
- :mod:`~optcal.core.recording.detection`: the variance detector (Tedaldi et al. 2014, §IV-A),
  :func:`detect_static` → :class:`DetectionResult`, and :func:`parse_ks` for its threshold multipliers;
- :mod:`~optcal.core.recording.intervals`: intervals given by hand or by a label column;
- :mod:`~optcal.core.recording.positions`: averaging intervals into positions, :func:`positions_from_recording`;
- :mod:`~optcal.core.recording.report`: what detection found, as text, :func:`describe_detection`.

What fits a model, and so runs a solver, is the application's :mod:`optcal.app.workflows.recording`: the
variance detector's threshold search and :func:`~optcal.app.workflows.recording.positions_from_raw`, a
recording file to positions in one call. The figure of a recording is
:func:`optcal.core.plots.recording.recording_figure`. Errors name the functions' parameters in backquotes
(`` `rate` ``); the command line puts its option names there (optcal/app/commands/_dataopts.py).
"""


from optcal.core.recording.detection import (
    DEFAULT_KS,
    NO_REST_RATIO,
    DetectionResult,
    detect_static,
    parse_ks,
    too_few,
    variance_statistic,
)
from optcal.core.recording.intervals import given_intervals, label_intervals, read_intervals
from optcal.core.recording.positions import positions_from_recording
from optcal.core.recording.reading import _NOT_LOADED as _NOT_LOADED  # the reader's "pyarrow not imported yet" marker
from optcal.core.recording.reading import INT16_RAILS, Recording, read_recording
from optcal.core.recording.report import describe_detection, detection_summary
from optcal.core.recording.segment import interval_scores, segment_static
from optcal.core.recording.sniff import ALIASES, POSITIONAL, RATE_KEYS, ROLES, SNIFF_LINES

__all__ = [
    "ALIASES", "DEFAULT_KS", "INT16_RAILS", "NO_REST_RATIO", "POSITIONAL", "RATE_KEYS", "ROLES", "SNIFF_LINES",
    "DetectionResult", "Recording", "describe_detection", "detect_static",
    "detection_summary", "given_intervals", "label_intervals", "parse_ks", "positions_from_recording",
    "read_intervals", "read_recording", "segment_static", "too_few", "variance_statistic", "interval_scores",
]

