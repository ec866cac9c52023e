"""optcal: reference-free calibration of triaxial accelerometers, and a bench for comparing optimisers.

One folder per layer, each importing only the ones below it (CONTRIBUTING.md, "Layers"):
:mod:`optcal.core` (the problem library: models, schemes, simulation, data and recordings, the calibration
problem, analysis, discovery's statistics, noise, navigation, calibration files) ← :mod:`optcal.solvers` (the
registry of backends) ← :mod:`optcal.studies` (Monte-Carlo comparison studies) ← :mod:`optcal.app` (the CLI,
the workflows that run a solver, the Python API).

This file is the front door for Python users and imports none of them: its names are loaded at first use
(PEP 562), so that ``import optcal`` and ``optcal --help`` do not import NumPy, SciPy or anything heavier.
``optcal.calibrate``, ``optcal.apply``, ``optcal.read_recording`` and ``optcal.noise`` (the noise analysis),
with ``optcal.calibrate_imu`` and ``optcal.apply_gyro`` for an IMU, come from :mod:`optcal.app.api`
(docs/api.md); ``optcal.study`` from :mod:`optcal.app.study`; the rest from the core.
"""

from __future__ import annotations

from optcal.core.errors import BudgetExhausted, InputError
from optcal.core.lazy import lazy_names

__version__ = "0.1.0"

__all__ = [
    "NAMED_MODELS", "TERMS", "Budget", "BudgetExhausted", "CalibrationProblem", "Context", "InputError", "Model",
    "DiscoveryReport", "PositionsData", "Simulation", "discover", "get_model", "read_positions", "simulate",
    "apply", "apply_gyro", "calibrate", "calibrate_imu", "noise", "read_recording", "study",
]

# name -> the module that defines it, imported when the name is first looked up.
_LAZY = {
    # the front door (docs/api.md): optcal.calibrate, optcal.apply, optcal.read_recording, optcal.noise
    "apply": "app.api", "calibrate": "app.api", "noise": "app.api", "read_recording": "app.api",
    "calibrate_imu": "app.api", "apply_gyro": "app.api",  # the IMU: accelerometer and gyroscope
    "discover": "app.workflows.discovery",
    "study": "app.study",  # the studies' Python API (docs/api.md)
    "PositionsData": "core.data", "read_positions": "core.data",
    "DiscoveryReport": "core.discovery",
    "NAMED_MODELS": "core.model", "TERMS": "core.model", "Context": "core.model", "Model": "core.model",
    "get_model": "core.model",
    "Budget": "core.problem", "CalibrationProblem": "core.problem",
    "Simulation": "core.simulate", "simulate": "core.simulate",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, __all__)
