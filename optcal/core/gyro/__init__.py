"""Gyroscope calibration from the same multi-position recording as the accelerometer's (issue #23).

The motions between rests, integrated with the calibrated rate, must carry one rest's gravity direction
onto the next's (Tedaldi, Pretto and Menegatti, ICRA 2014): :mod:`.model` (the sensor model),
:mod:`.data` (rests and motions of a recording), :mod:`.problem` (the calibration problem the solvers
take), :mod:`.simulate` (recordings with known truth).
"""

import importlib

__all__ = ["GyroData", "GyroModel", "GyroPresets", "GyroProblem", "SimulatedIMU", "draw_truth", "get_gyro_model",
           "simulate_imu"]

# name -> the module that defines it, imported when the name is first looked up (PEP 562): a command that reads
# and fits a gyroscope imports neither the simulator nor the schemes it draws from
_LAZY = {"GyroData": "data", "GyroModel": "model", "get_gyro_model": "model", "GyroPresets": "problem",
         "GyroProblem": "problem", "SimulatedIMU": "simulate", "draw_truth": "simulate", "simulate_imu": "simulate"}


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
