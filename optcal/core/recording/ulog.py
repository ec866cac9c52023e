"""PX4 ULog flight logs as raw recordings (issue #33), read with pyulog.

**What is read.** ``sensor_combined`` (``accelerometer_m_s2`` in m/s², ``gyro_rad`` in rad/s, timed by its
``timestamp``, µs: PX4's primary IMU, already corrected by the calibration PX4 holds in its parameters), or one
sensor's raw messages, ``sensor_accel`` (``x, y, z`` in m/s², ``temperature`` in °C) with the ``sensor_gyro``
of the same instance (``x, y, z`` in rad/s), each timed by ``timestamp_sample`` (µs; ``timestamp`` in logs
without it). Each source is a topic for `topic`: ``sensor_combined``, ``sensor_accel`` (instance 0) or
``sensor_accel:N``. A log that holds one of them is read from it; one that holds several (sensor_combined and
a raw sensor logged at full rate, or several IMUs) is refused in one line listing them with their rates, so that
the choice, calibrated by PX4 or not, is the user's. The gyroscope is joined to the accelerometer's stamps as a
ROS bag's separate topics are (:func:`optcal.core.recording.robotlogs.join`).

pyulog reads a log cut short up to its last whole message (a flight's log often ends so) and prints what it
finds damaged on standard output: that output is caught, and the damage said in
:attr:`~optcal.core.recording.Recording.reading`.
"""

from __future__ import annotations

import io
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError, listing
from optcal.core.recording.robotlogs import LogSamples, join, sort_stamps

COMBINED = "sensor_combined"
ACCEL, GYRO = "sensor_accel", "sensor_gyro"
TICK = 1e-6  # ULog's timestamps are microseconds


def _load(path: Path, names):
    from pyulog import ULog

    caught = io.StringIO()
    try:
        with redirect_stdout(caught):
            ulog = ULog(str(path), names, True)
    except Exception as exc:  # noqa: BLE001 - pyulog raises ULogException, struct and index errors on damage
        said = (str(exc).splitlines() or [type(exc).__name__])[0].rstrip(".") or type(exc).__name__
        raise InputError(f"cannot read {path} as a PX4 ULog: {said}; is it a whole .ulg file?") from None
    return ulog


def _stamps(d) -> np.ndarray:
    key = "timestamp_sample" if "timestamp_sample" in d.data else "timestamp"
    return d.data[key].astype(np.int64)


def _xyz(d, stem: str) -> np.ndarray:
    keys = [f"{stem}[{j}]" for j in range(3)] if stem else ["x", "y", "z"]
    return np.column_stack([d.data[k] for k in keys]).astype(float)


def _rate(d) -> float:
    t = _stamps(d)
    return 1.0 / (float(np.median(np.diff(t))) * TICK) if len(t) > 1 else float("nan")


def _logged(ulog) -> list[str]:
    """The log's message formats that are topics (not only nested in another)."""
    nested = {ty for f in ulog.message_formats.values() for ty, _, _ in f.fields}
    return sorted(n for n in ulog.message_formats if n not in nested)


def read_ulog(path, topic: str | None = None) -> LogSamples:
    """The IMU samples of the ULog ``path`` (module docstring) from ``topic`` (``sensor_combined``,
    ``sensor_accel`` or ``sensor_accel:N``; default the log's one source)."""
    path = Path(path)
    ulog = _load(path, [COMBINED, ACCEL, GYRO])
    data = {(d.name, d.multi_id): d for d in ulog.data_list if len(d.data.get("timestamp", ())) > 0}
    sources = {COMBINED: data[COMBINED, 0]} if (COMBINED, 0) in data else {}
    sources.update({f"{ACCEL}:{k}": d for (name, k), d in sorted(data.items()) if name == ACCEL})
    said = listing(f"{s} ({len(_stamps(d))} samples, {_rate(d):.4g} Hz)" for s, d in sources.items())
    if topic is None:
        if not sources:
            raise InputError(f"{path} holds no IMU messages ({COMBINED}, {ACCEL}; its messages: "
                             f"{listing(_logged(ulog)) or 'none'}); log the IMU (SDLOG_PROFILE) or read another file")
        if len(sources) > 1:
            raise InputError(f"{path} holds {len(sources)} IMU sources: {said}; pick one with `topic` "
                             f"({COMBINED} is calibrated by PX4, {ACCEL} raw)")
        name = next(iter(sources))
    else:
        name = str(topic).strip()
        name = f"{ACCEL}:0" if name == ACCEL else name
        if name not in sources:
            raise InputError(f"{path} has no IMU source {topic!r}; its sources: {said or 'none'} (give one with "
                             "`topic`)")
    d = sources[name]
    t = _stamps(d)
    order = sort_stamps(t, path, name, TICK)
    t = t[order]
    how = {"topic": name, "time": "timestamp_sample" if "timestamp_sample" in d.data else "timestamp"}
    temp = None
    if name == COMBINED:
        A, W = _xyz(d, "accelerometer_m_s2")[order], _xyz(d, "gyro_rad")[order]
        how["gyroscope"] = f"{COMBINED}'s gyro_rad (rad/s)"
    else:
        k = int(name.split(":")[1])
        A, W = _xyz(d, "")[order], None
        if "temperature" in d.data and np.all(np.isfinite(d.data["temperature"])):
            temp = d.data["temperature"].astype(float)[order]
        g = data.get((GYRO, k))
        if g is not None:
            tg = _stamps(g)
            og = sort_stamps(tg, path, f"{GYRO}:{k}", TICK)
            keep, W, joined = join(t, tg[og], _xyz(g, "")[og])
            t, A, temp = t[keep], A[keep], None if temp is None else temp[keep]
            how["gyroscope"] = f"{GYRO}:{k} (rad/s), {joined}"
    how["format"] = f"PX4 ULog, {name}, {how['time']} (µs)"
    if ulog.file_corruption:
        how["damage"] = "pyulog found damaged data and skipped it"
    if len(t):
        how["first_stamp_us"] = int(t[0])
    return LogSamples(t, TICK, A, W, temp, how)
