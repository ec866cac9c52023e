"""The names a table's columns go by (docs/design.md, "Raw recordings" and "Positions CSV"): the aliases of each
role, time, the accelerometer's ax, ay, az, the gyroscope's gx, gy, gz and the temperature, compared as
:func:`~optcal.core.tablefile.column_key` keys (case, a trailing unit in parentheses or brackets, and spaces,
underscores, dots and hyphens aside). One list for both readers: the raw recording's
(:mod:`optcal.core.recording.sniff`) and the positions file's (:func:`optcal.core.data.read_positions`)."""

from __future__ import annotations

from optcal.core.tablefile import column_key

GYRO = ("gx", "gy", "gz")  # angular rate, in the file's units (rad/s, °/s or counts): optional, all three or none
# Header names of the axes, a stem and the axis: ax, acc_x, AccX, ACCELX, accelerometer_x, ...; gx, gyr_x, GYROX,
# wx, omega_x, ... Names are compared as column_keys (case, a trailing unit in parentheses or brackets, and
# spaces, underscores, dots and hyphens aside), so acc_x stands for accx, Acc_X, ACC X and acc_x [m/s^2] too.
ACC_STEMS = ("a", "acc", "accel", "acceleration", "accelerometer", "accl",
             "加速度")  # WitMotion's software in Chinese: 加速度X(g), 角速度X(°/s), 时间, 温度(°C), 设备名称
GYRO_STEMS = ("g", "gyr", "gyro", "gyroscope", "w", "omega", "angvel", "ang_vel", "angular_velocity", "rate",
              "as", "角速度")  # as: WitMotion's exports (AsX(°/s): angular speed)
ALIASES = {
    "t": ("t", "time", "timestamp", "time_s", "t_s", "seconds", "tx", "time_ms", "t_ms", "timestamp_ms", "mstime",
          "time_us", "t_us", "timestamp_us", "ustime", "time_ns", "timestamp_ns", "nstime", "时间"),
    **{a: tuple(f"{stem}_{a[1]}" for stem in ACC_STEMS) + tuple(f"{stem}_{a[1]}_raw" for stem in ACC_STEMS[1:3])
       for a in ("ax", "ay", "az")},
    **{g: tuple(f"{stem}_{g[1]}" for stem in GYRO_STEMS) + (f"gyr_{g[1]}_raw", f"gyro_{g[1]}_raw") for g in GYRO},
    "temp": ("temp", "temperature", "temp_c", "t_degc", "温度"),
}
ALIAS_KEYS = {r: frozenset(column_key(a) for a in names) for r, names in ALIASES.items()}
