"""Robot and drone logs for the tests (issue #33), written without optcal's code: ROS bags by rosbags' own
writers with every message serialised by rosbags' typestores, and PX4 ULog files from the format's public
specification (docs.px4.io, "ULog File Format": a 16-byte header, then messages of a uint16 size, a uint8 type
and the payload; pyulog reads but does not create them). Imported by tests/test_robot_logs.py,
tests/test_bad_inputs_table.py and the read benchmark."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

IMU = "sensor_msgs/msg/Imu"
VECTOR = "geometry_msgs/msg/Vector3Stamped"
STORAGES = ("ros1", "sqlite3", "mcap")
SUFFIX = {"ros1": ".bag", "sqlite3": "", "mcap": ""}  # ROS 2 bags are folders
EPOCH_NS = 1_700_000_000 * 10**9  # stamps start at a 2023 date, as a robot's clock would


def typestore(storage: str):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if storage == "ros1" else Stores.ROS2_HUMBLE)


def imu_message(ts, storage, stamp_ns: int, acc, gyro, frame="imu_link", seq=0, no_gyro=False):
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9))
    header = (T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame) if storage == "ros1"
              else T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame))
    V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    cov = np.zeros(9)
    gcov = np.r_[-1.0, np.zeros(8)] if no_gyro else cov
    return T[IMU](header=header, orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.r_[-1.0,
                  np.zeros(8)], angular_velocity=V(x=float(gyro[0]), y=float(gyro[1]), z=float(gyro[2])),
                  angular_velocity_covariance=gcov,
                  linear_acceleration=V(x=float(acc[0]), y=float(acc[1]), z=float(acc[2])),
                  linear_acceleration_covariance=cov)


def vector_message(ts, storage, stamp_ns: int, v, frame="imu_link", seq=0):
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 10**9), nanosec=int(stamp_ns % 10**9))
    header = (T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame) if storage == "ros1"
              else T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame))
    return T[VECTOR](header=header, vector=T["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]),
                                                                          z=float(v[2])))


def serialise(ts, storage, msg, msgtype):
    return bytes(ts.serialize_ros1(msg, msgtype) if storage == "ros1" else ts.serialize_cdr(msg, msgtype))


def write_bag(path: Path, storage: str, topics: dict) -> Path:
    """A bag at ``path`` (+ its storage's suffix) in ``storage``: ``topics`` maps a name to (message type, a list
    of (bag stamp ns, serialised message)); messages are written in the order of their bag stamps."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    ts = typestore(storage)
    path = Path(str(path) + SUFFIX[storage])
    writer = (Writer1(path) if storage == "ros1" else
              Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP if storage == "mcap"
                      else StoragePlugin.SQLITE3))
    with writer:
        conns = {name: writer.add_connection(name, msgtype, typestore=ts) for name, (msgtype, _) in topics.items()}
        merged = sorted(((stamp, name, raw) for name, (_, msgs) in topics.items() for stamp, raw in msgs),
                        key=lambda m: m[0])
        for stamp, name, raw in merged:
            writer.write(conns[name], int(stamp), raw)
    return path


def imu_bag(path: Path, storage: str, t_ns, acc, gyro, topic="/imu", extra: dict | None = None, **kw) -> Path:
    """A bag of one Imu topic: stamps ``t_ns`` (int), ``acc`` (n, 3) m/s², ``gyro`` (n, 3) rad/s; ``extra`` topics
    as :func:`write_bag` takes them."""
    ts = typestore(storage)
    msgs = [(s, serialise(ts, storage, imu_message(ts, storage, s, a, g, seq=i, **kw), IMU))
            for i, (s, a, g) in enumerate(zip(t_ns, acc, gyro))]
    return write_bag(path, storage, {topic: (IMU, msgs), **(extra or {})})


def vector_topic(storage: str, t_ns, v) -> tuple[str, list]:
    ts = typestore(storage)
    return VECTOR, [(s, serialise(ts, storage, vector_message(ts, storage, s, x, seq=i), VECTOR))
                    for i, (s, x) in enumerate(zip(t_ns, v))]


# PX4's message formats as PX4's logger writes them (fields ordered by size, padding explicit)
FORMATS = {
    "sensor_combined": [("uint64_t", "timestamp"), ("float[3]", "gyro_rad"), ("uint32_t", "gyro_integral_dt"),
                        ("int32_t", "accelerometer_timestamp_relative"), ("float[3]", "accelerometer_m_s2"),
                        ("uint32_t", "accelerometer_integral_dt"), ("uint8_t", "accelerometer_clipping"),
                        ("uint8_t", "gyro_clipping"), ("uint8_t", "accel_calibration_count"),
                        ("uint8_t", "gyro_calibration_count")],
    "sensor_accel": [("uint64_t", "timestamp"), ("uint64_t", "timestamp_sample"), ("uint32_t", "device_id"),
                     ("float", "x"), ("float", "y"), ("float", "z"), ("float", "temperature"),
                     ("uint32_t", "error_count"), ("uint8_t[3]", "clip_counter"), ("uint8_t", "samples"),
                     ("uint8_t[4]", "_padding0")],
    "sensor_gyro": [("uint64_t", "timestamp"), ("uint64_t", "timestamp_sample"), ("uint32_t", "device_id"),
                    ("float", "x"), ("float", "y"), ("float", "z"), ("float", "temperature"),
                    ("uint32_t", "error_count"), ("uint8_t[3]", "clip_counter"), ("uint8_t", "samples"),
                    ("uint8_t[4]", "_padding0")],
    "vehicle_status": [("uint64_t", "timestamp"), ("uint8_t", "arming_state"), ("uint8_t[7]", "_padding0")],
}
_NP = {"uint64_t": "<u8", "int64_t": "<i8", "uint32_t": "<u4", "int32_t": "<i4", "uint16_t": "<u2",
       "uint8_t": "u1", "int8_t": "i1", "float": "<f4", "double": "<f8"}


def _dtype(fields):
    out = []
    for ty, name in fields:
        base, _, n = ty.partition("[")
        out.append((name, _NP[base], (int(n[:-1]),)) if n else (name, _NP[base]))
    return np.dtype(out)


def _message(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def write_ulog(path: Path, topics: dict, start_us: int = 0) -> Path:
    """A ULog at ``path``: ``topics`` maps (name, instance) to a dict of field arrays of :data:`FORMATS`' message
    ``name`` (fields left out are zero); data messages are written interleaved by timestamp."""
    out = [b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", start_us)]
    out.append(_message("B", bytes(16) + bytes(24)))  # flag bits: no compat or incompat flags, no appended data
    for name in sorted({n for n, _ in topics}):
        fmt = name + ":" + "".join(f"{ty} {field};" for ty, field in FORMATS[name])
        out.append(_message("F", fmt.encode()))
    key = b"char[9] sys_name"
    out.append(_message("I", bytes([len(key)]) + key + b"optcal-t\x00"))
    records = []
    for msg_id, ((name, instance), fields) in enumerate(sorted(topics.items())):
        out.append(_message("A", struct.pack("<BH", instance, msg_id) + name.encode()))
        fields_logged = list(FORMATS[name])
        while fields_logged[-1][1].startswith("_padding"):  # the spec: a message's trailing padding is not logged
            fields_logged.pop()
        dt = _dtype(fields_logged)
        n = len(fields["timestamp"])
        rec = np.zeros(n, np.dtype([("size", "<u2"), ("type", "u1"), ("id", "<u2"), ("p", dt)]))
        rec["size"], rec["type"], rec["id"] = 2 + dt.itemsize, ord("D"), msg_id
        for f, v in fields.items():
            rec["p"][f] = v
        raw = rec.tobytes()
        size = rec.dtype.itemsize
        records += [(int(ts), raw[i * size:(i + 1) * size]) for i, ts in enumerate(fields["timestamp"])]
    records.sort(key=lambda r: r[0])
    path.write_bytes(b"".join(out) + b"".join(r for _, r in records))
    return path
