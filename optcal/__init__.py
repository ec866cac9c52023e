"""optcal: reference-free calibration of triaxial accelerometers, and a bench for comparing optimisers.

The problem library (the core layer: models, schemes, simulation, data I/O, the calibration problem,
analysis, discovery's statistics, navigation, calibration files), and above it the application layer (the
CLI, the workflows that run a solver, the Python API), which imports ``solvers`` directly; the core never
does (CONTRIBUTING.md, "Layers"). This package is a facade over both: its names load at first use.

The public names are loaded at first use (PEP 562), so that ``import optcal`` and ``optcal --help`` do not
import NumPy, SciPy or anything heavier; ``from optcal import simulate`` works as before. The front door for
Python users is ``optcal.calibrate``, ``optcal.apply``, ``optcal.read_recording`` and ``optcal.noise``, with
``optcal.calibrate_imu`` and ``optcal.apply_gyro`` for an IMU (``optcal.api``, docs/api.md). As
``optcal.simulate`` is the function and not its submodule, ``optcal.noise`` is the analysis function; the
module's names are imported from it (``from optcal.noise import analyse``).
"""

from __future__ import annotations

import importlib
import sys
import types

from .errors import BudgetExhausted, InputError

__version__ = "0.1.0"

__all__ = [
    "NAMED_MODELS", "TERMS", "Budget", "BudgetExhausted", "CalibrationProblem", "Context", "InputError", "Model",
    "DiscoveryReport", "PositionsData", "Simulation", "discover", "get_model", "read_positions", "simulate",
    "apply", "apply_gyro", "calibrate", "calibrate_imu", "noise", "read_recording", "study",
]

# name -> the submodule that defines it, imported when the name is first looked up.
_LAZY = {
    # the front door (docs/api.md): optcal.calibrate, optcal.apply, optcal.read_recording, optcal.noise
    "apply": "api", "calibrate": "api", "noise": "api", "read_recording": "api",
    "calibrate_imu": "api", "apply_gyro": "api",  # the IMU: accelerometer and gyroscope (docs/gyroscope.md)
    "PositionsData": "data", "read_positions": "data",
    "DiscoveryReport": "discovery", "discover": "discovery",
    "NAMED_MODELS": "model", "TERMS": "model", "Context": "model", "Model": "model", "get_model": "model",
    "Budget": "problem", "CalibrationProblem": "problem",
    "Simulation": "simulate", "simulate": "simulate",
    "study": "study",  # the studies' Python API (application layer: optcal/study.py, docs/api.md)
}
# Submodules that an eager ``import optcal`` used to leave reachable as attributes (``optcal.model``).
_SUBMODULES = frozenset({"analysis", "data", "discovery", "errors", "linfit", "model", "presets", "problem",
                         "schemes"})


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _Package(types.ModuleType):
    """``optcal.simulate`` is the function, as it was when the package imported it eagerly: importing the
    submodule ``optcal.simulate`` (which Python records as an attribute of the package) must not replace it.
    The same holds for ``optcal.noise``, the front-door function, and the submodule ``optcal.noise``."""

    def __setattr__(self, name, value):
        if isinstance(value, types.ModuleType) and name in _LAZY and value.__name__ == f"{__name__}.{name}":
            return  # the submodule of the same name; the attribute stays the public function
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
