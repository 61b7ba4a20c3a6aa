"""MCAP ingestion: simulator → reader round trips, an independent rosbag2 writer, the fast and
general paths, pipeline choice, and every bad-input case."""

from __future__ import annotations

import dataclasses
import math
import struct
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from dhlog.errors import (
    JointNamesError,
    MissingTopicError,
    NotMcapError,
    PipelineError,
    TooFewSamplesError,
    UnknownSchemaError,
)
from dhlog.identify.segment.segment import segment_log
from dhlog.io.pipeline import load_pipeline, parse_pipeline, pipeline_by_name, shipped_pipelines
from dhlog.io.reader import read_log
from dhlog.io.writer import write_session
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

ENCODINGS = ["ros2", "json", "protobuf"]


@pytest.fixture(scope="module")
def session() -> Session:
    cfg = SimulationConfig(
        noise=2e-5,
        seed=11,
        phase=True,
        sweep=math.radians(40),
        dwell=0.1,
        outliers=0.01,
        dropouts=0.02,
    )
    return simulate_session(load_robot("scara"), cfg)


def written(session: Session, tmp_path: Path, encoding: str, **kwargs: object) -> Path:
    path = tmp_path / f"run_{encoding}.mcap"
    write_session(session, path, encoding, **kwargs)  # type: ignore[arg-type]
    return path


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_round_trip_gives_back_what_was_written(
    session: Session, tmp_path: Path, encoding: str
) -> None:
    log = read_log(written(session, tmp_path, encoding))
    assert (
        log.pipeline.name
        == {"ros2": "ros2_tracker", "json": "foxglove_json", "protobuf": "foxglove_protobuf"}[
            encoding
        ]
    )
    np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), session.point_t_ns)
    np.testing.assert_array_equal(log.points.select(["x", "y", "z"]).to_numpy(), session.point_xyz)
    assert log.joints is not None and log.joint_names == session.joint_names
    np.testing.assert_array_equal(log.joints["t_ns"].to_numpy(), session.joint_t_ns)
    np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), session.joint_q)
    assert log.base is not None
    np.testing.assert_array_equal(log.base.select(["x", "y", "z"]).to_numpy(), session.base_xyz)
    assert log.phase is not None
    assert log.phase["joint"].to_list() == [j for _, j in session.phase]
    assert log.set_aside == {}


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_fast_and_general_paths_give_identical_tables(
    session: Session, tmp_path: Path, encoding: str
) -> None:
    path = written(session, tmp_path, encoding)
    fast, general = read_log(path), read_log(path, fast=False)
    assert fast.points.equals(general.points)
    assert fast.joints is not None and fast.joints.equals(general.joints)
    assert fast.base is not None and fast.base.equals(general.base)
    assert fast.phase is not None and fast.phase.equals(general.phase)
    assert segment_log(fast).table.equals(segment_log(general).table)


def test_pose_stamped_targets_are_read(session: Session, tmp_path: Path) -> None:
    path = written(session, tmp_path, "ros2", point_type="pose")
    for fast in (True, False):
        log = read_log(path, fast=fast)
        np.testing.assert_array_equal(
            log.points.select(["x", "y", "z"]).to_numpy(), session.point_xyz
        )


def rosbags_bag(
    bag: Path, seed: int, compression: str = "none", lag: tuple[int, int] = (0, 0)
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A ROS 2 bag written by an independent writer (rosbags' rosbag2 MCAP storage, with
    ``compression`` none, message or file): PointStamped targets and two-joint JointStates;
    returns their stamps and values. ``lag``: log time minus header stamp, per topic."""
    rng = np.random.default_rng(seed)
    xyz = rng.normal(size=(50, 3))
    q = rng.normal(size=(60, 2))
    t_pt = 1_700_000_000_000_000_000 + np.arange(50) * 10_000_000
    t_q = 1_700_000_000_000_000_000 + np.arange(60) * 8_000_000 + 1234
    _write_points_and_joints(bag, t_pt, xyz, t_q, q, compression, lag)
    return t_pt, xyz, t_q, q


def test_rosbag2_written_by_rosbags_is_read(tmp_path: Path) -> None:
    """A ROS 2 bag from an independent writer (rosbags' rosbag2 MCAP storage)."""
    bag = tmp_path / "bag"
    t_pt, xyz, _, q = rosbags_bag(bag, 0, lag=(5, 7))
    mcap_file = next(bag.glob("*.mcap"))
    for fast in (True, False):
        log = read_log(mcap_file, fast=fast)
        assert log.pipeline.name == "ros2_tracker"
        np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), t_pt)  # header stamps
        np.testing.assert_array_equal(log.points.select(["x", "y", "z"]).to_numpy(), xyz)
        assert log.joint_names == ["shoulder", "elbow"]
        assert log.joints is not None
        np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), q)


def test_length_unit_mm_is_scaled(session: Session, tmp_path: Path) -> None:
    path = written(session, tmp_path, "ros2")
    text = Path(pipeline_by_name("ros2_tracker").source).read_text()  # type: ignore[union-attr]
    mm = parse_pipeline(text.replace('length_unit = "m"', 'length_unit = "mm"'), "mm.toml")
    log = read_log(path, mm)
    np.testing.assert_allclose(log.points["x"].to_numpy(), session.point_xyz[:, 0] * 1e-3)


def test_shipped_pipelines_are_valid() -> None:
    names = [p.name for p in shipped_pipelines()]
    assert names[:3] == ["ros2_tracker", "foxglove_json", "foxglove_protobuf"]
    assert "phase_markers" in names


def test_pipeline_for_logs_without_encoders(tmp_path: Path) -> None:
    cfg = SimulationConfig(seed=2, encoders=False, phase=True, sweep=math.radians(30), dwell=0.1)
    sess = simulate_session(load_robot("kr5"), cfg)
    log = read_log(written(sess, tmp_path, "ros2"))
    assert log.pipeline.name == "phase_markers"
    assert log.joints is None
    seg = segment_log(log)
    assert seg.segments["joint"].to_list() == [1, 2, 3, 4, 5, 6]
    assert "idle" in seg.set_aside


# ---- bad input ---------------------------------------------------------------------------------


def test_not_mcap(tmp_path: Path) -> None:
    path = tmp_path / "notes.mcap"
    path.write_text("x, y, z\n1, 2, 3\n")
    with pytest.raises(NotMcapError, match=r"notes\.mcap: not an MCAP file"):
        read_log(path)


def test_truncated_file_keeps_what_precedes_the_damage(session: Session, tmp_path: Path) -> None:
    path = tmp_path / "small_chunks.mcap"
    write_session(session, path, "ros2", chunk_size=16 * 1024)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    log = read_log(cut, pipeline_by_name("ros2_tracker"))
    warning = next(w for w in log.warnings if "cut short" in w)
    assert "cut.mcap" in warning and "recovered" in warning
    n = log.points.height
    assert 0 < n < session.point_t_ns.size
    np.testing.assert_array_equal(
        log.points.select(["x", "y", "z"]).to_numpy(), session.point_xyz[:n]
    )


def test_unknown_schema_on_configured_topic(session: Session, tmp_path: Path) -> None:
    path = written(session, tmp_path, "ros2")
    wrong = parse_pipeline('[streams.point]\ntopic = "/joint_states"\n', "wrong.toml")
    with pytest.raises(
        UnknownSchemaError, match="/joint_states carries 'sensor_msgs/msg/JointState'"
    ):
        read_log(path, wrong)


def test_missing_topic_lists_the_topics_present(session: Session, tmp_path: Path) -> None:
    path = written(session, tmp_path, "ros2")
    other = parse_pipeline('[streams.point]\ntopic = "/laser/point"\n', "other.toml")
    with pytest.raises(
        MissingTopicError,
        match=r"no topic /laser/point.*/joint_states, /tracker/base_plane, /tracker/point",
    ):
        read_log(path, other)


def test_non_finite_samples_are_set_aside_and_counted(tmp_path: Path) -> None:
    cfg = SimulationConfig(seed=3, sweep=math.radians(30), dwell=0.1)
    sess = simulate_session(load_robot("scara"), cfg)
    sess.point_xyz[[3, 10, 11]] = [np.nan, np.inf, -np.inf]
    log = read_log(written(sess, tmp_path, "ros2"))
    assert log.set_aside == {"non_finite_point": 3}
    assert log.points.height == sess.point_t_ns.size - 3


def test_joint_names_that_do_not_match_the_pipeline(session: Session, tmp_path: Path) -> None:
    path = written(session, tmp_path, "ros2")
    named = parse_pipeline(
        '[streams.point]\n[streams.joints]\n[joints]\nnames = ["a1", "a2"]\n', "named.toml"
    )
    with pytest.raises(JointNamesError, match=r"names joints \['joint_1'.*expects \['a1', 'a2'\]"):
        read_log(path, named)


def test_too_few_samples(tmp_path: Path) -> None:
    cfg = SimulationConfig(seed=3, sweep=math.radians(30), dwell=0.1, tracker_rate=100)
    sess = simulate_session(load_robot("scara"), cfg)
    keep = 2
    sess.point_t_ns, sess.point_xyz = sess.point_t_ns[:keep], sess.point_xyz[:keep]
    with pytest.raises(TooFewSamplesError, match="point stream: only 2 usable sample"):
        segment_log(read_log(written(sess, tmp_path, "ros2")))


def test_a_sweep_with_too_few_samples_is_named(tmp_path: Path) -> None:
    cfg = SimulationConfig(seed=3, sweep=math.radians(30), dwell=0.1, tracker_rate=10)
    sess = simulate_session(load_robot("scara"), cfg)
    pipe = parse_pipeline(
        "[streams.point]\n[streams.joints]\n[segmentation]\nmin_samples = 40\n", "strict.toml"
    )
    seg = segment_log(read_log(written(sess, tmp_path, "ros2"), pipe))
    assert seg.set_aside["too_few_samples"] > 0
    assert any(
        n.code == "short-sweep" and "joint 1 (joint_1): a sweep with only" in n.text
        for n in seg.notes
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("name = [", "not valid TOML"),
        ('[streams.target]\ntopic = "/x"\n', "unknown stream"),
        ('encoding = "ros1"\n[streams.point]\n', "encoding"),
        ('length_unit = "inch"\n[streams.point]\n', "length_unit"),
        ("[streams.joints]\n", "no \\[streams.point\\]"),
        ("[streams.point]\n[segmentation]\nlock = 1\n", "unknown key 'lock'"),
        ('length_units = "mm"\n[streams.point]\n', "did you mean 'length_unit'"),
        ('[streams.point]\nfields = { px = "a.x" }\n', "fields: unknown key 'px'"),
        ('[streams.point]\ntopik = "/x"\n', "did you mean 'topic'"),
        ('[streams.point]\n[joints]\nname = ["a"]\n', "did you mean 'names'"),
        ('[streams.point]\n[segmentation]\nmin_samples = "3"\n', "must be a finite number"),
        ('angle_unit = "grad"\n[streams.point]\n', "angle_unit 'grad' unknown"),
    ],
)
def test_malformed_pipelines(text: str, message: str) -> None:
    with pytest.raises(PipelineError, match=message):
        parse_pipeline(text, "bad.toml")


def test_missing_pipeline_file(tmp_path: Path) -> None:
    with pytest.raises(PipelineError, match=r"nothing\.toml: cannot be read"):
        load_pipeline(tmp_path / "nothing.toml")


def test_no_pipeline_matches(tmp_path: Path) -> None:
    from mcap.writer import Writer

    path = tmp_path / "odd.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        cid = w.register_channel("/camera", "json", w.register_schema("x", "jsonschema", b"{}"))
        w.add_message(cid, 1, b"{}", 1)
        w.finish()  # type: ignore[no-untyped-call]
    with pytest.raises(PipelineError, match=r"no shipped pipeline matches its topics \(/camera"):
        read_log(path)


def test_segmented_table_has_the_contract_columns(session: Session, tmp_path: Path) -> None:
    seg = segment_log(read_log(written(session, tmp_path, "ros2")))
    t = seg.table
    assert t.schema["t_ns"] == pl.Int64
    assert all(t.schema[c] == pl.Float64 for c in ["x", "y", "z", "q_1", "q_2", "q_3", "q_4"])
    assert t.schema["joint"] == pl.Int32 and t.schema["segment"] == pl.Int32
    assert seg.segments["joint"].to_list() == [1, 2, 3, 4]
    # every target sample is either in a sweep or counted
    unassigned = t.filter(pl.col("segment").is_null()).height
    assert unassigned == sum(v for k, v in seg.set_aside.items() if not k.startswith("non_finite"))


def test_a_pipeline_is_checked_against_the_log(session: Session, tmp_path: Path) -> None:
    """Declared encodings, the number of joint types and JSON field paths are checked against
    the log, each with a one-line error naming the topic or key."""
    from dhlog.errors import InputError

    cdr = written(session, tmp_path, "ros2")
    as_json = parse_pipeline('encoding = "json"\n[streams.point]\n[streams.joints]\n', "j.toml")
    with pytest.raises(PipelineError, match="/tracker/point is encoded as 'cdr'"):
        read_log(cdr, as_json)
    two = parse_pipeline(
        '[streams.point]\n[streams.joints]\n[joints]\ntypes = ["revolute", "revolute"]\n', "t.toml"
    )
    with pytest.raises(PipelineError, match=r"types lists 2 joint\(s\) but .* has 4"):
        read_log(cdr, two)
    json_log = written(session, tmp_path, "json")
    paths = parse_pipeline(
        'encoding = "json"\n[streams.point]\nfields = { x = "pos.x", y = "pos.y", z = "pos.z" }\n'
        "[streams.joints]\n",
        "f.toml",
    )
    with pytest.raises(InputError, match=r"\[streams.point\] fields \(x = 'pos.x'"):
        read_log(json_log, paths)


def test_encoders_in_degrees_with_angle_unit_deg(tmp_path: Path) -> None:
    """``angle_unit = "deg"``: revolute encoders recorded in degrees read as the same log in
    radians (prismatic joints stay in the length unit)."""
    sess = simulate_session(load_robot("scara"), SimulationConfig(seed=4))
    plain = read_log(written(sess, tmp_path, "ros2"))
    deg = dataclasses.replace(sess, joint_q=sess.joint_q.copy())
    revolute = [t.value == "revolute" for t in sess.joint_types]
    deg.joint_q[:, revolute] = np.degrees(deg.joint_q[:, revolute])
    path = tmp_path / "deg.mcap"
    write_session(deg, path, "ros2")
    pipe = parse_pipeline(
        'angle_unit = "deg"\n[streams.point]\n[streams.joints]\n[joints]\n'
        'types = ["revolute", "revolute", "revolute", "prismatic"]\n',
        "deg.toml",
    )
    log = read_log(path, pipe)
    assert log.joints is not None and plain.joints is not None
    assert np.allclose(log.joints.drop("t_ns").to_numpy(), plain.joints.drop("t_ns").to_numpy())


@pytest.mark.parametrize("mode", ["none", "message", "file"])
def test_a_rosbag2_folder_is_read_as_rosbag2_writes_it(mode: str, tmp_path: Path) -> None:
    """The bag folder as the argument (metadata.yaml read by rosbags), written by rosbags with
    no compression, per-message zstd and per-file zstd (``.mcap.zstd``): the same streams as
    the uncompressed bag."""
    bag = tmp_path / "bag"
    t_pt, xyz, _, q = rosbags_bag(bag, 1, mode)
    if mode == "file":
        assert list(bag.glob("*.mcap.zstd"))
    log = read_log(bag)
    assert log.pipeline.name == "ros2_tracker"
    np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), t_pt)
    np.testing.assert_array_equal(log.points.select(["x", "y", "z"]).to_numpy(), xyz)
    assert log.joints is not None and log.joint_names == ["shoulder", "elbow"]
    np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), q)
    if mode != "none":  # the file alone reads too (payloads compressed one by one: seen)
        alone = read_log(next(bag.glob("*.mcap*")))
        np.testing.assert_array_equal(alone.points.select(["x", "y", "z"]).to_numpy(), xyz)


def test_transforms_as_the_point_stream_selected_by_child_frame(tmp_path: Path) -> None:
    """``tf2_msgs/msg/TFMessage`` on /tf carrying two frames (a bag from rosbags): the pipeline's
    ``child_frame`` picks the target; without it the first frame is used and a warning names
    the others; a ``TransformStamped`` topic reads as well; a frame that is not there is one
    line."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from dhlog.errors import InputError

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    rng = np.random.default_rng(2)
    xyz = rng.normal(size=(30, 3))
    t_pt = 1_700_000_000_000_000_000 + np.arange(30) * 10_000_000
    bag = tmp_path / "bag"

    def transform(t: int, child: str, p: np.ndarray):  # type: ignore[no-untyped-def]
        stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
        return T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="tracker"),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )

    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        single = writer.add_connection(
            "/smr", "geometry_msgs/msg/TransformStamped", typestore=store
        )
        for t, p in zip(t_pt.tolist(), xyz, strict=True):
            msg = T["tf2_msgs/msg/TFMessage"](
                transforms=[transform(t, "flange", p + 1.0), transform(t, "smr", p)]
            )
            writer.write(tf, t, store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))
            one = transform(t, "smr", p)
            writer.write(single, t, store.serialize_cdr(one, "geometry_msgs/msg/TransformStamped"))

    def pipeline(topic: str, child: str) -> object:
        extra = f'child_frame = "{child}"\n' if child else ""
        return parse_pipeline(f'[streams.point]\ntopic = "{topic}"\n{extra}', "tf.toml")

    log = read_log(bag, pipeline("/tf", "smr"))  # type: ignore[arg-type]
    np.testing.assert_array_equal(log.points.select(["x", "y", "z"]).to_numpy(), xyz)
    np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), t_pt)
    first = read_log(bag, pipeline("/tf", ""))  # type: ignore[arg-type]
    np.testing.assert_array_equal(first.points.select(["x", "y", "z"]).to_numpy(), xyz + 1.0)
    assert any("carries the frames flange, smr" in w for w in first.warnings)
    alone = read_log(bag, pipeline("/smr", ""))  # type: ignore[arg-type]
    np.testing.assert_array_equal(alone.points.select(["x", "y", "z"]).to_numpy(), xyz)
    with pytest.raises(InputError, match="no transform to the frame 'tcp'"):
        read_log(bag, pipeline("/tf", "tcp"))  # type: ignore[arg-type]


def test_foxglove_frame_transforms_as_the_point_stream(tmp_path: Path) -> None:
    """``foxglove.FrameTransforms`` (protobuf, written with the mcap library and the Foxglove
    schemas) with two child frames: ``child_frame`` picks the target."""
    from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
    from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
    from google.protobuf.timestamp_pb2 import Timestamp
    from mcap.writer import CompressionType, Writer
    from mcap_protobuf.schema import register_schema

    rng = np.random.default_rng(3)
    xyz = rng.normal(size=(20, 3))
    t_pt = 1_700_000_000_000_000_000 + np.arange(20) * 10_000_000
    path = tmp_path / "fox.mcap"
    with path.open("wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="protobuf", library="test")
        channel = writer.register_channel(
            "/tf", "protobuf", register_schema(writer, FrameTransforms)
        )
        for t, p in zip(t_pt.tolist(), xyz, strict=True):
            ts = Timestamp(seconds=t // 10**9, nanos=t % 10**9)
            frames = [
                FrameTransform(
                    timestamp=ts,
                    parent_frame_id="tracker",
                    child_frame_id=child,
                    translation=Vector3(x=v[0], y=v[1], z=v[2]),
                    rotation=Quaternion(w=1.0),
                )
                for child, v in (("flange", p - 1.0), ("smr", p))
            ]
            writer.add_message(
                channel, t, FrameTransforms(transforms=frames).SerializeToString(), t
            )
        writer.finish()
    pipe = parse_pipeline(
        'encoding = "protobuf"\n[streams.point]\ntopic = "/tf"\nchild_frame = "smr"\n', "f.toml"
    )
    log = read_log(path, pipe)
    np.testing.assert_allclose(log.points.select(["x", "y", "z"]).to_numpy(), xyz)
    np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), t_pt)


def test_foxglove_poses_in_frame_as_the_point_stream(tmp_path: Path) -> None:
    """``foxglove.PosesInFrame`` (protobuf, from the mcap writer) with three poses per message:
    ``pose_index`` picks the target (default the first); an index beyond the list is one line."""
    from foxglove_schemas_protobuf.Pose_pb2 import Pose
    from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
    from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
    from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
    from google.protobuf.timestamp_pb2 import Timestamp
    from mcap.writer import Writer
    from mcap_protobuf.schema import register_schema

    from dhlog.errors import InputError

    rng = np.random.default_rng(4)
    xyz = rng.normal(size=(20, 3))
    t_pt = 1_700_000_000_000_000_000 + np.arange(20) * 10_000_000
    path = tmp_path / "poses.mcap"
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="protobuf", library="test")
        channel = writer.register_channel("/smr", "protobuf", register_schema(writer, PosesInFrame))
        for t, p in zip(t_pt.tolist(), xyz, strict=True):
            poses = [
                Pose(position=Vector3(x=v[0], y=v[1], z=v[2]), orientation=Quaternion(w=1.0))
                for v in (p, p + 1.0, p + 2.0)
            ]
            msg = PosesInFrame(
                timestamp=Timestamp(seconds=t // 10**9, nanos=t % 10**9),
                frame_id="tracker",
                poses=poses,
            )
            writer.add_message(channel, t, msg.SerializeToString(), t)
        writer.finish()

    def pipeline(extra: str) -> object:
        return parse_pipeline(
            f'encoding = "protobuf"\n[streams.point]\ntopic = "/smr"\n{extra}', "p.toml"
        )

    first = read_log(path, pipeline(""))  # type: ignore[arg-type]
    np.testing.assert_allclose(first.points.select(["x", "y", "z"]).to_numpy(), xyz)
    np.testing.assert_array_equal(first.points["t_ns"].to_numpy(), t_pt)
    third = read_log(path, pipeline("pose_index = 2\n"))  # type: ignore[arg-type]
    np.testing.assert_allclose(third.points.select(["x", "y", "z"]).to_numpy(), xyz + 2.0)
    with pytest.raises(InputError, match="none of its 20 message"):
        read_log(path, pipeline("pose_index = 5\n"))  # type: ignore[arg-type]


@pytest.mark.parametrize(("unit", "vertical"), [("deg", "zenith"), ("gon", "elevation")])
def test_spherical_tracker_angles_as_the_point_stream(
    session: Session, tmp_path: Path, unit: str, vertical: str
) -> None:
    """Raw tracker angles (horizontal, vertical, distance in mm) in JSON from the mcap writer,
    ``coordinates = "spherical"``: the same positions (to rounding) as the Cartesian log, and
    the same identified model."""
    import json

    from mcap.writer import Writer

    from dhlog.identify.run import process_data
    from dhlog.model.dh import JointType
    from dhlog.model.fk import fk_point

    cart = read_log(written(session, tmp_path, "ros2"))
    xyz = cart.points.select(["x", "y", "z"]).to_numpy()
    d = np.linalg.norm(xyz, axis=1)
    hz = np.arctan2(xyz[:, 1], xyz[:, 0])
    v = np.arccos(xyz[:, 2] / d)
    if vertical == "elevation":
        v = math.pi / 2 - v
    per_rad = 180 / math.pi if unit == "deg" else 200 / math.pi
    path = tmp_path / "angles.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="tracker export")
        pc = w.register_channel("/angles", "json", 0)
        jc = w.register_channel("/joints", "json", 0)
        for t, h_, v_, d_ in zip(cart.points["t_ns"].to_list(), hz, v, d, strict=True):
            msg = {"t": t, "hz": h_ * per_rad, "v": v_ * per_rad, "dist": d_ * 1e3}
            w.add_message(pc, t, json.dumps(msg).encode(), t)
        assert cart.joints is not None
        turn = [per_rad if k is JointType.REVOLUTE else 1e3 for k in session.table.joint_types]
        for row in cart.joints.iter_rows():
            t, q = row[0], row[1:]
            scaled = [x * s for x, s in zip(q, turn, strict=True)]
            msg2 = {"t": t, "name": cart.joint_names, "position": scaled}
            w.add_message(jc, t, json.dumps(msg2).encode(), t)
        w.finish()
    pipe = parse_pipeline(
        f"""encoding = "json"
length_unit = "mm"
angle_unit = "{unit}"
[streams.point]
topic = "/angles"
coordinates = "spherical"
vertical = "{vertical}"
fields = {{ horizontal = "hz", vertical = "v", distance = "dist", stamp_ns = "t" }}
[streams.joints]
topic = "/joints"
fields = {{ names = "name", positions = "position" }}
[joints]
types = ["revolute", "revolute", "revolute", "prismatic"]  # the units differ by type
""",
        "angles.toml",
    )
    log = read_log(path, pipe)
    np.testing.assert_allclose(log.points.select(["x", "y", "z"]).to_numpy(), xyz, atol=1e-12)
    a, b = process_data(cart).extraction, process_data(log).extraction
    assert a is not None and b is not None
    q = np.random.default_rng(0).uniform(-0.5, 0.5, size=(50, b.standard.n))
    np.testing.assert_allclose(
        fk_point(b.standard, q, b.tool_point, T_base=b.T_measurement_base),
        fk_point(a.standard, q, a.tool_point, T_base=a.T_measurement_base),
        atol=1e-9,
    )


def test_spherical_pipeline_rules() -> None:
    """A spherical stream names its angles' fields, and fields naming angles are spherical: a
    ``coordinates = "spherical"`` over a PointStamped stream (a TypeError in
    ``decode.frames.cartesian`` before, issue 31) and angles read as x, y, z are refused."""
    fields = 'fields = { horizontal = "hz", vertical = "v", distance = "d" }\n'
    with pytest.raises(PipelineError, match="station is its origin"):
        parse_pipeline(
            f'[streams.point]\ncoordinates = "spherical"\n{fields}[noise]\nmodel = "tracker"\n'
            "station = [1.0, 0.0, 0.0]\n",
            "s.toml",
        )
    with pytest.raises(PipelineError, match="coordinates must be one of"):
        parse_pipeline('[streams.point]\ncoordinates = "polar"\n', "s.toml")
    with pytest.raises(PipelineError, match=r"/tracker/point carry x, y, z.*leave coordinates out"):
        parse_pipeline('[streams.point]\ncoordinates = "spherical"\n', "s.toml")
    with pytest.raises(PipelineError, match='would be read as x, y, z; set coordinates = "sph'):
        parse_pipeline(f"[streams.point]\n{fields}", "s.toml")


def test_a_split_rosbag2_bag_is_read_as_one_log(tmp_path: Path) -> None:
    """A bag split in two files as ``ros2 bag record --max-bag-size`` leaves it: each file written
    by rosbags' writer (which does not split itself), the folder's metadata.yaml listing both
    files as rosbag2 does (relative_file_paths, files, summed counts). Read in order as one log,
    the streams are the whole session's."""
    import shutil

    import yaml

    t_pt, xyz, t_q, q = rosbags_bag(tmp_path / "whole", 5)
    # the same session, cut at its middle into two bags by time
    halves = []
    for k in range(2):
        bag = tmp_path / f"half_{k}"
        part_pt = slice(0, 25) if k == 0 else slice(25, None)
        cut = t_pt[25]
        part_q = (t_q < cut) if k == 0 else (t_q >= cut)
        _write_points_and_joints(bag, t_pt[part_pt], xyz[part_pt], t_q[part_q], q[part_q])
        halves.append(bag)
    split = tmp_path / "split"
    split.mkdir()
    metas = [yaml.safe_load((h / "metadata.yaml").read_text()) for h in halves]
    info = metas[0]["rosbag2_bagfile_information"]
    files, paths = [], []
    for k, (h, m) in enumerate(zip(halves, metas, strict=True)):
        name = f"split_{k}.mcap"
        shutil.copy(next(h.glob("*.mcap")), split / name)
        entry = m["rosbag2_bagfile_information"]["files"][0]
        files.append({**entry, "path": name})
        paths.append(name)
    info["relative_file_paths"] = paths
    info["files"] = files
    info["message_count"] = sum(m["rosbag2_bagfile_information"]["message_count"] for m in metas)
    for topic, other in zip(
        info["topics_with_message_count"],
        metas[1]["rosbag2_bagfile_information"]["topics_with_message_count"],
        strict=True,
    ):
        topic["message_count"] += other["message_count"]
    (split / "metadata.yaml").write_text(yaml.safe_dump(metas[0]))
    log = read_log(split)
    assert "a rosbag2 bag of 2 file(s)" in (log.pipeline_reason or "")
    np.testing.assert_array_equal(log.points["t_ns"].to_numpy(), t_pt)
    np.testing.assert_array_equal(log.points.select(["x", "y", "z"]).to_numpy(), xyz)
    assert log.joints is not None
    np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), q)
    # a long bag: each file's tables wait for the join in scratch files, the log the same
    import dhlog.io.reader as reader
    from dhlog.io import scratch

    moved: list[int] = []

    def counted(frame: pl.DataFrame) -> pl.DataFrame:
        moved.append(frame.height)
        return spill(frame)

    spill = reader.spilled
    with scratch.spill_above(0), pytest.MonkeyPatch.context() as patch:
        patch.setattr(reader, "spilled", counted)
        spilled = read_log(split)
    assert sorted(moved) == sorted([25, 25, *(int(np.sum(t_q < cut)), int(np.sum(t_q >= cut)))])
    assert spilled.points.equals(log.points) and spilled.joints is not None
    assert spilled.joints.equals(log.joints)


def _write_points_and_joints(
    bag: Path,
    t_pt: np.ndarray,
    xyz: np.ndarray,
    t_q: np.ndarray,
    q: np.ndarray,
    compression: str = "none",
    lag: tuple[int, int] = (0, 0),
) -> None:
    """PointStamped targets and two-joint JointStates written by rosbags' rosbag2 writer (MCAP
    storage, ``compression`` none, message or file; ``lag``: log time minus stamp per topic)."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    if compression != "none":
        writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with writer:
        pc = writer.add_connection(
            "/tracker/point", "geometry_msgs/msg/PointStamped", typestore=store
        )
        jc = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for t, p in zip(t_pt.tolist(), xyz, strict=True):
            stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
            msg = T["geometry_msgs/msg/PointStamped"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="laser_tracker"),
                point=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
            )
            writer.write(pc, t + lag[0], store.serialize_cdr(msg, "geometry_msgs/msg/PointStamped"))
        for t, row in zip(t_q.tolist(), q, strict=True):
            stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
            msg = T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
                name=["shoulder", "elbow"],
                position=row,
                velocity=np.zeros(2),
                effort=np.zeros(0),
            )
            writer.write(jc, t + lag[1], store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


# ------------------------------------------------- the MCAP walk: late channels, loose messages


def _rewritten(tmp_path: Path) -> tuple[Path, bytes]:
    """The 0.1 mm sample log rewritten by the mcap library's writer in 4 KiB uncompressed
    chunks (many chunks: the walk runs behind the decompression)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    out = tmp_path / "small.mcap"
    with (
        open(Path(__file__).parents[1] / "sample_logs/kr5_0.1mm.mcap", "rb") as f,
        open(out, "wb") as g,
    ):
        w = Writer(g, chunk_size=4096, compression=CompressionType.NONE)
        w.start(profile="ros2", library="test")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, msg in make_reader(f).iter_messages(log_time_order=False):
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], channel.metadata
                )
            w.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time)
        w.finish()
    return out, out.read_bytes()


def _counts(path: Path, topics: list[str] | None = None) -> dict[str, int]:
    from dhlog.io.mcapscan import scan_mcap

    scan = scan_mcap(path, topics=topics)
    return {scan.channels[c].topic: len(m) for c, m in scan.messages.items()}


def test_channels_defined_only_after_their_chunks_keep_their_messages(tmp_path: Path) -> None:
    """Every Channel record inside the chunks made unknown (and DataEnd), so the channels are
    defined only by the summary, after every chunk: with a topic filter, the walk (which runs
    behind the decompression) kept only the last chunks' messages."""
    path, data = _rewritten(tmp_path)
    whole = _counts(path)
    b = bytearray(data)
    pos = 8
    while pos + 9 <= len(b):
        op = b[pos]
        (length,) = struct.unpack_from("<Q", b, pos + 1)
        if op == 6:  # a chunk: blank its channel records
            (name,) = struct.unpack_from("<I", b, pos + 9 + 28)
            p = pos + 9 + 32 + name
            (records,) = struct.unpack_from("<Q", b, p)
            q = p + 8
            while q < p + 8 + records:
                (size,) = struct.unpack_from("<Q", b, q + 1)
                if b[q] == 4:
                    b[q] = 0x80
                q += 9 + size
        if op == 0x0F:
            b[pos] = 0x80
            break
        pos += 9 + length
    late = tmp_path / "late.mcap"
    late.write_bytes(bytes(b))
    wanted = ["/tracker/point", "/joint_states"]
    assert _counts(late, wanted) == {k: v for k, v in whole.items() if k in wanted}
    assert _counts(late, ["/tracker/point"]) == {"/tracker/point": whole["/tracker/point"]}


def test_loose_messages_join_their_channels_chunked_ones(tmp_path: Path) -> None:
    """A message outside any chunk on a channel that also has chunked messages: the loose one
    replaced all the chunked ones (2 904 → 1)."""
    from dhlog.io.mcapscan import scan_mcap

    path, data = _rewritten(tmp_path)
    scan = scan_mcap(path)
    cid = next(c for c, i in scan.channels.items() if i.topic == "/tracker/point")
    before = len(scan.messages[cid])
    pos = 8
    while data[pos] != 0x0F:
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    body = struct.pack("<HIQQ", cid, 0, 10**18, 10**18) + scan.messages[cid].payload(0)
    mixed = tmp_path / "mixed.mcap"
    mixed.write_bytes(data[:pos] + bytes([5]) + struct.pack("<Q", len(body)) + body + data[pos:])
    again = scan_mcap(mixed)
    assert len(again.messages[cid]) == before + 1
    assert again.messages[cid].log_time[-1] == 10**18


def test_only_unread_topics_beside_the_target_of_its_type_are_named() -> None:
    """The hint of a further target names topics of the point stream's message type in its
    namespace that no stream reads — not a transform stream's other topics (``/tf_static``),
    not a point type elsewhere (RViz's ``/clicked_point``), not the base plane read."""
    from dhlog.io.mcapwalk import ChannelInfo
    from dhlog.io.reader import _unread_targets

    def channel(k: int, topic: str, kind: str) -> ChannelInfo:
        return ChannelInfo(k, topic, "cdr", kind, "ros2msg", b"")

    point = "geometry_msgs/msg/PointStamped"
    found = [
        channel(1, "/tracker/point", point),
        channel(2, "/tracker/point_2", point),
        channel(3, "/tracker/base_plane", point),
        channel(4, "/clicked_point", point),
        channel(5, "/tracker/smr_b", point),
        channel(6, "/joint_states", "sensor_msgs/msg/JointState"),
    ]
    channels = {c.id: c for c in found}
    infos = {"point": [found[0]], "base": [found[2]], "joints": [found[5]]}
    assert _unread_targets(channels, infos, []) == ["/tracker/point_2", "/tracker/smr_b"]
    assert _unread_targets(channels, infos, [[found[1]], [found[4]]]) == []
    tf = "tf2_msgs/msg/TFMessage"
    transforms = [channel(1, "/tf", tf), channel(2, "/tf_static", tf)]
    assert _unread_targets({c.id: c for c in transforms}, {"point": transforms[:1]}, []) == []


def test_a_zstd_compressed_log_is_decompressed_to_a_scratch_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A ``.mcap.zstd`` (rosbag2's file compression) reads as its plain file, decompressed a
    block at a time into a scratch file, not into memory; one cut short keeps what precedes the
    damage (as before); one that is not zstd past its magic, or decompressing to more than
    MAX_RATIO times its size, is one line naming the file."""
    import io

    import zstandard

    from dhlog.errors import InputError
    from dhlog.io import mcapscan

    plain = Path(__file__).parents[1] / "sample_logs" / "kr5_0.01mm.mcap"
    packed = tmp_path / "kr5.mcap.zstd"
    packed.write_bytes(zstandard.ZstdCompressor().compress(plain.read_bytes()))
    import tracemalloc

    tracemalloc.start()
    log = mcapscan._Log(packed)
    held = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    # a block at a time (it asked for a buffer of MAX_RATIO x the file: a MemoryError and a
    # traceback for any file beyond a few tens of MB)
    assert held < 4 * mcapscan.READ_AHEAD
    try:
        assert not isinstance(log.file, io.BytesIO) and log.file.fileno() >= 0
        assert log.size == plain.stat().st_size
        assert log.read(0, log.size) == plain.read_bytes()
    finally:
        log.close()
    a, b = read_log(packed), read_log(plain)
    assert a.points.equals(b.points) and a.joints is not None and b.joints is not None
    assert a.joints.equals(b.joints)
    cut = tmp_path / "cut.mcap.zstd"  # what precedes the cut is read, the damage said
    cut.write_bytes(packed.read_bytes()[: packed.stat().st_size // 2])
    part = read_log(cut)
    assert 0 < part.points.height < b.points.height
    assert any("cut short" in w for w in part.warnings)
    bad = tmp_path / "bad.mcap.zstd"
    bad.write_bytes(mcapscan.ZSTD_MAGIC + bytes(range(256)) * 64)
    with pytest.raises(InputError, match=r"bad\.mcap\.zstd: a zstd file that cannot be"):
        read_log(bad)
    monkeypatch.setattr(mcapscan, "MAX_RATIO", 1)
    with pytest.raises(InputError, match=r"decompresses to more than 1x its size"):
        read_log(packed)
