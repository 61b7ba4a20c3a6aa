"""Write simulated sessions as MCAP files, in each encoding of the input contract.

* ``ros2``: as rosbag2 writes it: profile ``ros2``, schemas ``ros2msg``, CDR messages, a
  ``rosbag2`` metadata record, no chunk CRCs.
* ``json``: ``jsonschema`` schemas ``foxglove.Point3InFrame`` (``foxglove.PoseInFrame`` for a
  6-DoF target) and ``foxglove.JointStates``, phase markers as ``{"joint": k}``.
* ``protobuf``: the Foxglove protobuf schemas; phase markers as JSON on their own channel.

Further targets go on ``/tracker/point_2``, ``/tracker/point_3``, … in every encoding, as points
(SMRs measure no orientation) beside a 6-DoF target. A session with commanded joint targets
(``command_t_ns`` / ``command_q``, the ISO 9283 test) writes them on ``/joint_command`` as joint
states (sensor_msgs/JointState, foxglove.JointStates).

Files are written to a temporary name beside the target and renamed into place.
"""

from __future__ import annotations

import heapq
import json
import os
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np
from mcap.writer import CompressionType, Writer
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.io import ros2
from dhlog.io.streams import RecordedStreams

Encoding = Literal["ros2", "json", "protobuf"]
TOPICS = {
    "point": "/tracker/point",
    "joints": "/joint_states",
    "base": "/tracker/base_plane",
    "phase": "/calibration/phase",
    "command": "/joint_command",
}

_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
JSON_SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.Point3InFrame": {
        "title": "foxglove.Point3InFrame",
        "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"}, "point": _VEC3},
    },
    "foxglove.PoseInFrame": {
        "title": "foxglove.PoseInFrame",
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "frame_id": {"type": "string"},
            "pose": {
                "type": "object",
                "properties": {
                    "position": _VEC3,
                    "orientation": {
                        "type": "object",
                        "properties": {k: {"type": "number"} for k in "xyzw"},
                    },
                },
            },
        },
    },
    "foxglove.JointStates": {
        "title": "foxglove.JointStates",
        "type": "object",
        "properties": {
            "timestamp": _TIME,
            "joints": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {"name": {"type": "string"}, "position": {"type": "number"}},
                },
            },
        },
    },
    "dhlog.Phase": {
        "title": "dhlog.Phase",
        "type": "object",
        "properties": {"joint": {"type": ["integer", "null"]}},
    },
}


#: Threads in a block that must not be cut in half (:func:`signals_deferred`, the moves of
#: :func:`staged_outputs`), each with the stop asked of it meanwhile (:func:`stop_thread`).
_UNCUT: dict[int, type[BaseException] | None] = {}
_UNCUT_LOCK = threading.Lock()


def stop_thread(ident: int, exc: type[BaseException]) -> None:
    """Raise ``exc`` in the thread ``ident`` at its next Python instruction, or, when it is in
    a block that must not be cut in half, as that block ends: how a Dask worker's job is
    stopped (:mod:`dhlog.fleet.executors`; a thread has no signals). Code in C runs on until
    it returns."""
    with _UNCUT_LOCK:
        if ident in _UNCUT:
            _UNCUT[ident] = exc
        else:
            _async_exc(ident, exc)


def forget_stop() -> None:
    """Drop a stop asked of this thread and not yet raised (a job that ended meanwhile)."""
    with _UNCUT_LOCK:
        _async_exc(threading.get_ident(), None)


def _async_exc(ident: int, exc: type[BaseException] | None) -> None:
    import ctypes

    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(ident), exc and ctypes.py_object(exc))


@contextmanager
def _stop_deferred() -> Iterator[None]:
    """A stop of this thread (:func:`stop_thread`) asked during the block raised after it."""
    ident = threading.get_ident()
    if ident in _UNCUT:  # nested: the outer block raises it
        yield
        return
    try:
        with _UNCUT_LOCK:
            _UNCUT[ident] = None
        yield
    finally:
        with _UNCUT_LOCK:
            asked = _UNCUT.pop(ident, None)
        if asked is not None:
            raise asked()


@contextmanager
def signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM noted during the block and raised again right after it (in the main
    thread; elsewhere a stop of the thread, :func:`stop_thread`): for work that must not be cut
    in half."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        with _stop_deferred():
            yield
        return
    noted: list[int] = []

    def note(signum: int, frame: object) -> None:
        noted.append(signum)

    previous = {s: signal.signal(s, note) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if noted:
            signal.raise_signal(noted[0])


def publish(tmp: str | Path, target: str | Path) -> None:
    """Move a finished temporary file into place, with the permissions of the user's umask (a
    temporary file is created 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, target)


@contextmanager
def atomic_output(path: str | Path) -> Iterator[IO[bytes]]:
    """A binary file that replaces ``path`` only when the block finishes without error (its
    folder must exist)."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
        publish(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextmanager
def staged_outputs(paths: list[Path], *, hold_signals: bool = False) -> Iterator[list[Path]]:
    """Temporary files beside ``paths``, moved into place together when the block finishes
    without error (none of them otherwise: an interrupted run leaves no partial set). With
    ``hold_signals`` (the command line), SIGINT and SIGTERM are held from the moment the files
    are moved into place on: the run is complete then, and ends as such."""
    temps: list[Path] = []
    try:
        for target in paths:
            fd, name = tempfile.mkstemp(
                prefix=f".{target.name}.", suffix=".part", dir=target.parent
            )
            os.close(fd)
            temps.append(Path(name))
        yield temps
        if hold_signals:  # ignored process-wide (a mask would hold only this thread)
            import signal

            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
        with _stop_deferred():  # a thread's stop, too, waits for the moves
            for staged, target in zip(temps, paths, strict=True):
                publish(staged, target)
    finally:
        for staged in temps:
            staged.unlink(missing_ok=True)


def _stamp(t_ns: int) -> dict[str, int]:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _extra_streams(session: RecordedStreams) -> list[str]:
    """Streams of the further targets: ``point_2``, ``point_3``, … (topics ``/tracker/point_k``)."""
    return [f"point_{k + 2}" for k in range(len(session.extra_point_xyz))]


def _commands(session: RecordedStreams) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The commanded joint targets' stamps and values (none for a session without them: the
    attributes ``command_t_ns`` / ``command_q`` are optional)."""
    t_ns = getattr(session, "command_t_ns", None)
    q = getattr(session, "command_q", None)
    if t_ns is None or q is None or not np.asarray(t_ns).size:
        return np.zeros(0, dtype=np.int64), np.zeros((0, len(session.joint_names)))
    return np.asarray(t_ns, dtype=np.int64), np.asarray(q, dtype=np.float64)


def _events(session: RecordedStreams, *, extras: bool = False) -> list[tuple[int, str, int]]:
    """(time, stream, index) of every message (with the further targets'), in the order a
    recorder receives them: the streams merged by time, each in its own order — a stream whose
    stamps fall (its clock set back mid-session) is written as it was sent, as rosbag2 does."""
    streams: list[list[tuple[int, str, int]]] = [
        [(int(t), "base", i) for i, t in enumerate(session.base_t_ns)],
        [(int(t), "point", i) for i, t in enumerate(session.point_t_ns)],
    ]
    if extras:
        for stream in _extra_streams(session):
            streams.append([(int(t), stream, i) for i, t in enumerate(session.point_t_ns)])
    streams.append([(int(t), "joints", i) for i, t in enumerate(session.joint_t_ns)])
    streams.append([(t, "phase", i) for i, (t, _) in enumerate(session.phase)])
    streams.append([(int(t), "command", i) for i, t in enumerate(_commands(session)[0])])
    return list(heapq.merge(*streams, key=lambda e: e[0]))


def _quaternions(session: RecordedStreams) -> NDArray[np.float64] | None:
    """The 6-DoF target's orientation per sample as unit quaternions (x, y, z, w), or None."""
    if session.point_rotation is None:
        return None
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(session.point_rotation).as_quat(canonical=True))


def _target_xyz(session: RecordedStreams, stream: str, i: int) -> NDArray[np.float64]:
    """Sample ``i`` of a point stream: ``point``, ``base`` or a further target ``point_k``."""
    if stream == "point":
        xyz = session.point_xyz
    elif stream == "base":
        xyz = session.base_xyz
    else:
        xyz = session.extra_point_xyz[int(stream.removeprefix("point_")) - 2]
    return np.asarray(xyz[i], dtype=np.float64)


def _phase_text(joint: int | None) -> str:
    return "none" if joint is None else f"joint_{joint}"


def write_session(
    session: RecordedStreams,
    path: str | Path,
    encoding: Encoding = "ros2",
    *,
    point_type: Literal["point", "pose"] = "point",
    chunk_size: int = 768 * 1024,
) -> None:
    """Write ``session`` to ``path`` (atomically) in ``encoding``, in chunks of ``chunk_size``
    bytes (rosbag2's default)."""
    with atomic_output(path) as f:
        if encoding == "ros2":
            _write_ros2(session, f, point_type, chunk_size)
        elif encoding == "json":
            _write_json(session, f, chunk_size)
        else:
            _write_protobuf(session, f, chunk_size)


def _write_ros2(session: RecordedStreams, f: IO[bytes], point_type: str, chunk_size: int) -> None:
    writer = Writer(f, chunk_size=chunk_size, compression=CompressionType.ZSTD, enable_crcs=False)
    writer.start(profile="ros2", library="rosbag2 (simulated by dhlog)")
    if session.point_rotation is not None:  # a 6-DoF target: PoseStamped with its orientation
        point_type = "pose"
    point_schema = ros2.POSE_STAMPED if point_type == "pose" else ros2.POINT_STAMPED
    schema_ids = {
        name: writer.register_schema(name, "ros2msg", ros2.MSGDEFS[name].encode())
        for name in (point_schema, ros2.POINT_STAMPED, ros2.JOINT_STATE, ros2.STRING)
    }
    encode = ros2.encode_pose_stamped if point_type == "pose" else ros2.encode_point_stamped
    points = encode(session.point_t_ns, session.point_xyz, "tracker")
    quats = _quaternions(session)
    if quats is not None:
        points = ros2.encode_pose_stamped(session.point_t_ns, session.point_xyz, "tracker", quats)
    payloads: dict[str, list[bytes]] = {
        "point": points,
        "base": ros2.encode_point_stamped(session.base_t_ns, session.base_xyz, "tracker"),
        "joints": ros2.encode_joint_state(session.joint_t_ns, session.joint_names, session.joint_q),
        "phase": [ros2.encode_string(_phase_text(j)) for _, j in session.phase],
    }
    stream_schema = {
        "point": point_schema,
        "base": ros2.POINT_STAMPED,
        "joints": ros2.JOINT_STATE,
        "phase": ros2.STRING,
    }
    command_t, command_q = _commands(session)
    if command_t.size:  # only then: a session without commands is written as before
        payloads["command"] = ros2.encode_joint_state(command_t, session.joint_names, command_q)
        stream_schema["command"] = ros2.JOINT_STATE
    # further targets are SMRs: no orientation of their own (a pose message only when asked)
    extra_schema, encode_extra = point_schema, encode
    if quats is not None:
        extra_schema, encode_extra = ros2.POINT_STAMPED, ros2.encode_point_stamped
    for stream, extra in zip(_extra_streams(session), session.extra_point_xyz, strict=True):
        payloads[stream] = encode_extra(session.point_t_ns, extra, "tracker")
        stream_schema[stream] = extra_schema
    channels = {
        s: writer.register_channel(
            TOPICS.get(s, f"/tracker/{s}"),
            "cdr",
            schema_ids[stream_schema[s]],
            {"offered_qos_profiles": ""},
        )
        for s in payloads
        if payloads[s]
    }
    counts = {s: len(p) for s, p in payloads.items()}
    for t, stream, i in _events(session, extras=True):
        writer.add_message(channels[stream], t, payloads[stream][i], t)
    writer.add_metadata(
        "rosbag2",
        {
            "serialized_metadata": json.dumps(
                {"version": 9, "storage_identifier": "mcap", "message_counts": counts}
            )
        },
    )
    writer.finish()  # type: ignore[no-untyped-call]


def _write_json(session: RecordedStreams, f: IO[bytes], chunk_size: int) -> None:
    writer = Writer(f, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    writer.start(profile="", library="dhlog simulate")
    quats = _quaternions(session)
    point_schema = "foxglove.Point3InFrame" if quats is None else "foxglove.PoseInFrame"
    ids = {
        name: writer.register_schema(name, "jsonschema", json.dumps(s).encode())
        for name, s in JSON_SCHEMAS.items()
        if name != "foxglove.PoseInFrame" or quats is not None
    }
    channels = {
        "point": writer.register_channel(TOPICS["point"], "json", ids[point_schema]),
        "base": writer.register_channel(TOPICS["base"], "json", ids["foxglove.Point3InFrame"]),
    }
    for stream in _extra_streams(session):
        channels[stream] = writer.register_channel(
            f"/tracker/{stream}", "json", ids["foxglove.Point3InFrame"]
        )
    if session.joint_t_ns.size:
        channels["joints"] = writer.register_channel(
            TOPICS["joints"], "json", ids["foxglove.JointStates"]
        )
    if session.phase:
        channels["phase"] = writer.register_channel(TOPICS["phase"], "json", ids["dhlog.Phase"])
    command_t, command_q = _commands(session)
    if command_t.size:
        channels["command"] = writer.register_channel(
            TOPICS["command"], "json", ids["foxglove.JointStates"]
        )
    for t, stream, i in _events(session, extras=True):
        if stream.startswith("point") or stream == "base":
            xyz = _target_xyz(session, stream, i)
            position = {"x": float(xyz[0]), "y": float(xyz[1]), "z": float(xyz[2])}
            msg: dict[str, Any] = {"timestamp": _stamp(t), "frame_id": "tracker"}
            if stream == "point" and quats is not None:
                orientation = dict(zip("xyzw", (float(v) for v in quats[i]), strict=True))
                msg["pose"] = {"position": position, "orientation": orientation}
            else:
                msg["point"] = position
        elif stream in ("joints", "command"):
            values = session.joint_q[i] if stream == "joints" else command_q[i]
            msg = {
                "timestamp": _stamp(t),
                "joints": [
                    {"name": n, "position": float(v)}
                    for n, v in zip(session.joint_names, values, strict=True)
                ],
            }
        else:
            msg = {"joint": session.phase[i][1]}
        writer.add_message(channels[stream], t, json.dumps(msg).encode(), t)
    writer.finish()  # type: ignore[no-untyped-call]


def _write_protobuf(session: RecordedStreams, f: IO[bytes], chunk_size: int) -> None:
    from foxglove_schemas_protobuf.JointState_pb2 import JointState
    from foxglove_schemas_protobuf.JointStates_pb2 import JointStates
    from foxglove_schemas_protobuf.Point3_pb2 import Point3
    from foxglove_schemas_protobuf.Point3InFrame_pb2 import Point3InFrame
    from foxglove_schemas_protobuf.Pose_pb2 import Pose
    from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
    from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
    from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
    from google.protobuf.timestamp_pb2 import Timestamp
    from mcap_protobuf.schema import register_schema

    writer = Writer(f, chunk_size=chunk_size, compression=CompressionType.ZSTD)
    writer.start(profile="protobuf", library="dhlog simulate")
    point_schema = register_schema(writer, Point3InFrame)
    quats = _quaternions(session)
    target_schema = point_schema if quats is None else register_schema(writer, PoseInFrame)
    channels = {
        "point": writer.register_channel(TOPICS["point"], "protobuf", target_schema),
        "base": writer.register_channel(TOPICS["base"], "protobuf", point_schema),
    }
    for stream in _extra_streams(session):
        channels[stream] = writer.register_channel(f"/tracker/{stream}", "protobuf", point_schema)
    command_t, command_q = _commands(session)
    if session.joint_t_ns.size or command_t.size:
        joint_schema = register_schema(writer, JointStates)
    if session.joint_t_ns.size:
        channels["joints"] = writer.register_channel(TOPICS["joints"], "protobuf", joint_schema)
    if command_t.size:
        channels["command"] = writer.register_channel(TOPICS["command"], "protobuf", joint_schema)
    if session.phase:
        phase_schema = writer.register_schema(
            "dhlog.Phase", "jsonschema", json.dumps(JSON_SCHEMAS["dhlog.Phase"]).encode()
        )
        channels["phase"] = writer.register_channel(TOPICS["phase"], "json", phase_schema)

    def stamp(t: int) -> Timestamp:
        sec, nsec = divmod(t, 1_000_000_000)
        return Timestamp(seconds=sec, nanos=nsec)

    for t, stream, i in _events(session, extras=True):
        if stream == "point" and quats is not None:
            xyz, quat = session.point_xyz[i], quats[i]
            pose = Pose(
                position=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                orientation=Quaternion(
                    x=float(quat[0]), y=float(quat[1]), z=float(quat[2]), w=float(quat[3])
                ),
            )
            payload = PoseInFrame(
                timestamp=stamp(t), frame_id="tracker", pose=pose
            ).SerializeToString()
        elif stream.startswith("point") or stream == "base":
            xyz = _target_xyz(session, stream, i)
            data = Point3InFrame(
                timestamp=stamp(t),
                frame_id="tracker",
                point=Point3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
            )
            payload = data.SerializeToString()
        elif stream in ("joints", "command"):
            values = session.joint_q[i] if stream == "joints" else command_q[i]
            joints = [
                JointState(name=n, position=float(v))
                for n, v in zip(session.joint_names, values, strict=True)
            ]
            payload = JointStates(timestamp=stamp(t), joints=joints).SerializeToString()
        else:
            payload = json.dumps({"joint": session.phase[i][1]}).encode()
        writer.add_message(channels[stream], t, payload, t)
    writer.finish()  # type: ignore[no-untyped-call]


def write_truth(document: dict[str, object], path: str | Path) -> None:
    """Write a truth/result document as indented JSON, atomically."""
    with atomic_output(path) as f:
        f.write((json.dumps(document, indent=2) + "\n").encode())


def sha256_of(path: str | Path) -> str:
    """Hex SHA-256 of a file, or of a folder's files (a rosbag2 bag) in name order."""
    import hashlib

    digest = hashlib.sha256()
    files = (
        sorted(p for p in Path(path).iterdir() if p.is_file()) if Path(path).is_dir() else [path]
    )
    for name in files:
        try:
            with open(name, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    digest.update(block)
        except OSError as exc:  # gone or unreadable since it was read (moved, deleted)
            raise InputError(
                f"{name}: cannot be read again for its checksum ({exc.strerror or exc}); keep "
                "the log in place until dhlog process has finished."
            ) from None
    return digest.hexdigest()


def sha256_begun(path: str | Path) -> Callable[[], str]:
    """:func:`sha256_of` ``path`` begun in a thread of its own, beside a long walk of the same
    log (a camera log's detection: the hash's reading and hashing release the GIL); the call
    it returns waits for the digest, or raises what :func:`sha256_of` raised. The thread is a
    daemon: a run that fails before it asks does not wait for the hash to exit."""
    found: list[str] = []
    failed: list[BaseException] = []

    def work() -> None:
        try:
            found.append(sha256_of(path))
        except BaseException as exc:  # handed to the caller, raised there
            failed.append(exc)

    thread = threading.Thread(target=work, name="dhlog-sha256", daemon=True)
    thread.start()

    def digest() -> str:
        thread.join()
        if failed:
            raise failed[0]
        return found[0]

    return digest
