"""Raw recordings (docs/design.md §9.2) → static intervals → positions, one job per module.

The package spans two layers (CONTRIBUTING.md, "Layers"). Core:

- :mod:`~optcal.recording.sniff`: the file's layout (delimiter, header, ``key,value`` lines, columns);
- :mod:`~optcal.recording.reading`: :func:`read_recording` → :class:`Recording`;
- :mod:`~optcal.recording.segment`: the default detector, change points (ruptures' PELT) and a rest test,
  :func:`segment_static` → :class:`DetectionResult` (docs/segmentation.md), with the precision and recall
  of detected intervals, :func:`interval_scores` (the simulated recordings they are measured on:
  :mod:`optcal.synthetic_recording`);
- :mod:`~optcal.recording.detection`: the variance detector (Tedaldi et al. 2014, §IV-A),
  :func:`detect_static` → :class:`DetectionResult`, and :func:`parse_ks` for its threshold multipliers;
- :mod:`~optcal.recording.intervals`: intervals given by hand or by a label column;
- :mod:`~optcal.recording.positions`: averaging intervals into positions, :func:`positions_from_recording`;
- :mod:`~optcal.recording.report`: what detection found, as text, :func:`describe_detection`.

Application: :mod:`~optcal.recording.workflow`, what fits a model and so runs a solver: the variance
detector's threshold search :func:`choose_threshold` (scored by :func:`fit_score`) and
:func:`positions_from_raw`, a recording file to positions in one call. The figure of a recording is
:func:`optcal.plots.recording.recording_figure`.

This file re-exports both: the core names here, the workflow's at first use (PEP 562) through a plain
``from . import workflow``, so importing a core submodule (which runs this file first) never imports the
solvers. Errors name the functions' parameters in backquotes (`` `rate` ``); the command line puts its
option names there (optcal/commands/_dataopts.py).
"""


from .detection import (
    DEFAULT_KS,
    NO_REST_RATIO,
    DetectionResult,
    detect_static,
    parse_ks,
    too_few,
    variance_statistic,
)
from .intervals import given_intervals, label_intervals, read_intervals
from .positions import positions_from_recording
from .reading import _NOT_LOADED as _NOT_LOADED  # the reader's "pyarrow not imported yet" marker
from .reading import INT16_RAILS, Recording, read_recording
from .report import describe_detection, detection_summary
from .segment import interval_scores, segment_static
from .sniff import ALIASES, POSITIONAL, RATE_KEYS, ROLES, SNIFF_LINES

_WORKFLOW = ("choose_threshold", "fit_score", "positions_from_raw")

__all__ = [
    "ALIASES", "DEFAULT_KS", "INT16_RAILS", "NO_REST_RATIO", "POSITIONAL", "RATE_KEYS", "ROLES", "SNIFF_LINES",
    "DetectionResult", "Recording", "choose_threshold", "describe_detection", "detect_static",
    "detection_summary", "fit_score",
    "given_intervals", "label_intervals", "parse_ks", "positions_from_raw", "positions_from_recording",
    "read_intervals", "read_recording", "segment_static", "too_few", "variance_statistic", "interval_scores",
]


def __getattr__(name: str):
    if name in _WORKFLOW:
        from . import workflow

        value = getattr(workflow, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
