"""Gyroscope calibration from the same multi-position recording as the accelerometer's (issue #23).

The motions between rests, integrated with the calibrated rate, must carry one rest's gravity direction
onto the next's (Tedaldi, Pretto and Menegatti, ICRA 2014): :mod:`.model` (the sensor model),
:mod:`.data` (rests and motions of a recording), :mod:`.problem` (the calibration problem the solvers
take), :mod:`.simulate` (recordings with known truth).
"""

from optcal.core.gyro.data import GyroData
from optcal.core.gyro.model import GyroModel, get_gyro_model
from optcal.core.gyro.problem import GyroPresets, GyroProblem
from optcal.core.gyro.simulate import SimulatedIMU, draw_truth, simulate_imu

__all__ = ["GyroData", "GyroModel", "GyroPresets", "GyroProblem", "SimulatedIMU", "draw_truth", "get_gyro_model",
           "simulate_imu"]
