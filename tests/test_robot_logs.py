"""Robot and drone logs (issue #33): ROS 1 bags, ROS 2 bags (SQLite and MCAP, the folder or its one file) and PX4
ULog read as raw recordings by every command through read_recording, round trips through files written by rosbags'
own writers (tests/robot_logs_files.py), a simulated 24-pose IMU recording calibrating to its CSV twin's
parameters in every format, calibrated bags written by optcal apply, and bad input refused in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest
import robot_logs_files as R
from conftest import run_cli

import optcal
from optcal.core.errors import InputError
from optcal.core.recording import bags
from optcal.core.recording.reading import read_recording

G0 = 9.80665
FORMATS = ("ros1", "sqlite3", "mcap", "ulog")


def _data(n=400, seed=0):
    rng = np.random.default_rng(seed)
    t_ns = R.EPOCH_NS + np.arange(n, dtype=np.int64) * 5_000_000 + rng.integers(0, 1000, n)  # 200 Hz, jittered
    acc = rng.normal(0, 0.1, (n, 3)) + [0.3, -0.2, 9.8]
    gyro = rng.normal(0, 0.05, (n, 3))
    return t_ns, acc, gyro


def _bare(path, storage):
    """A ROS 2 bag folder's one storage file."""
    return next(path.glob("*.mcap" if storage == "mcap" else "*.db3"))


def test_digests_are_rosbags_standard_definitions():
    """The digests a topic is checked against are what rosbags computes for the standard messages."""
    for msgtype in (bags.IMU, bags.VECTOR):
        assert R.typestore("ros1").generate_msgdef(msgtype)[1] == bags.MD5[msgtype]
        assert R.typestore("mcap").hash_rihs01(msgtype) == bags.RIHS01[msgtype]


@pytest.mark.parametrize("storage", R.STORAGES)
def test_round_trip_every_storage_gives_the_messages_values_at_their_stamps(tmp_path, storage):
    """Values, stamps and units exactly as written, whatever the other topics, from the bag and (ROS 2) from its
    one storage file; the reading says what was read."""
    t_ns, acc, gyro = _data()
    odom = R.vector_topic(storage, t_ns[::7], np.ones((len(t_ns[::7]), 3)))
    path = R.imu_bag(tmp_path / "b", storage, t_ns, acc, gyro, extra={"/odom": odom})
    for p in [path] + ([] if storage == "ros1" else [_bare(path, storage)]):
        rec = read_recording(p)
        assert np.array_equal(rec.N, acc) and np.array_equal(rec.W, gyro)
        assert np.array_equal(rec.t, (t_ns - t_ns[0]) * 1e-9)
        assert rec.units == "m/s2" and rec.temp is None
        assert rec.rate == pytest.approx(200.0, rel=1e-3)
        assert rec.reading["topic"] == "/imu" and rec.reading["time"] == "header stamps"
        assert rec.reading["first_stamp_ns"] == int(t_ns[0])
        assert rec.reading["format"].startswith(bags.FORMAT[storage])


@pytest.mark.parametrize("storage", ("ros1", "mcap"))
def test_bulk_reading_equals_message_by_message(tmp_path, storage, monkeypatch):
    """The bulk paths (rosbags' index and NumPy gathers) give what rosbags' reader gives one message at a time,
    on a bag whose messages differ in length (frame_id) and whose stamps are out of order; ROS 1 compressed
    chunks (LZ4, BZ2) too."""
    from rosbags.rosbag1 import Writer

    t_ns, acc, gyro = _data(900, seed=1)
    ts = R.typestore(storage)
    frames = ["imu", "imu_link", "base_imu_frame"]
    msgs = [(int(t_ns[i]), R.serialise(ts, storage, R.imu_message(ts, storage, int(t_ns[i]), acc[i], gyro[i],
                                                                      frame=frames[i % 3], seq=i), R.IMU))
            for i in range(len(t_ns))]
    msgs[10], msgs[11] = (msgs[11][0], msgs[10][1]), (msgs[10][0], msgs[11][1])  # recorded out of stamp order
    paths = [R.write_bag(tmp_path / "b", storage, {"/imu": (R.IMU, msgs)})]
    if storage == "ros1":
        for fmt in (Writer.CompressionFormat.LZ4, Writer.CompressionFormat.BZ2):
            p = tmp_path / f"{fmt.name}.bag"
            w = Writer(p)
            w.set_compression(fmt)
            with w:
                c = w.add_connection("/imu", R.IMU, typestore=ts)
                for s, raw in sorted(msgs, key=lambda m: m[0]):
                    w.write(c, s, raw)
            paths.append(p)
    for p in paths:
        fast = read_recording(p)
        assert np.array_equal(fast.N, acc) and np.array_equal(fast.W, gyro)
        with monkeypatch.context() as m:
            m.setattr(bags, "_ros1_rows", lambda *a: None)
            m.setattr(bags, "_mcap_rows", lambda *a: None)
            slow = read_recording(p)
        assert np.array_equal(fast.t, slow.t) and np.array_equal(fast.N, slow.N) and np.array_equal(fast.W, slow.W)


def test_big_endian_cdr_reads_as_little_endian(tmp_path):
    """CDR messages serialised big-endian (rosbags' serialize_cdr, little_endian=False) give the same samples."""
    t_ns, acc, gyro = _data(50)
    ts = R.typestore("sqlite3")
    msgs = [(int(s), bytes(ts.serialize_cdr(R.imu_message(ts, "sqlite3", int(s), a, g), R.IMU, little_endian=False)))
            for s, a, g in zip(t_ns, acc, gyro)]
    assert msgs[0][1][1] == 0  # the encapsulation says big-endian
    src = R.write_bag(tmp_path / "b", "sqlite3", {"/imu": (R.IMU, msgs)})
    rec = read_recording(src)
    assert np.array_equal(rec.N, acc) and np.array_equal(rec.W, gyro)
    assert np.array_equal(rec.t, (t_ns - t_ns[0]) * 1e-9)
    # written back in their own byte order, the new values in place (the writer under optcal apply)
    bags.write_calibrated(src, tmp_path / "out", topic=None, t0_ns=int(t_ns[0]), acc=lambda t, N: 2 * N + t[:, None],
                          gyro=lambda t, W, A: W - A)
    out = read_recording(tmp_path / "out")
    t = (t_ns - t_ns[0]) * 1e-9
    assert np.array_equal(out.N, 2 * acc + t[:, None]) and np.array_equal(out.W, gyro - out.N)
    assert all(raw[1] == 0 for raw in _messages(tmp_path / "out")["/imu"])


@pytest.mark.parametrize("storage", ("ros1", "mcap"))
def test_a_topic_of_another_definition_is_refused(tmp_path, storage):
    """A topic recorded as sensor_msgs/msg/Imu with a definition whose digest is not the standard one (an MD5 sum,
    ROS 1; a type hash, ROS 2) is refused, naming it."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    t_ns, acc, gyro = _data(20)
    ts = R.typestore(storage)
    path = tmp_path / ("b.bag" if storage == "ros1" else "b")
    msgdef = ts.generate_msgdef(R.IMU, ros_version=1 if storage == "ros1" else 2)[0]
    writer = Writer1(path) if storage == "ros1" else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    with writer:
        c = (writer.add_connection("/imu", R.IMU, msgdef=msgdef, md5sum="0" * 32) if storage == "ros1" else
             writer.add_connection("/imu", R.IMU, msgdef=msgdef, rihs01="RIHS01_" + "0" * 64))
        for s, a, g in zip(t_ns, acc, gyro):
            writer.write(c, int(s), R.serialise(ts, storage, R.imu_message(ts, storage, int(s), a, g), R.IMU))
    with pytest.raises(InputError, match=r"topic /imu's sensor_msgs/msg/Imu is not the standard definition"):
        read_recording(path)


def test_header_stamps_unset_are_replaced_by_the_bags(tmp_path):
    t_ns, acc, gyro = _data(300)
    ts = R.typestore("mcap")
    msgs = [(int(s), R.serialise(ts, "mcap", R.imu_message(ts, "mcap", 0, a, g), R.IMU))
            for s, a, g in zip(t_ns, acc, gyro)]
    rec = read_recording(R.write_bag(tmp_path / "b", "mcap", {"/imu": (R.IMU, msgs)}))
    assert np.array_equal(rec.t, (t_ns - t_ns[0]) * 1e-9) and np.array_equal(rec.N, acc)
    assert rec.reading["time"].startswith("the bag's receive stamps")


@pytest.mark.parametrize("storage", ("ros1", "sqlite3"))
def test_separate_topics_joined_as_they_are_or_interpolated(tmp_path, storage):
    """An accelerometer and a gyroscope on topics of their own: Vector3Stamped topics named accel and gyro are
    found without --topic and, at the same stamps, joined as they are; a gyroscope at twice the rate (Imu
    messages, as a RealSense camera records them) is interpolated linearly to the accelerometer's stamps."""
    t_ns, acc, gyro = _data(200)
    same = R.write_bag(tmp_path / "same", storage, {"/imu/accel": R.vector_topic(storage, t_ns, acc),
                                                    "/imu/gyro": R.vector_topic(storage, t_ns, gyro)})
    rec = read_recording(same)
    assert np.array_equal(rec.N, acc) and np.array_equal(rec.W, gyro)
    assert rec.reading["gyroscope_topic"] == "/imu/gyro" and "at the same stamps" in rec.reading["gyroscope"]
    tg = t_ns[0] + np.arange(2 * len(t_ns) + 3) * 2_500_000 - 1_000_000  # 400 Hz, starting 1 ms earlier
    W = np.column_stack([np.sin(tg * 1e-9), np.cos(tg * 1e-9), 0.01 * np.arange(len(tg))])
    ts = R.typestore(storage)
    gmsgs = [(int(s), R.serialise(ts, storage, R.imu_message(ts, storage, int(s), [0, 0, 0], w), R.IMU))
             for s, w in zip(tg, W)]
    amsgs = [(int(s), R.serialise(ts, storage, R.imu_message(ts, storage, int(s), a, [0, 0, 0], no_gyro=True),
                                  R.IMU)) for s, a in zip(t_ns, acc)]
    two = R.write_bag(tmp_path / "two", storage, {"/cam/accel/sample": (R.IMU, amsgs),
                                                  "/cam/gyro/sample": (R.IMU, gmsgs)})
    with pytest.raises(InputError, match="holds 2 IMU topics"):
        read_recording(two)
    rec = read_recording(two, topic="/cam/accel/sample,/cam/gyro/sample")
    keep = t_ns <= tg[-1]
    expect = np.column_stack([np.interp((t_ns[keep] - tg[0]).astype(float), (tg - tg[0]).astype(float), W[:, j])
                              for j in range(3)])
    assert np.array_equal(rec.N, acc[keep]) and np.allclose(rec.W, expect, rtol=0, atol=1e-12)
    assert "interpolated linearly" in rec.reading["gyroscope"]
    # the accelerometer's Imu messages mark angular_velocity absent: alone, they are an accelerometer only
    assert read_recording(two, topic="/cam/accel/sample").W is None


def test_ulog_sources_sensor_combined_and_raw_sensors(tmp_path):
    """sensor_combined; sensor_accel with sensor_gyro of the same instance (timestamp_sample, temperature); a
    log holding both is refused without --topic, naming them with their rates."""
    t_ns, acc, gyro = _data(300)
    us = (t_ns - R.EPOCH_NS) // 1000 + 10_000
    a32, g32 = acc.astype(np.float32), gyro.astype(np.float32)
    combined = {"timestamp": us, "accelerometer_m_s2": a32, "gyro_rad": g32}
    raw = {"timestamp": us + 200, "timestamp_sample": us, "x": a32[:, 0], "y": a32[:, 1], "z": a32[:, 2],
           "temperature": np.full(len(us), 31.5, np.float32)}
    graw = {**raw, "x": g32[:, 0], "y": g32[:, 1], "z": g32[:, 2]}
    one = R.write_ulog(tmp_path / "one.ulg", {("sensor_combined", 0): combined, ("vehicle_status", 0):
                                              {"timestamp": us[::10]}})
    rec = read_recording(one)
    assert np.array_equal(rec.N, a32) and np.array_equal(rec.W, g32) and rec.units == "m/s2"
    assert np.array_equal(rec.t, (us - us[0]) * 1e-6) and rec.reading["topic"] == "sensor_combined"
    both = R.write_ulog(tmp_path / "both.ulg", {("sensor_combined", 0): combined, ("sensor_accel", 0): raw,
                                                ("sensor_gyro", 0): graw, ("sensor_accel", 1): raw})
    with pytest.raises(InputError, match=r"holds 3 IMU sources: sensor_combined \(300 samples, 200 Hz\)"):
        read_recording(both)
    rec = read_recording(both, topic="sensor_accel")
    assert np.array_equal(rec.N, a32) and np.array_equal(rec.W, g32) and np.all(rec.temp == 31.5)
    assert rec.reading["time"] == "timestamp_sample" and "at the same stamps" in rec.reading["gyroscope"]
    assert read_recording(both, topic="sensor_accel:1").W is None


# --- the simulated 24-pose IMU recording and its CSV twin ------------------------------------------------------


@pytest.fixture(scope="module")
def twins(tmp_path_factory):
    """A simulated 24-pose IMU recording (optcal.core.gyro.simulate_imu: rests of 3 s, motions of 2 s, 100 Hz; the
    accelerometer with scale factors and offsets, in m/s²; a gyroscope of unit nominal scale, in rad/s) written as a
    ROS 1 bag, ROS 2 SQLite and MCAP bags and a ULog, each with its CSV twin holding the same numbers (the
    ULog's float32 values, its microsecond times) in the columns t, ax..az, gx..gz."""
    from optcal.core.gyro import draw_truth, get_gyro_model, simulate_imu

    d = tmp_path_factory.mktemp("twins")
    rng = np.random.default_rng(33)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1.0)
    D = simulate_imu(model, x, poses=24, rest_s=3.0, rng=rng).data
    acc = D.F * G0 * (1 + np.array([0.01, -0.02, 0.015])) + np.array([0.1, -0.05, 0.2])
    t_ns = R.EPOCH_NS + np.round(D.t * 1e9).astype(np.int64)
    out = {}
    for fmt in FORMATS:
        if fmt == "ulog":
            us = (t_ns - R.EPOCH_NS) // 1000 + 5_000_000
            A, W = acc.astype(np.float32), D.W.astype(np.float32)
            path = R.write_ulog(d / "imu.ulg", {("sensor_combined", 0): {"timestamp": us, "accelerometer_m_s2": A,
                                                                         "gyro_rad": W}})
            t = (us - us[0]) * 1e-6
        else:
            A, W = acc, D.W
            path = R.imu_bag(d / f"imu_{fmt}", fmt, t_ns, A, W)
            t = (t_ns - t_ns[0]) * 1e-9
        twin = d / f"twin_{fmt}.csv"
        np.savetxt(twin, np.column_stack([t, A, W]), delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="",
                   fmt="%.17g")
        out[fmt] = (path, twin)
    return out, x


def _params(block):
    return np.array(list(block["parameters"].values()))


@pytest.mark.parametrize("fmt", FORMATS)
def test_calibrate_raw_gives_the_csv_twins_parameters(twins, fmt, capsys):
    path, twin = twins[0][fmt]
    code, log, err = run_cli(["calibrate", path, "--raw", "--json"], capsys)
    assert code == 0, err
    code, csv, err = run_cli(["calibrate", twin, "--raw", "--units", "m/s2", "--json"], capsys)
    assert code == 0, err
    a, b = json.loads(log), json.loads(csv)
    assert a["model"] == b["model"] == "nonlinear12" and list(a["parameters"]) == list(b["parameters"])
    np.testing.assert_allclose(_params(a), _params(b), rtol=1e-9, atol=0)
    # and they are the sensor's: scale factors of 1 g in m/s² times (1 + 1 %, -2 %, 1.5 %)
    K = np.array([a["parameters"][f"K_{k}"] for k in "xyz"])
    np.testing.assert_allclose(K, G0 * np.array([1.01, 0.98, 1.015]), rtol=2e-4)


@pytest.mark.parametrize("fmt", FORMATS)
def test_imu_gives_the_csv_twins_parameters(twins, fmt, capsys):
    """optcal imu on the log (its gyroscope found with its accelerometer, in the rad/s the log defines: neither
    --gyro-columns nor --gyro-units) and on the twin (the gyroscope's columns those its header names): both
    sensors' parameters to 1e-9, the gyroscope's near the truth."""
    path, twin = twins[0][fmt]
    x = twins[1]
    code, log, err = run_cli(["imu", path, "--model", "linear9", "--json"], capsys)
    assert code == 0, err
    code, csv, err = run_cli(["imu", twin, "--units", "m/s2", "--gyro-units", "rad/s", "--model", "linear9", "--json"],
                             capsys)
    assert code == 0, err
    a, b = json.loads(log), json.loads(csv)
    for sensor in ("accelerometer", "gyroscope"):
        np.testing.assert_allclose(_params(a[sensor]), _params(b[sensor]), rtol=1e-9, atol=0)
    g = a["gyroscope"]
    assert abs(g["parameters"]["K_x"] - x[0]) < 4 * g["stderr"]["K_x"]


def test_discover_reads_a_log_as_the_twin(twins, capsys):
    path, twin = twins[0]["ulog"]
    code, log, err = run_cli(["discover", path, "--raw", "--base", "linear9", "--json"], capsys)
    assert code == 0, err
    code, csv, err = run_cli(["discover", twin, "--raw", "--units", "m/s2", "--base", "linear9", "--json"], capsys)
    assert code == 0, err
    assert json.loads(log) == json.loads(csv)


def test_noise_and_the_python_api_read_logs_as_the_twin(twins, capsys):
    path, twin = twins[0]["mcap"]
    code, log, err = run_cli(["noise", path, "--interval", "0:3", "--gyro-units", "rad/s", "--json"], capsys)
    assert code == 0, err
    code, csv, err = run_cli(["noise", twin, "--units", "m/s2", "--interval", "0:3", "--gyro-units", "rad/s",
                              "--gyro-columns", "gx,gy,gz", "--json"], capsys)
    assert code == 0, err
    a, b = json.loads(log), json.loads(csv)
    assert a["axes"] == b["axes"] and a["gyroscope"]["axes"] == b["gyroscope"]["axes"]
    cal_log = optcal.calibrate(path, raw=True, topic="/imu")
    cal_csv = optcal.calibrate(twin, raw=True, units="m/s2")
    np.testing.assert_allclose(cal_log.x, cal_csv.x, rtol=1e-9, atol=0)
    assert np.array_equal(optcal.read_recording(path).N, optcal.read_recording(twin, units="m/s2").N)
    assert optcal.noise(path, interval=(0, 3)).to_dict()["axes"] == \
        optcal.noise(twin, units="m/s2", interval=(0, 3)).to_dict()["axes"]


# --- optcal apply: a calibrated bag -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def imu_file(twins, tmp_path_factory):
    path, _ = twins[0]["ros1"]
    out = tmp_path_factory.mktemp("cal") / "imu.json"
    from optcal.app.cli import main

    assert main(["imu", str(path), "--gyro-units", "rad/s", "--model", "linear9", "-o", str(out)]) == 0
    return out


@pytest.mark.parametrize("storage", R.STORAGES)
def test_apply_writes_a_calibrated_bag_of_the_same_storage(tmp_path, storage, imu_file, capsys):
    """Every Imu message's linear_acceleration is the calibration applied to it in m/s² and its angular_velocity
    the gyroscope's in rad/s; every other byte of every message, and every other topic, as it was; on a new
    topic the originals stay. A ROS 2 bag's one .mcap/.db3 file gives one file."""
    from optcal.core.calfile import read_calibration
    from optcal.core.gyro.calfile import read_gyro_block

    t_ns, acc, gyro = _data(600)
    odom = R.vector_topic(storage, t_ns[::5], np.arange(3 * len(t_ns[::5])).reshape(-1, 3))
    src = R.imu_bag(tmp_path / "in", storage, t_ns, acc, gyro, extra={"/odom": odom})
    out = tmp_path / f"out{R.SUFFIX[storage]}"
    code, text, err = run_cli(["apply", imu_file, src, "-o", out], capsys)
    assert code == 0, err
    assert f"wrote {out} ({bags.FORMAT[storage]})" in text
    cal = read_calibration(imu_file)
    gcal = read_gyro_block(cal.meta, imu_file)
    rec = read_recording(out)
    t = (t_ns - t_ns[0]) * 1e-9
    np.testing.assert_allclose(rec.N, cal.apply(acc, t=t) * G0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rec.W, gcal.apply(gyro), rtol=1e-12, atol=1e-15)
    assert np.array_equal(rec.t, t)
    before, after = _messages(src), _messages(out)
    assert before["/odom"] == after["/odom"]
    for a, b in zip(before["/imu"], after["/imu"]):  # only the two vectors' 48 bytes differ
        assert len(a) == len(b) and sum(x != y for x, y in zip(a, b)) <= 48
    new = tmp_path / f"new{R.SUFFIX[storage]}"
    code, text, err = run_cli(["apply", imu_file, src, "-o", new, "--output-topic", "/imu/calibrated"], capsys)
    assert code == 0, err
    m = _messages(new)
    assert m["/imu"] == before["/imu"] and m["/imu/calibrated"] == after["/imu"]
    if storage != "ros1":
        one = tmp_path / f"one{_bare(src, storage).suffix}"
        code, text, err = run_cli(["apply", imu_file, _bare(src, storage), "-o", one], capsys)
        assert code == 0, err
        assert one.is_file() and _messages(one) == after
    # a table as before, for a name ending .csv
    code, text, err = run_cli(["apply", imu_file, src, "-o", tmp_path / "out.csv", "--output-units", "m/s2"], capsys)
    assert code == 0, err
    table = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1:4], rec.N, rtol=1e-9)


def test_apply_to_a_ulog_writes_a_table(twins, imu_file, tmp_path, capsys):
    from optcal.core.calfile import read_calibration

    path, _ = twins[0]["ulog"]
    out = tmp_path / "flight.csv"
    code, text, err = run_cli(["apply", imu_file, path, "-o", out, "--output-units", "m/s2"], capsys)
    assert code == 0, err
    rec = read_recording(path)
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1:4], read_calibration(imu_file).apply(rec.N, t=rec.t) * G0, rtol=1e-9)
    assert open(out).readline().strip() == "t,ax,ay,az,wx,wy,wz"


def _messages(path):
    """Topic → serialised messages in the bag's order (rosbags' reader)."""
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2

    out: dict = {}
    with (Reader1 if str(path).endswith(".bag") else Reader2)(path) as r:
        for c, _, raw in r.messages():
            out.setdefault(c.topic, []).append(bytes(raw))
    return out


def test_apply_replaces_a_bag_folder_only_with_force(tmp_path, imu_file, capsys):
    t_ns, acc, gyro = _data(300)
    src = R.imu_bag(tmp_path / "in", "mcap", t_ns, acc, gyro)
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    code, _, err = run_cli(["apply", imu_file, src, "-o", out], capsys)
    assert code == 2 and "--force" in err and (out / "old.txt").exists()
    code, _, err = run_cli(["apply", imu_file, src, "-o", out, "--force"], capsys)
    assert code == 0, err
    assert not (out / "old.txt").exists() and len(read_recording(out)) == 300
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out"]  # no temporary folder left


# --- bad input: one line, exit status 2 -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    t_ns, acc, gyro = _data(300)
    ts = R.typestore("ros1")
    chatter = [(int(s), R.serialise(ts, "ros1", ts.types["std_msgs/msg/String"](data="hello"), "std_msgs/msg/String"))
               for s in t_ns[::10]]
    files = {"noimu": R.write_bag(d / "noimu", "ros1", {"/chatter": ("std_msgs/msg/String", chatter)}),
             "two": R.imu_bag(d / "two", "ros1", t_ns, acc, gyro, topic="/imu0",
                              extra={"/imu1": (R.IMU, [(int(s), R.serialise(ts, "ros1", R.imu_message(
                                  ts, "ros1", int(s), a, g), R.IMU)) for s, a, g in zip(t_ns, acc, gyro)])}),
             "ok": R.imu_bag(d / "ok", "ros1", t_ns, acc, gyro, extra={"/chatter": ("std_msgs/msg/String", chatter)})}
    cut = d / "cut.bag"
    cut.write_bytes(files["ok"].read_bytes()[: files["ok"].stat().st_size // 2])
    files["cut"] = cut
    mcap = R.imu_bag(d / "m", "mcap", t_ns, acc, gyro)
    files["mcap"] = mcap
    cutm = d / "cut.mcap"
    cutm.write_bytes(_bare(mcap, "mcap").read_bytes()[:5000])
    files["cut_mcap"] = cutm
    ulog = R.write_ulog(d / "x.ulg", {("sensor_combined", 0): {"timestamp": np.arange(300) * 5000,
                                                             "accelerometer_m_s2": acc.astype(np.float32)}})
    cutu = d / "cut.ulg"
    cutu.write_bytes(ulog.read_bytes()[:12])
    files["cut_ulog"] = cutu
    files["ulog"] = ulog
    # an Imu topic whose messages are not the standard Imu's (a message of another definition under its name)
    odd = [(int(s), R.serialise(ts, "ros1", R.vector_message(ts, "ros1", int(s), a), R.VECTOR)) for s, a in
           zip(t_ns, acc)]
    files["odd"] = R.write_bag(d / "odd", "ros1", {"/imu": (R.IMU, odd)})
    (d / "rec.csv").write_text("t,ax,ay,az\n" + "\n".join(f"{i / 100},0,0,1" for i in range(50)) + "\n")
    files["csv"] = d / "rec.csv"
    return files


CASES = [
    (["calibrate", "{noimu}", "--raw"], "holds no IMU messages (sensor_msgs/msg/Imu or geometry_msgs/msg/"
     "Vector3Stamped; its topics: /chatter (std_msgs/msg/String))"),
    (["calibrate", "{two}", "--raw"], "holds 2 IMU topics (/imu0, /imu1); pick one with --topic"),
    (["imu", "{two}", "--gyro-units", "rad/s"], "holds 2 IMU topics (/imu0, /imu1)"),
    (["calibrate", "{cut}", "--raw"], "as a ROS 1 bag: Bag index looks damaged"),
    (["noise", "{cut_mcap}"], "as a ROS 2 bag (MCAP)"),
    (["calibrate", "{cut_ulog}", "--raw"], "as a PX4 ULog: Invalid file format (Header too short)"),
    (["noise", "{ok}", "--topic", "/chatter"], "topic /chatter carries std_msgs/msg/String, not an IMU's message; "
     "give a topic of sensor_msgs/msg/Imu or geometry_msgs/msg/Vector3Stamped with --topic (here: /imu (Imu))"),
    (["calibrate", "{ok}", "--raw", "--topic", "/nope"], "has no topic /nope; its IMU topics: /imu (Imu)"),
    (["calibrate", "{odd}", "--raw"], "message 0 of /imu is not a well-formed sensor_msgs/msg/Imu"),
    (["calibrate", "{ok}", "--raw", "--units", "counts"], "a log's accelerometer is in m/s²"),
    (["calibrate", "{ok}", "--raw", "--rate", "100"], "its stamps give the times; drop --rate"),
    (["calibrate", "{csv}", "--raw", "--topic", "/imu"], "is neither: drop --topic"),
    (["calibrate", "{ok}"], "looks like a raw recording, not a positions file (it is a ROS bag"),
    (["imu", "{ok}", "--gyro-units", "deg/s"], "a log's gyroscope is in rad/s"),
    (["noise", "{ok}", "--gyro-units", "deg/s"], "a log's gyroscope is in rad/s"),
    (["calibrate", "{ulog}", "--raw", "--topic", "sensor_accel"], "has no IMU source 'sensor_accel'"),
]


@pytest.mark.parametrize("argv, fragment", CASES, ids=[f"{c[0][0]}-{c[0][1].strip('{}')}-{i}"
                                                       for i, c in enumerate(CASES)])
def test_bad_logs_are_one_line_and_exit_2(bad, argv, fragment, capsys):
    code, out, err = run_cli([a.format(**bad) for a in argv], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and len(lines[0]) <= 300, err
    assert "Traceback" not in err and fragment in lines[0], lines[0]


def test_apply_refuses_what_it_cannot_write(bad, tmp_path, imu_file, capsys):
    for argv, fragment in (
            (["apply", imu_file, bad["ulog"], "-o", tmp_path / "x.ulg"], "as a table, not a ULog"),
            (["apply", imu_file, bad["ok"], "-o", tmp_path / "x.bag", "--output-topic", "/chatter"],
             "has that topic already"),
            (["apply", imu_file, bad["ok"], "-o", tmp_path / "x.csv", "--output-topic", "/new"],
             "drop --output-topic"),
            (["apply", imu_file, bad["ok"], "-o", tmp_path / "x.bag", "--output-topic", "new"], "starting with /"),
            (["apply", imu_file, bad["ok"], "-o", tmp_path / "x.mcap"], "would change the bag's storage (ROS 1 bag)"),
            (["apply", imu_file, bad["mcap"], "-o", tmp_path / "x.db3"], "name it .mcap or a folder")):
        code, out, err = run_cli(argv, capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and fragment in err, err
    assert list(tmp_path.iterdir()) == []
