"""Model discovery: find where a fitted model and the measurements disagree, name the missing effect, add
it, and show the gap shrink (docs/design.md, "Model discovery"; docs/discovery.md).

The core of it: :mod:`.statistics` (regressors, the F-test and ΔBIC, the noise of each residual),
:mod:`.dictionary` (the generated features the term table lacks and their linearised screening),
:mod:`.diagnostics` (the residuals against orientation, temperature, time, order and duration, at the floor),
:mod:`.results` (:class:`Step`, :class:`DiscoveryReport`), :mod:`.text` (the plain-text report) and
:mod:`.figures` (the diagnostics' figure); the steps' figure is :mod:`optcal.core.plots.discovery`. The search
itself runs a solver and so is the application's :mod:`optcal.app.workflows.discovery` (``discover``,
``fit_model``, ``score``; ``optcal.discover`` at the top).
"""

from __future__ import annotations

from optcal.core.discovery.results import DiscoveryReport, Step
from optcal.core.discovery.statistics import (
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

__all__ = ["CANDIDATES", "DEFAULT_ALPHA", "DEFAULT_BIC_THRESHOLD", "EXPLAINED", "NO_DOF", "REMAINS", "UNKNOWN",
           "DiscoveryReport", "Fit", "Score", "Step", "best_of", "noise_per_position",
           "projected", "regressors"]

