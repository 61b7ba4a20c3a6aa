"""The fast path's chunk-by-chunk decoding (``io.decode.columns``): the fixed-layout ROS 2
messages decoded as the walk meets each chunk, their payloads never all kept, give the tables
the whole-channel decode gives and the general path's, over chunk sizes, compressions, joint
state layouts that change, messages outside chunks and a message that does not fit the bulk
decode (the channel read again)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import CompressionType, Writer

from dhlog.io import reader, ros2
from dhlog.io.decode.blocks import bulk_decode
from dhlog.io.decode.columns import ColumnSink, layout_plan
from dhlog.io.mcapscan import scan_mcap
from dhlog.io.pipeline import pipeline_by_name, shipped_pipelines
from dhlog.io.reader import LogData, read_log

T0 = 1_700_000_000_000_000_000
COMPRESSIONS = {
    "none": CompressionType.NONE,
    "lz4": CompressionType.LZ4,
    "zstd": CompressionType.ZSTD,
}


def _log(
    path: Path,
    *,
    chunk_size: int,
    compression: str,
    point_type: str = ros2.POINT_STAMPED,
    layouts: bool = False,
    big_endian_at: int | None = None,
    loose: int = 0,
    seed: int = 0,
) -> Path:
    """Targets, joint states, base points and phase markers (CDR as rosbag2 records it). With
    ``layouts``: frame ids of several lengths, zero stamps (log time used), joint states whose
    name order and payload length change, with stamps shared across layouts;
    ``big_endian_at``: that target message flagged big-endian; ``loose``: the last that many
    messages written outside chunks, after the chunks."""
    rng = np.random.default_rng(seed)
    n, m = 1500, 400
    t_pt = T0 + np.arange(n) * 1_000_000 + rng.integers(0, 1000, n)
    xyz = rng.normal(size=(n, 3))
    frames = ["laser_tracker", "t", "tracker_1", ""] if layouts else ["laser_tracker"]
    points = []
    for i in range(n):
        stamp, frame = (0 if layouts and i % 97 == 5 else t_pt[i]), frames[i % len(frames)]
        if point_type == ros2.POSE_WITH_COVARIANCE:
            cov = np.abs(rng.normal(size=(1, 6))) * 1e-8
            points += ros2.encode_pose_with_covariance([stamp], xyz[i : i + 1], frame, cov)
        else:
            points += ros2.encode_point_stamped([stamp], xyz[i : i + 1], frame)
    if big_endian_at is not None:
        p = points[big_endian_at]
        points[big_endian_at] = p[:1] + b"\x00" + p[2:]
    # with ``layouts``: the names with a longer payload, then in three orders (the whole-channel
    # decode takes the shorter payloads' layouts first)
    orders = [["a", "b", "c"], ["a", "b", "c"], ["c", "a", "b"], ["b", "c", "a"]]
    joints = []
    t_q = T0 + np.arange(m) * 4_000_000 + 17
    for i in range(m):
        k = (i // 23) % len(orders) if layouts else 0
        stamp = t_q[i - 1] if layouts and i % 23 == 0 and i else t_q[i]  # ties across layouts
        (q,) = ros2.encode_joint_state([stamp], orders[k], rng.normal(size=(1, 3)))
        joints.append(q + b"\x00" * 8 if k == 0 else q)
    events = [(int(t), "/tracker/point", p) for t, p in zip(t_pt, points, strict=True)]
    events += [(int(t), "/joint_states", p) for t, p in zip(t_q, joints, strict=True)]
    events += [
        (T0 + k * 9_000_000, "/tracker/base_plane", q)
        for k, q in enumerate(ros2.encode_point_stamped(T0 + np.arange(5), np.eye(5, 3), "b"))
    ]
    events += [
        (T0 + k * 300_000_000, "/calibration/phase", ros2.encode_string(f"joint_{k % 3 + 1}"))
        for k in range(5)
    ]
    events.sort(key=lambda e: e[0])
    types = {
        "/tracker/point": point_type,
        "/joint_states": ros2.JOINT_STATE,
        "/tracker/base_plane": ros2.POINT_STAMPED,
        "/calibration/phase": ros2.STRING,
    }
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=COMPRESSIONS[compression])
        w.start(profile="ros2", library="test")
        schemas = {
            s: w.register_schema(s, "ros2msg", ros2.MSGDEFS[s].encode())
            for s in dict.fromkeys(types.values())
        }
        channels = {
            topic: w.register_channel(topic, "cdr", schemas[s]) for topic, s in types.items()
        }
        for t, topic, payload in events[: len(events) - loose]:
            w.add_message(channels[topic], t, payload, t)
        w.finish()
    if loose:  # the last messages outside chunks, before the data end
        data = path.read_bytes()
        pos = 8
        while data[pos] != 0x0F:
            pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
        records = b""
        for t, topic, payload in events[len(events) - loose :]:
            body = struct.pack("<HIQQ", channels[topic], 0, t, t) + payload
            records += bytes([5]) + struct.pack("<Q", len(body)) + body
        path.write_bytes(data[:pos] + records + data[pos:])
    return path


def _same(a: LogData, b: LogData) -> None:
    assert a.points.equals(b.points) and a.points.height > 1000
    assert a.joints is not None and a.joints.height > 300
    for x, y in ((a.joints, b.joints), (a.base, b.base), (a.phase, b.phase)):
        assert x is not None and y is not None and x.equals(y)
    assert a.joint_names == b.joint_names
    assert a.set_aside == b.set_aside
    assert a.warnings == b.warnings


def _payloads_kept(path: Path, monkeypatch: pytest.MonkeyPatch, **kw: object) -> LogData:
    """``read_log`` as before the chunk-by-chunk decoding: every wanted payload kept by the
    walk, then each channel decoded whole."""
    with monkeypatch.context() as m:
        m.setattr(reader, "ColumnSink", lambda plan: None)
        return read_log(path, **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("chunk_size", "compression"),
    [(2048, "none"), (5000, "lz4"), (40_000, "zstd"), (10**7, "zstd")],
)
def test_chunk_by_chunk_gives_the_general_paths_tables(
    tmp_path: Path, chunk_size: int, compression: str
) -> None:
    for point_type in (ros2.POINT_STAMPED, ros2.POSE_WITH_COVARIANCE):
        path = _log(
            tmp_path / "run.mcap",
            chunk_size=chunk_size,
            compression=compression,
            point_type=point_type,
        )
        _same(read_log(path), read_log(path, fast=False))


@pytest.mark.parametrize(
    ("chunk_size", "compression", "point_type", "big_endian_at", "loose"),
    [
        (1500, "lz4", ros2.POINT_STAMPED, None, 0),
        (3000, "none", ros2.POSE_WITH_COVARIANCE, None, 40),
        (20_000, "zstd", ros2.POINT_STAMPED, 1400, 0),  # read again: the channel whole
        (10**7, "zstd", ros2.POSE_WITH_COVARIANCE, 3, 7),
    ],
)
def test_chunk_by_chunk_gives_the_whole_channel_decodes_tables(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    chunk_size: int,
    compression: str,
    point_type: str,
    big_endian_at: int | None,
    loose: int,
) -> None:
    """Joint-state layouts in the order the whole-channel decode finds them (by payload
    length, then first message: the table's order where stamps tie), zero stamps, frame ids of
    several lengths; a big-endian message: the point channel read whole, message by message."""
    path = _log(
        tmp_path / "run.mcap",
        chunk_size=chunk_size,
        compression=compression,
        point_type=point_type,
        layouts=True,
        big_endian_at=big_endian_at,
        loose=loose,
        seed=chunk_size,
    )
    pipeline = pipeline_by_name("ros2_tracker")
    _same(read_log(path), _payloads_kept(path, monkeypatch))
    _same(read_log(path, pipeline), _payloads_kept(path, monkeypatch, pipeline=pipeline))
    if big_endian_at is not None:
        assert read_log(path).set_aside["damaged_message"] == 1


def test_the_walk_keeps_no_payload_of_a_channel_decoded_chunk_by_chunk(tmp_path: Path) -> None:
    """The decoded channels' payloads are not in the scan (they were all kept until the end of
    the walk, beside the decoded columns); the columns are the whole channel's bulk decode."""
    path = _log(tmp_path / "run.mcap", chunk_size=4096, compression="zstd", layouts=True)
    sink = ColumnSink(layout_plan(shipped_pipelines()))
    scan = scan_mcap(path, sink=sink)
    whole = scan_mcap(path)
    topics = {c.topic: cid for cid, c in whole.channels.items()}
    decoded = {"/tracker/point": "point", "/joint_states": "joints", "/tracker/base_plane": "point"}
    assert set(scan.messages) == {topics["/calibration/phase"]}  # a String: kept
    for topic, layout in decoded.items():
        cid = topics[topic]
        assert sink.decoded(cid) == (whole.channels[cid], layout)
        got, want = sink.blocks(cid), bulk_decode(layout, whole.messages[cid])
        assert len(got) == len(want) > (1 if layout == "joints" else 0)
        for (t, values), (t_whole, values_whole) in zip(got, want, strict=True):
            np.testing.assert_array_equal(t, t_whole)
            if layout == "joints":
                assert values[0] == values_whole[0]
                values, values_whole = values[1], values_whole[1]
            np.testing.assert_array_equal(np.column_stack(values), values_whole)
