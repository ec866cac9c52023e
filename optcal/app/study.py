"""``optcal.study``: run a comparison study from Python and get its results as pandas tables (docs/api.md).

Application layer, as :mod:`optcal.app.api` is: the studies live in the ``studies`` package (above the solvers),
which the core never imports; this module only hands the name on (:func:`optcal.studies.api.study`).
"""

from __future__ import annotations

from optcal.studies.api import StudyResult, study

__all__ = ["StudyResult", "study"]
