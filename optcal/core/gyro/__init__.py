"""Gyroscope calibration from the same multi-position recording as the accelerometer's (issue #23).

The motions between rests, integrated with the calibrated rate, must carry one rest's gravity direction
onto the next's (Tedaldi, Pretto and Menegatti, ICRA 2014): :mod:`.model` (the sensor model),
:mod:`.data` (rests and motions of a recording), :mod:`.problem` (the calibration problem the solvers
take), :mod:`.simulate` (recordings with known truth).
"""

from optcal.core.lazy import lazy_names

__all__ = ["GyroData", "GyroModel", "GyroPresets", "GyroProblem", "SimulatedIMU", "draw_truth", "get_gyro_model",
           "simulate_imu"]

# name -> the module that defines it, imported when the name is first looked up (PEP 562): a command that reads
# and fits a gyroscope imports neither the simulator nor the schemes it draws from
_LAZY = {"GyroData": "data", "GyroModel": "model", "get_gyro_model": "model", "GyroPresets": "problem",
         "GyroProblem": "problem", "SimulatedIMU": "simulate", "draw_truth": "simulate", "simulate_imu": "simulate"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, __all__)
