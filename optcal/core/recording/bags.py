"""ROS bags as raw recordings (issue #33): ROS 1 ``.bag`` files and ROS 2 bags (the folder ``ros2 bag`` writes, or
its ``.db3`` or ``.mcap`` file: SQLite and MCAP storage), read and written with rosbags, without a ROS
installation.

**What is read.** ``sensor_msgs/msg/Imu`` (``linear_acceleration`` in m/s², ``angular_velocity`` in rad/s, as the
message defines them; a field whose covariance's first element is -1 in every message is absent, as the
message's comment says), or ``geometry_msgs/msg/Vector3Stamped`` when the accelerometer and the gyroscope come
on topics of their own (``--topic ACC,GYRO``; without ``--topic``, the two ``Vector3Stamped`` topics whose names
say accel and gyro). Each sample's time is its header's stamp; a topic whose stamps are all zero (a driver
that leaves them unset) is timed by the bag's receive stamps, and says so. A gyroscope on another topic is
joined to the accelerometer's stamps: taken as it is when both topics have the same stamps (within a tenth of a
step), else interpolated linearly to them (the accelerometer's samples outside the gyroscope's span dropped).

**How.** The fields are taken from the messages' serialised bytes with NumPy instead of a Python object per
message (:func:`decode`): both message types are a header (stamp and ``frame_id``) followed by a fixed number of
float64, so a message's fields lie at an offset set by the length of its ``frame_id`` (ROS 1: packed; ROS 2's
CDR: aligned to 8 bytes after the 4-byte encapsulation header, little- or big-endian), and messages of one
length and one ``frame_id`` length, which a topic's are, are one reshaped array. The bytes come in bulk where
rosbags has located them: a ROS 1 bag's and an MCAP file's index gives each message's place in its chunk, and
each chunk is decompressed once (:func:`_ros1_rows`, :func:`_mcap_rows`); otherwise (SQLite, an MCAP file
without index) from rosbags' reader, a batch at a time. A topic whose recorded definition differs from the
standard one (its MD5 sum, ROS 1, or type hash, ROS 2) or whose messages have another length is refused. The
speed against rosbags' own deserialiser: docs/real_data.md (tests/benchmarks/test_robot_logs_read.py).

**Out.** :func:`write_calibrated` copies a bag into a new one of the same storage with the IMU's messages
calibrated: their bytes with the accelerometer's (and gyroscope's) three float64 replaced, everything else
(stamps, orientation, covariances, other topics) as it was, on the same topic or on a new one beside the
original.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from itertools import chain, islice
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError, listing
from optcal.core.recording.robotlogs import LogSamples, join, sort_stamps

IMU = "sensor_msgs/msg/Imu"
VECTOR = "geometry_msgs/msg/Vector3Stamped"
# The standard definitions' digests as rosbags' typestores compute them (tests/test_robot_logs.py checks them
# against rosbags): ROS 1's MD5 sum and ROS 2's type hash (recorded in bags from Iron on; older bags have none)
MD5 = {IMU: "6a62c6daae103f4ff57a132d6f95cec2", VECTOR: "7b324c7325e683bf02a9b14b01090ec7"}
RIHS01 = {IMU: "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
          VECTOR: "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a"}
# after the header, a message is DOUBLES float64; the fields read: (index of the first, count)
DOUBLES = {IMU: 37, VECTOR: 3}
FIELDS = {IMU: {"angular_velocity": (13, 3), "angular_velocity_covariance": (16, 1), "linear_acceleration": (25, 3),
                "linear_acceleration_covariance": (28, 1)},
          VECTOR: {"vector": (0, 3)}}
ACC_FIELD = {IMU: "linear_acceleration", VECTOR: "vector"}
GYRO_FIELD = {IMU: "angular_velocity", VECTOR: "vector"}
# words of a Vector3Stamped topic's name that make it the accelerometer's or the gyroscope's
ACC_WORDS = ("acc", "accel", "accelerometer", "acceleration", "linear_acceleration", "specific_force")
GYRO_WORDS = ("gyr", "gyro", "gyroscope", "angular_velocity", "angvel", "rate", "omega")
BATCH = 1 << 16  # messages decoded at a time (bounds the memory: about 20 MB of Imu messages)
# the way out of a bag rosbags cannot read: most often one cut short (a recording stopped by a power loss)
FIX = {"ros1": "is the file complete? A ROS 1 bag cut short is mended by rosbag reindex",
       "sqlite3": "is the file complete? A ROS 2 bag cut short is mended by ros2 bag reindex",
       "mcap": "is the file complete? An MCAP file cut short is mended by mcap recover"}


def storage_of(path: Path) -> str:
    """``ros1``, ``sqlite3`` or ``mcap``: a ROS 2 bag's file by its suffix, a ROS 2 bag's folder by the storage
    files in it (compressed ones too), anything else a ROS 1 bag."""
    if path.is_dir():
        return "mcap" if any(p.name.endswith((".mcap", ".mcap.zstd")) for p in path.iterdir()) else "sqlite3"
    return {".mcap": "mcap", ".db3": "sqlite3"}.get(path.suffix.lower(), "ros1")


FORMAT = {"ros1": "ROS 1 bag", "sqlite3": "ROS 2 bag (SQLite)", "mcap": "ROS 2 bag (MCAP)"}


@contextmanager
def _rosbags_errors(path: Path, storage: str):
    """rosbags' failures (ReaderError, a struct or decompression error on a damaged file, SQLite's) as one
    line naming the file and the way out."""
    try:
        yield
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags and its storage libraries raise many kinds on a damaged file
        said = (str(exc).splitlines() or [""])[0]
        said = re.sub(r"\('(.*)',\)", r"\1", said).rstrip(".") or type(exc).__name__  # rosbags quotes some args
        raise InputError(f"cannot read {path} as a {FORMAT[storage]}: {said}; {FIX[storage]}") from None


@contextmanager
def _no_cyclic_gc():
    """Python's cyclic garbage collector paused: rosbags makes a small object per message (a ROS 1 bag's index
    entries when it is opened, a tuple per message read), none of which can form a cycle, and every full
    collection would scan them all (opening a ROS 1 bag of 720,000 messages: 1.1 s of CPU with it, 0.7 s
    without)."""
    import gc

    paused = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if paused:
            gc.enable()


def _reader(path: Path, storage: str):
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2

    with _rosbags_errors(path, storage), _no_cyclic_gc():
        reader = Reader1(path) if storage == "ros1" else Reader2(path)
        reader.open()
    return reader


def _u32(M: np.ndarray, at: int, endian: str) -> np.ndarray:
    return M[:, at:at + 4].copy().view(endian + "u4")[:, 0].astype(np.int64)


def decode_rows(M: np.ndarray, ros1: bool, msgtype: str) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """:func:`decode` of messages of one length, the rows of the uint8 matrix ``M``."""
    n, L = M.shape
    stamps = np.zeros(n, np.int64)
    out = {f: np.full((n, c), np.nan) for f, (_, c) in FIELDS[msgtype].items()}
    bad = np.zeros(n, bool)
    if L < 16:
        return stamps, out, ~bad
    doubles = 8 * DOUBLES[msgtype]
    if ros1:
        groups = [("<", np.ones(n, bool))]
    else:  # CDR's encapsulation: 0x00 0x01 little-endian, 0x00 0x00 big-endian
        groups = [(e, (M[:, 0] == 0) & (M[:, 1] == k)) for e, k in (("<", 1), (">", 0))]
        bad = ~(groups[0][1] | groups[1][1])
    for endian, sel in groups:
        if not sel.any():
            continue
        whole = sel.all()
        S, r = (M, np.arange(n)) if whole else (M[sel], np.flatnonzero(sel))
        slen = _u32(S, 12, endian)
        head = 16 + slen if ros1 else 4 + (12 + slen + 7) // 8 * 8
        ok = (head + doubles == L) if ros1 else (head + doubles <= L) & (L - head - doubles < 8)
        bad[r[~ok]] = True
        sec = S[:, 4:8].copy().view(endian + ("u4" if ros1 else "i4"))[:, 0].astype(np.int64)
        stamps[r] = sec * 1_000_000_000 + _u32(S, 8, endian)
        for h in np.unique(head[ok]):
            k = ok & (head == h)
            for f, (first, count) in FIELDS[msgtype].items():
                at = int(h) + 8 * first
                block = S[:, at:at + 8 * count] if k.all() else S[k, at:at + 8 * count]
                out[f][r[k]] = np.ascontiguousarray(block).view(endian + "f8")
    return stamps, out, bad


def decode(raws, ros1: bool, msgtype: str) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The header stamps (ns, int64) and the fields of :data:`FIELDS` of serialised messages ``raws`` (a
    sequence of bytes) of ``msgtype``, and which messages are malformed (bool): of another length than their
    ``frame_id`` implies, or, for CDR, of an unknown encapsulation. Vectorised over the messages that share a
    layout (module docstring): the messages of one length are one matrix (:func:`decode_rows`)."""
    n = len(raws)
    lengths = np.fromiter(map(len, raws), np.int64, n)
    first = int(lengths[0]) if n else 0
    if n and np.all(lengths == first):
        return decode_rows(np.frombuffer(b"".join(raws), np.uint8).reshape(n, first), ros1, msgtype)
    stamps = np.zeros(n, np.int64)
    out = {f: np.full((n, c), np.nan) for f, (_, c) in FIELDS[msgtype].items()}
    bad = np.zeros(n, bool)
    for L in np.unique(lengths):
        rows = np.flatnonzero(lengths == L)
        M = np.frombuffer(b"".join([raws[i] for i in rows]), np.uint8).reshape(len(rows), int(L))
        s, f, b = decode_rows(M, ros1, msgtype)
        stamps[rows], bad[rows] = s, b
        for k, v in f.items():
            out[k][rows] = v
    return stamps, out, bad


@dataclass
class Topic:
    """A topic's messages, decoded, in the bag's order."""

    name: str
    msgtype: str
    stamps: np.ndarray  # header stamps, ns
    received: np.ndarray  # the bag's stamps, ns
    fields: dict = field(default_factory=dict)


def _gather(B: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    """The ``width`` bytes of ``B`` at each of ``starts``, (k, width): rows of a sliding-window view of ``B``, so
    NumPy copies each row whole (20 times faster than indexing with a (k, width) array of positions)."""
    from numpy.lib.stride_tricks import sliding_window_view

    return sliding_window_view(B, int(width))[starts]


def _ros1_rows(reader, conns) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]] | None:
    """A ROS 1 topic's messages in bulk: rosbags' index of the bag (each message's time, chunk and offset, read
    when the bag is opened) locates every message record in its chunk, each chunk is read and decompressed once
    by rosbags' own decompressor, and the records' data are gathered with NumPy, without parsing a record
    header per message. Returns the messages' bag stamps (ns) in the bag's order, and their positions in that
    order with (k, L) uint8 matrices of equal-length messages. None when the records are not the plain ones
    read here (a message record whose header differs in length, or lacks ``op=2`` where the first has it) or
    rosbags' reader does not expose its index: then the messages are read one by one."""
    try:
        indexes = [reader.indexes[c.id] for c in conns]
        chunks, bio = reader.chunks, reader.bio
    except AttributeError:  # pragma: no cover - another rosbags version's reader
        return None
    n = sum(map(len, indexes))
    if not n:
        return np.zeros(0, np.int64), []
    # time, chunk position, offset in the chunk (np.fromiter over the flattened tuples: 10x np.array's speed)
    E = np.fromiter(chain.from_iterable(chain.from_iterable(indexes)), np.int64, 3 * n).reshape(n, 3)
    order = np.lexsort((E[:, 2], E[:, 1], E[:, 0]))  # as rosbags gives them: by time, then position
    by_chunk = order[np.argsort(E[order, 1], kind="stable")]
    cuts = np.flatnonzero(np.diff(E[by_chunk, 1])) + 1
    out, op_at, head_len = [], None, 0
    for rows in np.split(by_chunk, cuts):
        chunk = chunks[int(E[rows[0], 1])]
        bio.seek(chunk.datapos)
        B = np.frombuffer(chunk.decompressor(bio.read(chunk.datasize)), np.uint8)
        o = E[rows, 2]
        if o.max() + 8 > len(B):
            return None
        hl = _gather(B, o, 4).view("<u4")[:, 0].astype(np.int64)
        start = o + 8 + hl
        if op_at is None:  # where the first record's header holds op: every record's must hold it there
            head_len, op_at = int(hl[0]), _op_offset(bytes(B[o[0] + 4:min(o[0] + 4 + hl[0], len(B))]))
            if op_at is None:
                return None
        if np.any(hl != head_len) or start.max() > len(B) or np.any(B[o + 4 + op_at] != 2):
            return None
        dl = _gather(B, start - 4, 4).view("<u4")[:, 0].astype(np.int64)
        if np.any(start + dl > len(B)):
            return None
        for L in np.unique(dl):
            k = dl == L
            out.append((rows[k], _gather(B, start[k], L)))
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    return E[order, 0], [(rank[r], M) for r, M in out]


def _mcap_rows(reader, name: str) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]] | None:
    """An MCAP topic's messages in bulk, as :func:`_ros1_rows` reads a ROS 1 bag's: the MCAP file's message
    index (a record per chunk and channel listing each message's time and offset in the chunk, which rosbags
    locates when it reads the file's summary) gives every message record's place; each chunk holding the topic
    is decompressed once by rosbags' own ``decompress`` (its checksum checked), and the records' data are
    gathered with NumPy. None for a file without a summary or message index, messages compressed one by one
    (``compression_mode: message``), or records that are not the topic's message records: then the messages
    are read one by one."""
    from rosbags.rosbag2.storage_mcap import McapReader, decompress

    storage = getattr(reader, "storage", None)
    storages = getattr(storage, "storages", [storage])
    if getattr(getattr(storage, "metadata", None), "compression_mode", None) == "message":
        return None
    times, rows_of, found = [], [], []
    for st in storages:
        if not isinstance(st, McapReader) or not st.chunks:
            return None
        ids = {c.id for c in st.connections if c.topic == name}
        for chunk in st.chunks:
            if not any(chunk.channel_count.get(i, 0) for i in ids):
                continue
            entries = []
            for i in ids:
                at = chunk.message_index_offsets.get(i)
                if at is None:
                    continue
                st.bio.seek(at)
                head = st.bio.read(15)
                if len(head) < 15 or head[0] != 0x07 or int.from_bytes(head[9:11], "little") != i:
                    return None
                size = int.from_bytes(head[11:15], "little")
                entries.append(np.frombuffer(st.bio.read(size), "<u8").reshape(-1, 2).astype(np.int64))
            if not entries:
                continue
            E = np.concatenate(entries)  # log time, offset in the chunk
            st.bio.seek(chunk.chunk_start_offset + 9 + 24)
            crc = int.from_bytes(st.bio.read(4), "little")
            st.bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
            B = np.frombuffer(decompress(st.bio.read(chunk.compressed_size), chunk.compression,
                                         chunk.uncompressed_size, crc), np.uint8)
            o = E[:, 1]
            if o.max() + 31 > len(B) or np.any(B[o] != 0x05):
                return None
            length = _gather(B, o + 1, 8).view("<u8")[:, 0].astype(np.int64)
            channel = _gather(B, o + 9, 2).view("<u2")[:, 0]
            if not np.isin(channel, list(ids)).all() or np.any(o + 9 + length > len(B)) or np.any(length < 22):
                return None
            dl = length - 22
            for L in np.unique(dl):
                k = dl == L
                rows_of.append(_gather(B, o[k] + 31, L))
                times.append(E[k, 0])
                found.append(len(times[-1]))
    if not times:
        return np.zeros(0, np.int64), []
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    rank = np.empty(len(t), np.int64)
    rank[order] = np.arange(len(t))
    bounds = np.cumsum([0, *found])
    return t[order], [(rank[a:b], M) for a, b, M in zip(bounds[:-1], bounds[1:], rows_of)]


def _op_offset(header: bytes) -> int | None:
    """Where the value of the field ``op`` lies in a ROS 1 record header (``len name=value`` fields), or None."""
    at = 0
    while at + 4 <= len(header):
        n = int.from_bytes(header[at:at + 4], "little")
        name, eq, _ = header[at + 4:at + 4 + n].partition(b"=")
        if eq and name == b"op" and n == 4:
            return at + 7
        at += 4 + n
    return None


def read_topic(reader, path: Path, storage: str, name: str, msgtype: str) -> Topic:
    """Every message of topic ``name``, decoded: a ROS 1 bag's or an MCAP file's in bulk (:func:`_ros1_rows`,
    :func:`_mcap_rows`), else a batch of :data:`BATCH` messages at a time from rosbags' reader (:func:`decode`;
    for SQLite, one query whose rows its reader yields: fetching them in one call measured no faster). A
    malformed message is refused."""
    conns = [c for c in reader.connections if c.topic == name]
    ros1 = storage == "ros1"
    with _rosbags_errors(path, storage):
        bulk = _ros1_rows(reader, conns) if ros1 else _mcap_rows(reader, name) if storage == "mcap" else None
        if bulk is not None:
            received, rows = bulk
            parts = [(r, *decode_rows(M, ros1, msgtype), np.full(len(r), M.shape[1])) for r, M in rows]
        else:
            parts, received = _batches(reader, conns, ros1, msgtype)
    n = len(received)
    stamps = np.zeros(n, np.int64)
    fields = {f: np.zeros((n, c)) for f, (_, c) in FIELDS[msgtype].items()}
    for r, s, f, bad, size in parts:
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            at = int(r[i])
            raise InputError(f"{path}: message {at} of {name} is not a well-formed {msgtype} ({size[i]} bytes); "
                             "record the topic with the standard message")
        stamps[r] = s
        for k, v in f.items():
            fields[k][r] = v
    return Topic(name, msgtype, stamps, received, fields)


def _batches(reader, conns, ros1: bool, msgtype: str):
    """The messages from rosbags' reader, :data:`BATCH` at a time, decoded: (positions, stamps, fields, malformed,
    lengths) per batch, and the bag's stamps (the cyclic garbage collector paused, :func:`_no_cyclic_gc`)."""
    parts, received, seen = [], [], 0
    it = reader.messages(connections=conns)
    with _no_cyclic_gc():
        while batch := list(islice(it, BATCH)):
            raws = [m[2] for m in batch]
            received.append(np.fromiter((m[1] for m in batch), np.int64, len(batch)))
            s, f, bad = decode(raws, ros1, msgtype)
            sizes = np.fromiter(map(len, raws), np.int64, len(raws))
            parts.append((np.arange(seen, seen + len(raws)), s, f, bad, sizes))
            seen += len(raws)
    return parts, (np.concatenate(received) if received else np.zeros(0, np.int64))


def _words(topic: str) -> set[str]:
    return {w for part in topic.lower().split("/") for w in (part, *part.split("_")) if w}


def topics_of(reader) -> dict[str, tuple[str, int]]:
    """Topic → (message type, messages) of the bag's connections."""
    out: dict[str, tuple[str, int]] = {}
    for c in reader.connections:
        t, n = out.get(c.topic, (c.msgtype, 0))
        out[c.topic] = (c.msgtype if t == c.msgtype else "(several types)", n + c.msgcount)
    return out


def choose_topics(topics: dict[str, tuple[str, int]], topic: str | None, path) -> tuple[str, str | None]:
    """The accelerometer's topic and the gyroscope's (the same for an Imu topic; None for an accelerometer
    alone) from ``topic`` (``NAME`` or ``ACC,GYRO``), or without it the one Imu topic with messages, or the
    Vector3Stamped topics named as an accelerometer's and a gyroscope's (:data:`ACC_WORDS`, :data:`GYRO_WORDS`).
    Ambiguity, absence and other message types are refused in one line that lists the IMU topics."""
    usable = {t: ty for t, (ty, n) in topics.items() if ty in (IMU, VECTOR) and n > 0}
    said = listing(f"{t} ({'Imu' if ty == IMU else 'Vector3Stamped'})" for t, ty in sorted(usable.items()))
    if topic is not None:
        names = [s.strip() for s in str(topic).split(",")]
        if not 1 <= len(names) <= 2 or not all(names):
            raise InputError(f"`topic` {topic!r}: give one topic, or the accelerometer's and the gyroscope's as "
                             "ACC,GYRO")
        for t in names:
            if t not in topics:
                raise InputError(f"{path} has no topic {t}; its IMU topics: {said or 'none'}")
            ty, n = topics[t]
            if ty not in (IMU, VECTOR):
                raise InputError(f"{path}: topic {t} carries {ty}, not an IMU's message; give a topic of {IMU} or "
                                 f"{VECTOR} with `topic` (here: {said or 'none'})")
            if n == 0:
                raise InputError(f"{path}: topic {t} has no messages; give another with `topic` (here: "
                                 f"{said or 'none'})")
        if len(names) == 2:
            return names[0], names[1]
        return names[0], names[0] if topics[names[0]][0] == IMU else None
    imus = [t for t, ty in sorted(usable.items()) if ty == IMU]
    if len(imus) == 1:
        return imus[0], imus[0]
    if len(imus) > 1:
        raise InputError(f"{path} holds {len(imus)} IMU topics ({listing(imus)}); pick one with `topic` (or "
                         "ACC,GYRO for an accelerometer and a gyroscope on topics of their own)")
    vectors = [t for t, ty in sorted(usable.items()) if ty == VECTOR]
    acc = [t for t in vectors if _words(t) & set(ACC_WORDS)]
    gyro = [t for t in vectors if _words(t) & set(GYRO_WORDS) and t not in acc]
    if len(acc) == 1 and len(gyro) <= 1:
        return acc[0], gyro[0] if gyro else None
    if vectors:
        raise InputError(f"{path}: cannot tell the accelerometer's topic among {listing(vectors)} "
                         f"({VECTOR}); name it with `topic` ACC or ACC,GYRO")
    others = listing(f"{t} ({ty})" for t, (ty, _) in sorted(topics.items()))
    raise InputError(f"{path} holds no IMU messages ({IMU} or {VECTOR}; its topics: {others or 'none'}); record "
                     "the IMU's topic, or read another file")


def _check_definition(reader, path, name: str, storage: str) -> None:
    """Refuse a topic whose recorded definition is not the standard one (its digest differs)."""
    for c in reader.connections:
        if c.topic != name or not c.digest or c.digest == "*":
            continue
        want = MD5 if storage == "ros1" else RIHS01
        if c.msgtype in want and c.digest.startswith("RIHS01_" if storage != "ros1" else "") \
                and c.digest != want[c.msgtype]:
            raise InputError(f"{path}: topic {name}'s {c.msgtype} is not the standard definition (digest "
                             f"{c.digest[:16]}…, standard {want[c.msgtype][:16]}…); record it with the standard "
                             "message")


def times_ns(topic: Topic) -> tuple[np.ndarray, str]:
    """A topic's sample times (ns): its header stamps, or the bag's when every header stamp is zero (a driver
    that leaves them unset)."""
    if len(topic.stamps) and not topic.stamps.any():
        return topic.received, "the bag's receive stamps (every header stamp is zero)"
    return topic.stamps, "header stamps"


def read_bag(path, topic: str | None = None) -> LogSamples:
    """The IMU samples of the bag ``path`` (module docstring) on ``topic`` (``NAME`` or ``ACC,GYRO``; default:
    the one IMU topic, :func:`choose_topics`)."""
    path = Path(path)
    storage = storage_of(path)
    reader = _reader(path, storage)
    try:
        topics = topics_of(reader)
        acc_name, gyro_name = choose_topics(topics, topic, path)
        for name in {acc_name, gyro_name} - {None}:
            _check_definition(reader, path, name, storage)
        acc_t = read_topic(reader, path, storage, acc_name, topics[acc_name][0])
        gyro_t = None
        if gyro_name is not None and gyro_name != acc_name:
            gyro_t = read_topic(reader, path, storage, gyro_name, topics[gyro_name][0])
    finally:
        with _rosbags_errors(path, storage):
            reader.close()
    t, timing = times_ns(acc_t)
    order = sort_stamps(t, path, acc_name, 1e-9)
    t = t[order]
    A = acc_t.fields[ACC_FIELD[acc_t.msgtype]][order]
    how = {"format": f"{FORMAT[storage]}, topic {acc_name} ({acc_t.msgtype}), {timing}",
           "topic": acc_name, "message_type": acc_t.msgtype, "time": timing}
    if acc_t.msgtype == IMU and np.all(acc_t.fields["linear_acceleration_covariance"][:, 0] == -1):
        raise InputError(f"{path}: every message of {acc_name} marks linear_acceleration absent (covariance -1); "
                         "give the accelerometer's topic with `topic` ACC,GYRO")
    W = None
    if gyro_name == acc_name:
        if not np.all(acc_t.fields["angular_velocity_covariance"][:, 0] == -1):
            W = acc_t.fields["angular_velocity"][order]
            how["gyroscope"] = f"{acc_name}'s angular_velocity (rad/s)"
    elif gyro_t is not None:
        tg, _ = times_ns(gyro_t)
        og = sort_stamps(tg, path, gyro_name, 1e-9)
        keep, W, joined = join(t, tg[og], gyro_t.fields[GYRO_FIELD[gyro_t.msgtype]][og])
        t, A = t[keep], A[keep]
        how["gyroscope"] = f"{gyro_name}'s {GYRO_FIELD[gyro_t.msgtype]} (rad/s), {joined}"
        how["gyroscope_topic"] = gyro_name
    if len(t):
        how["first_stamp_ns"] = int(t[0])
    return LogSamples(t, 1e-9, A, W, None, how)


def _definition(conn, typestore):
    """The message definition and digest a writer needs to copy connection ``conn`` (its own when the bag
    recorded them, else generated by ``typestore``, the standard types and the bag's own)."""
    from rosbags.interfaces import MessageDefinitionFormat

    if conn.msgdef.format != MessageDefinitionFormat.NONE and conn.digest:
        return conn.msgdef.data, conn.digest
    if conn.msgtype not in typestore.fielddefs:
        raise InputError(f"cannot copy topic {conn.topic}: the bag holds no definition of {conn.msgtype}; convert "
                         "the bag with one (ros2 bag convert) or apply to a table (-o FILE.csv)")
    return typestore.generate_msgdef(conn.msgtype, ros_version=2)[0], typestore.hash_rihs01(conn.msgtype)


def _typestore(reader):
    """ROS 2's standard types (Humble) and the types whose definitions the bag recorded."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    for c in reader.connections:
        if c.msgdef.format == MessageDefinitionFormat.MSG:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        elif c.msgdef.format == MessageDefinitionFormat.IDL:
            store.register(get_types_from_idl(c.msgdef.data))
    return store


def encode(raws, ros1: bool, msgtype: str, values: dict[str, np.ndarray]) -> list[bytes]:
    """``raws`` (serialised messages of ``msgtype``, well-formed: :func:`decode`) with the fields named in
    ``values`` ((n, 3) float64 each) replaced, every other byte kept; vectorised as :func:`decode` is."""
    n = len(raws)
    lengths = np.fromiter(map(len, raws), np.int64, n)
    out: list[bytes] = list(raws)
    for L in np.unique(lengths):
        rows = np.flatnonzero(lengths == L)
        blob = b"".join(raws) if len(rows) == n else b"".join([raws[i] for i in rows])
        M = np.frombuffer(blob, np.uint8).reshape(len(rows), int(L)).copy()
        endian = np.full(len(rows), "<") if ros1 else np.where(M[:, 1] == 1, "<", ">")
        for e in np.unique(endian):
            sel = endian == e
            slen = _u32(M[sel], 12, str(e))
            head = 16 + slen if ros1 else 4 + (12 + slen + 7) // 8 * 8
            idx = np.flatnonzero(sel)
            for h in np.unique(head):
                k = idx[head == h]
                for f, V in values.items():
                    a = int(h) + 8 * FIELDS[msgtype][f][0]
                    M[k, a:a + 24] = np.ascontiguousarray(V[rows[k]], dtype=str(e) + "f8").view(np.uint8)
        for j, i in enumerate(rows):
            out[i] = M[j].tobytes()
    return out


def _raw_topic(reader, name: str) -> tuple[list[bytes], np.ndarray]:
    """Every serialised message of topic ``name`` in the bag's order, and the bag's stamps (ns)."""
    conns = [c for c in reader.connections if c.topic == name]
    raws, got = [], []
    it = reader.messages(connections=conns)
    while batch := list(islice(it, BATCH)):
        _, g, r = zip(*batch)
        raws.extend(r)
        got.append(np.asarray(g, np.int64))
    return raws, (np.concatenate(got) if got else np.zeros(0, np.int64))


def write_calibrated(src, dst, *, topic: str | None, t0_ns: int,
                     acc: Callable[[np.ndarray, np.ndarray], np.ndarray],
                     gyro: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None,
                     output_topic: str | None = None, overwrite: bool = False) -> dict:
    """Copy the bag ``src`` to ``dst`` in the same storage (a ``.bag`` file; a ROS 2 bag's folder, or its one
    ``.mcap`` or ``.db3`` file when ``dst`` ends so) with the IMU's messages calibrated: ``acc(t, N)`` gives the
    specific force (m/s²) of raw samples N at times t (s from ``t0_ns``, the recording's first stamp) and
    replaces the accelerometer's field; ``gyro(t, W, A)`` (if given) gives the angular rate (rad/s) of raw
    rates W with the specific force A (m/s²) at their times and replaces the gyroscope's field. The calibrated
    messages replace the originals, or go on topics of their own beside them (``output_topic``: NAME, or
    ACC,GYRO). Written whole or not at all (:func:`optcal.core.atomicfile.atomic_output`); returns what was written."""
    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_output

    src, dst = Path(src), Path(dst)
    storage = storage_of(src)
    suffix = dst.suffix.lower()
    want = {"ros1": (".bag",), "mcap": (".mcap", ""), "sqlite3": (".db3", "")}[storage]
    if suffix not in want and (suffix in (".bag", ".mcap", ".db3") or storage == "ros1"):
        named = want[0] + (" or a folder without a suffix" if len(want) > 1 else "")
        raise InputError(f"the output {dst} would change the bag's storage ({FORMAT[storage]}), which apply keeps: "
                         f"name it {named}, or .csv for a table")
    one_file = storage != "ros1" and suffix in (".mcap", ".db3")
    reader = _reader(src, storage)
    try:
        topics = topics_of(reader)
        acc_name, gyro_name = choose_topics(topics, topic, src)
        renamed = _renamed(acc_name, gyro_name, output_topic, topics, src)
        with _rosbags_errors(src, storage):
            patched = _patches(reader, storage, topics, acc_name, gyro_name, t0_ns, acc, gyro)
        with atomic_output(dst, overwrite=overwrite, exists=EXISTS_OUTPUT) as tmp:
            with _rosbags_errors(src, storage):
                # a ROS 2 writer makes a folder; for a single file, the folder's one storage file is kept
                _copy(reader, storage, tmp.with_suffix("") if one_file else tmp, patched, renamed)
            if one_file:
                folder = tmp.with_suffix("")
                (folder / f"{folder.name}{dst.suffix.lower()}").rename(tmp)
                for p in folder.iterdir():
                    p.unlink()
                folder.rmdir()
    finally:
        with _rosbags_errors(src, storage):
            reader.close()
    return {"format": FORMAT[storage], "topics": {t: renamed.get(t, t) for t in patched},
            "messages": {t: len(v) for t, v in patched.items()}}


def _renamed(acc_name: str, gyro_name: str | None, output_topic: str | None, topics: dict, src) -> dict[str, str]:
    """Calibrated topic → the new topic it goes on (``output_topic``), or {} to replace the originals."""
    if output_topic is None:
        return {}
    names = [s.strip() for s in output_topic.split(",")]
    calibrated = [acc_name] + ([gyro_name] if gyro_name not in (None, acc_name) else [])
    if len(names) != len(calibrated) or not all(n.startswith("/") and len(n) > 1 for n in names) \
            or len(set(names)) < len(names):
        raise InputError(f"`output_topic` {output_topic!r}: give {len(calibrated)} new topic name(s) starting with / "
                         f"for {', '.join(calibrated)}")
    taken = [n for n in names if n in topics]
    if taken:
        raise InputError(f"`output_topic` {listing(taken)}: {src} has that topic already; choose a new name")
    return dict(zip(calibrated, names))


def _patches(reader, storage: str, topics: dict, acc_name: str, gyro_name: str | None, t0_ns: int, acc,
             gyro) -> dict[str, dict[bytes, bytes]]:
    """The calibrated messages, {topic: {original bytes: calibrated bytes}} (a message is found again by its
    bytes when the bag is copied, whatever order the storage gives equal stamps)."""
    ros1 = storage == "ros1"
    raws, got = _raw_topic(reader, acc_name)
    ty = topics[acc_name][0]
    stamps, f, _ = decode(raws, ros1, ty)
    t = ((got if len(stamps) and not stamps.any() else stamps) - t0_ns) * 1e-9
    A = np.asarray(acc(t, f[ACC_FIELD[ty]]), float)
    values = {ACC_FIELD[ty]: A}
    if gyro is not None and gyro_name == acc_name and not np.all(f["angular_velocity_covariance"][:, 0] == -1):
        values["angular_velocity"] = np.asarray(gyro(t, f["angular_velocity"], A), float)
    out = {acc_name: dict(zip(raws, encode(raws, ros1, ty, values)))}
    if gyro is not None and gyro_name not in (None, acc_name):
        graws, ggot = _raw_topic(reader, gyro_name)
        gty = topics[gyro_name][0]
        gstamps, gf, _ = decode(graws, ros1, gty)
        tg = ((ggot if len(gstamps) and not gstamps.any() else gstamps) - t0_ns) * 1e-9
        order = np.argsort(t, kind="stable")
        A_at = np.column_stack([np.interp(tg, t[order], A[order, j]) for j in range(3)])
        W = np.asarray(gyro(tg, gf[GYRO_FIELD[gty]], A_at), float)
        out[gyro_name] = dict(zip(graws, encode(graws, ros1, gty, {GYRO_FIELD[gty]: W})))
    return out


def _copy(reader, storage: str, dst: Path, patched: dict, renamed: dict) -> None:
    """Every message of ``reader`` into a new bag at ``dst``: a patched topic's messages replaced by their
    calibrated bytes, or, for a topic in ``renamed``, kept and followed by the calibrated ones on the new topic.
    Connections that differ only in their id are written as one."""
    if storage == "ros1":
        from rosbags.rosbag1 import Writer

        def add(c, topic):
            return writer.add_connection(topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest,
                                         callerid=c.ext.callerid, latching=c.ext.latching)

        writer = Writer(dst)
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        store = _typestore(reader)

        def add(c, topic):
            msgdef, digest = _definition(c, store)
            return writer.add_connection(topic, c.msgtype, msgdef=msgdef, rihs01=digest,
                                         serialization_format=c.ext.serialization_format,
                                         offered_qos_profiles=c.ext.offered_qos_profiles)

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(dst, version=Writer2.VERSION_LATEST, storage_plugin=plugin)
    writer.open()
    try:
        made: dict = {}
        conns, extra = {}, {}
        for c in reader.connections:
            key = repr((c.topic, c.msgtype, c.msgdef, c.digest, c.ext))  # ROS 2's QoS list is not hashable
            if key not in made:
                made[key] = add(c, c.topic)
            conns[c.id] = made[key]
            if c.topic in renamed and c.topic not in extra:
                extra[c.topic] = add(c, renamed[c.topic])
        for c, stamp, raw in reader.messages():
            fix = patched.get(c.topic)
            if fix is None:
                writer.write(conns[c.id], stamp, raw)
            elif c.topic in extra:
                writer.write(conns[c.id], stamp, raw)
                writer.write(extra[c.topic], stamp, fix[raw])
            else:
                writer.write(conns[c.id], stamp, fix[raw])
    finally:
        writer.close()
