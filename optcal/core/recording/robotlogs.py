"""Robot and drone logs as raw recordings (issue #33): what the readers of ROS bags
(:mod:`optcal.core.recording.bags`) and PX4 ULog (:mod:`optcal.core.recording.ulog`) share, and how their samples
become the table :func:`optcal.core.recording.reading.read_recording` reads a text file or a MAT file as.

A log is told by its first bytes or its name (:func:`log_kind`): a ROS 1 bag (``#ROSBAG V2.0``, or ``.bag``), a
ROS 2 bag (a folder holding ``metadata.yaml``, or its ``.db3`` or ``.mcap`` file), a ULog (``ULog`` and its
version bytes, or ``.ulg``). Its samples are a table of columns ``t`` (s from the first sample), ``ax, ay, az``
(the accelerometer, m/s²), ``gx, gy, gz`` (the gyroscope, rad/s, when the log has one) and ``temp`` (°C, when
the log records it): the names the recording path knows (:data:`optcal.core.recording.sniff.ALIASES`), so `columns`
can pick among them as in any table (``optcal noise`` reads the gyroscope's columns in the accelerometer's
roles). The units are the messages' own (ROS's ``sensor_msgs/msg/Imu``, PX4's ``sensor_combined`` and
``sensor_accel``), so `units` is not needed: left at its default (g), or given as m/s2, the accelerometer is read
in m/s², and other units are refused (:func:`log_units`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.tablefile import Layout

ROS1_MAGIC = b"#ROSBAG V"
ULOG_MAGIC = b"ULog\x01\x12\x35"
TIME_TOLERANCE = 0.1  # two sensors share their stamps when none differs by more than this fraction of a step
ACC_NAMES = ("ax", "ay", "az")


def log_kind(path) -> str | None:
    """``"bag"`` (ROS 1 or ROS 2), ``"ulog"``, or None for any other file (a table, a MAT file) or a path that
    does not exist."""
    path = Path(path)
    if path.is_dir():
        return "bag" if (path / "metadata.yaml").is_file() else None
    if not path.is_file():
        return None
    suffix = path.suffix.lower()
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
    except OSError:
        return None
    if head.startswith(ROS1_MAGIC) or suffix in (".bag", ".db3", ".mcap"):
        return "bag"
    if head.startswith(ULOG_MAGIC) or suffix == ".ulg":
        return "ulog"
    return None


@dataclass
class LogSamples:
    """A log's IMU samples: times (int64, in ``tick`` seconds each: 1e-9 for ROS's nanoseconds, 1e-6 for PX4's
    microseconds; increasing), the accelerometer's (n, 3) in m/s², the gyroscope's (n, 3) in rad/s or None,
    the temperature (n,) in °C or None, and how they were read (JSON-ready, for
    :attr:`optcal.core.recording.Recording.reading`)."""

    stamps: np.ndarray
    tick: float
    acc: np.ndarray
    gyro: np.ndarray | None
    temp: np.ndarray | None
    how: dict


def sort_stamps(t: np.ndarray, path, name: str, tick: float) -> np.ndarray:
    """The order that sorts the stamps ``t`` (messages may be recorded out of their stamps' order); a stamp
    repeated is refused."""
    order = np.argsort(t, kind="stable")
    ts = t[order]
    same = np.flatnonzero(np.diff(ts) == 0)
    if len(same):
        raise InputError(f"{path}: {len(same)} message(s) of {name} repeat the stamp of the one before (first at "
                         f"{(ts[same[0]] - ts[0]) * tick:.6f} s from the first); keep one sample per stamp (e.g. "
                         "rosbag filter) or record with a stamp per sample")
    return order


def at_times(t_acc: np.ndarray, t_gyro: np.ndarray, X: np.ndarray,
             gap_steps: float | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
    """Samples ``X`` (m, k) taken at the increasing times ``t_gyro`` (m,), at the increasing times ``t_acc`` (n,):
    as they are when the times agree within :data:`TIME_TOLERANCE` of a step, else linearly interpolated (times
    counted from ``t_gyro[0]`` before the one conversion to float: integer stamps lose no precision). Returns them
    (n, k), which of ``t_acc`` they hold (inside ``t_gyro``'s span and, with ``gap_steps``, not inside a gap of
    more than that many of its median steps), and whether the times were the same."""
    if len(t_acc) == len(t_gyro) and len(t_acc) > 1:
        step = float(np.median(np.diff(t_acc)))
        if np.max(np.abs(t_acc - t_gyro)) <= TIME_TOLERANCE * step:
            return X, np.ones(len(t_acc), bool), True
    x, xp = (t_acc - t_gyro[0]).astype(float), (t_gyro - t_gyro[0]).astype(float)
    ok = (x >= 0) & (x <= xp[-1])
    if gap_steps is not None:
        j = np.clip(np.searchsorted(xp, x), 1, len(xp) - 1)
        ok &= xp[j] - xp[j - 1] <= gap_steps * float(np.median(np.diff(xp)))
    return np.column_stack([np.interp(x, xp, X[:, k]) for k in range(X.shape[1])]), ok, False


def join(t_acc: np.ndarray, t_gyro: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """A gyroscope's samples ``W`` at the accelerometer's times (integer stamps, both increasing): as they are
    when the stamps agree within :data:`TIME_TOLERANCE` of a step, else linearly interpolated to the
    accelerometer's stamps inside the gyroscope's span (:func:`at_times`). Returns which accelerometer samples are
    kept, W at them, and how, in words."""
    if len(t_gyro) < 2:
        raise InputError(f"the gyroscope has {len(t_gyro)} sample(s); a calibration needs its samples throughout")
    Wi, keep, same = at_times(t_acc, t_gyro, W)
    if same:
        return keep, W, "at the same stamps"
    dropped = int((~keep).sum())
    out = f" ({dropped} accelerometer sample(s) outside the gyroscope's span dropped)" if dropped else ""
    return keep, Wi[keep], "interpolated linearly to the accelerometer's stamps" + out


def log_layout(samples: LogSamples) -> tuple[Layout, np.ndarray]:
    """The table of a log's samples (module docstring) and its :class:`~optcal.core.tablefile.Layout`, as
    :func:`optcal.core.recording.sniff.mat_layout` gives a MAT file's. Time is in seconds from the first sample,
    counted in the log's integer ticks before the one conversion to float (no rounding of absolute stamps)."""
    t = (samples.stamps - samples.stamps[0]) * samples.tick if len(samples.stamps) else np.zeros(0)
    names, cols = ["t", *ACC_NAMES], [t[:, None], samples.acc]
    if samples.gyro is not None:
        names += ["gx", "gy", "gz"]
        cols.append(samples.gyro)
    if samples.temp is not None:
        names.append("temp")
        cols.append(samples.temp[:, None])
    table = np.hstack(cols).astype(float, copy=False)
    return Layout(None, 0, len(names), (True,) * len(names), names, {}, []), table


def refuse_options(path, *, rate, labels, adc, time_unit) -> None:
    """The reading options a log has no use for are refused, each with its reason."""
    for value, name, why in ((rate, "rate", "its stamps give the times"),
                             (time_unit, "time_unit", "its stamps give the times"),
                             (labels, "labels", "it has no label column"),
                             (adc, "adc", "its samples are in m/s² and rad/s, not counts")):
        if value is not None:
            raise InputError(f"{path} is a robot or drone log: {why}; drop `{name}`")


def log_units(lay: Layout, cols: dict, units: str, path) -> str:
    """The units of the samples read in the roles ax, ay, az: m/s² when they are the accelerometer's columns
    (``units`` left at its default g, or m/s2; others refused: the message defines them), else (the gyroscope's
    columns read in those roles, as ``optcal noise`` does) ``units`` as given, a label."""
    if not all(lay.header[cols[a]] in ACC_NAMES for a in ACC_NAMES):
        return units
    if units not in ("g", "m/s2"):
        raise InputError(f"{path}: a log's accelerometer is in m/s², as its messages define it, not {units}; drop "
                         "`units` (or give m/s2)")
    return "m/s2"


def check_gyro_units(path, units: str) -> None:
    """A log's gyroscope is in rad/s, as its messages define it: other declared units are refused."""
    if units != "rad/s":
        raise InputError(f"{path}: a log's gyroscope is in rad/s, as its messages define it, not {units}; give "
                         "`gyro_units` rad/s")

