"""Reading robot logs (issue #33 asks for 1 hour of 200 Hz IMU messages from a bag in 3 s or less): 720,000
sensor_msgs/msg/Imu messages, with a 20 Hz topic of other messages between them, in a ROS 1 bag, a ROS 2 SQLite bag
and a ROS 2 MCAP bag written by rosbags' writers, read whole by optcal.core.recording.read_recording (open, decode,
sort, saturation check; what every command does first).

The bags are made once per storage in a temporary folder: one message is serialised by rosbags' typestore, the
720,000 are that message with its stamp and six values replaced (NumPy, at the offsets of its layout, checked
by deserialising messages back with rosbags), and rosbags' writer writes them. extra_info holds the seconds
of the fastest read, messages per second, the ratio to the 3 s asked for, and, when timing is on (make bench),
the CPU seconds of one more read (wall time on the shared machine depends on the other load) and the seconds of
rosbags' own message-by-message reading for comparison (the bulk paths of optcal.core.recording.bags switched off).
"""

from __future__ import annotations

import shutil
import time

import numpy as np
import pytest
import robot_logs_files as R

from optcal.core.recording import bags
from optcal.core.recording.reading import read_recording

N_HOUR = 720_000  # 1 hour at 200 Hz
TARGET_S = 3.0


def _messages(storage: str, t_ns: np.ndarray, acc: np.ndarray, gyro: np.ndarray) -> list[bytes]:
    """Imu messages at stamps ``t_ns`` with ``acc`` and ``gyro``: one serialised by rosbags, the rest made from it;
    the first, a middle one and the last deserialised again by rosbags to check them."""
    ts = R.typestore(storage)
    template = R.serialise(ts, storage, R.imu_message(ts, storage, 0, [0, 0, 0], [0, 0, 0]), R.IMU)
    n, L = len(t_ns), len(template)
    M = np.tile(np.frombuffer(template, np.uint8), (n, 1))
    head = 16 + len("imu_link") if storage == "ros1" else 4 + (12 + len("imu_link") + 1 + 7) // 8 * 8
    M[:, 4:8] = (t_ns // 10**9).astype("<u4").view(np.uint8).reshape(n, 4)
    M[:, 8:12] = (t_ns % 10**9).astype("<u4").view(np.uint8).reshape(n, 4)
    M[:, head + 8 * 13:head + 8 * 16] = gyro.astype("<f8").view(np.uint8).reshape(n, 24)
    M[:, head + 8 * 25:head + 8 * 28] = acc.astype("<f8").view(np.uint8).reshape(n, 24)
    raw = M.tobytes()
    out = [raw[i * L:(i + 1) * L] for i in range(n)]
    deser = ts.deserialize_ros1 if storage == "ros1" else ts.deserialize_cdr
    for i in (0, n // 2, n - 1):
        m = deser(out[i], R.IMU)
        assert m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == t_ns[i]
        assert [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] == acc[i].tolist()
        assert [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] == gyro[i].tolist()
    return out


def _timed(config) -> bool:
    """Whether this run times the benchmarks (``make bench``); under ``make test`` (timing disabled) each runs once
    as a test, on a minute of messages instead of an hour (the same paths, a sixtieth of the bags to write)."""
    return bool(config.getoption("benchmark_enable")) or not config.getoption("benchmark_disable")


@pytest.fixture(scope="module", params=R.STORAGES)
def hour_bag(request, tmp_path_factory):
    storage = request.param
    n = N_HOUR if _timed(request.config) else N_HOUR // 60
    rng = np.random.default_rng(0)
    t_ns = R.EPOCH_NS + np.arange(n, dtype=np.int64) * 5_000_000
    acc = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.standard_normal((n, 3))
    gyro = 0.001 * rng.standard_normal((n, 3))
    imu = list(zip(t_ns.tolist(), _messages(storage, t_ns, acc, gyro)))
    ts = R.typestore(storage)
    odom = R.serialise(ts, storage, R.vector_message(ts, storage, 0, [1.0, 2.0, 3.0]), R.VECTOR)
    other = [(s, odom) for s in t_ns[::10].tolist()]  # 20 Hz of another topic between the IMU's messages
    folder = tmp_path_factory.mktemp(storage)
    path = R.write_bag(folder / "hour", storage, {"/imu": (R.IMU, imu), "/odom": (R.VECTOR, other)})
    yield storage, path, acc, gyro
    shutil.rmtree(folder)  # 270 MB: not left for pytest's kept temporary folders


def test_bench_read_an_hour_of_imu_messages(benchmark, hour_bag):
    storage, path, acc, gyro = hour_bag
    rec = benchmark.pedantic(read_recording, args=(path,), rounds=3, iterations=1, warmup_rounds=0)
    n = len(acc)
    assert len(rec) == n and np.array_equal(rec.N, acc) and np.array_equal(rec.W, gyro)
    assert rec.rate == pytest.approx(200.0) and rec.duration == pytest.approx(n / 200.0 - 0.005)
    seconds = benchmark.stats.stats.min if benchmark.stats is not None else None
    info = {"storage": bags.FORMAT[storage], "messages": n, "seconds": seconds,
            "messages_per_s": None if seconds is None else n / seconds,
            "share_of_3_s_target": None if seconds is None else seconds / TARGET_S}
    if not benchmark.disabled:
        # the process's CPU time of one more read: on the shared machine, wall time depends on the other load
        c0 = time.process_time()
        read_recording(path)
        info["cpu_seconds"] = time.process_time() - c0
    if not benchmark.disabled and storage != "sqlite3":  # SQLite has no bulk path: rosbags' reader is its path
        mp = pytest.MonkeyPatch()
        for bulk in ("_ros1_rows", "_mcap_rows"):
            mp.setattr(bags, bulk, lambda *a: None)
        try:
            t0 = time.perf_counter()
            slow = read_recording(path)
            info["message_by_message_s"] = time.perf_counter() - t0
        finally:
            mp.undo()
        assert np.array_equal(slow.N, rec.N)
        info["speedup_of_bulk"] = info["message_by_message_s"] / seconds
    benchmark.extra_info.update(info)
