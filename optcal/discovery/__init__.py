"""Model discovery: find where a fitted model and the measurements disagree, name the missing effect, add
it, and show the gap shrink (docs/design.md §12; docs/discovery.md).

The package spans two layers (CONTRIBUTING.md, "Layers"). Core: :mod:`.statistics` (regressors, the
F-test and ΔBIC, the noise of each residual), :mod:`.dictionary` (the generated features the term table lacks
and their linearised screening), :mod:`.diagnostics` (the residuals against orientation, temperature, time,
order and duration, at the floor), :mod:`.results` (:class:`Step`, :class:`DiscoveryReport`), :mod:`.text`
(the plain-text report) and :mod:`.figures` (the diagnostics' figure); the steps' figure is
:mod:`optcal.plots.discovery`. Application:
:mod:`.workflow`, the search itself, which runs a solver (:func:`discover`, :func:`fit_model`,
:func:`score`).

This file re-exports both. The core names are imported here; the workflow's are imported at first use
(PEP 562), by a plain ``from . import workflow`` that import-linter sees, so that importing a core
submodule (which runs this file first) never imports ``solvers``. The layer contracts in pyproject.toml
therefore count ``optcal.discovery`` itself, like ``optcal.discovery.workflow``, as application layer.
"""

from __future__ import annotations

from .results import DiscoveryReport, Step
from .statistics import (
    CANDIDATES,
    DEFAULT_ALPHA,
    DEFAULT_BIC_THRESHOLD,
    EXPLAINED,
    NO_DOF,
    REMAINS,
    UNKNOWN,
    Fit,
    Score,
    best_of,
    noise_per_position,
    projected,
    regressors,
)

_WORKFLOW = ("discover", "fit_model", "score")

__all__ = ["CANDIDATES", "DEFAULT_ALPHA", "DEFAULT_BIC_THRESHOLD", "EXPLAINED", "NO_DOF", "REMAINS", "UNKNOWN",
           "DiscoveryReport", "Fit", "Score", "Step", "best_of", "discover", "fit_model", "noise_per_position",
           "projected", "regressors", "score"]


def __getattr__(name: str):
    if name in _WORKFLOW:
        from . import workflow

        value = getattr(workflow, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
