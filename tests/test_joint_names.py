"""Joints by name (io/jointnames.py), a permutation the data reveal (identify/check/permutation),
and ROS 2 bags in sqlite3 storage (io/sqlitebag.py): a simulated UR5 session recorded as
Universal Robots' ROS 2 driver publishes it (its joint names, in alphabetical order), written by
dhlog's MCAP writer and copied into rosbag2 sqlite3 bags by rosbags' writer."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.errors import DhlogError
from dhlog.identify.check.permutation import suspected_permutation
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import Identification, ProcessOptions, process_log
from dhlog.identify.segment.segment import segment_log
from dhlog.io.dhfile import DHModel, dh_model_from
from dhlog.io.jointnames import JointNamesMismatchError, chain_order, numbers
from dhlog.io.reader import read_log
from dhlog.io.writer import write_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

UR = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]
#: the driver's order: ros2_control's interfaces, alphabetical (elbow_joint first)
ALPHABETICAL = sorted(range(6), key=lambda k: UR[k])


@pytest.fixture(scope="module")
def session() -> Session:
    """A UR5 off its nominal (small geometric errors), random still poses, tracker noise."""
    cfg = SimulationConfig(
        seed=3,
        noise=2e-5,
        protocol="random-poses",
        poses=30,
        tracker_rate=50.0,
        joint_rate=20.0,
        perturb_angle=1e-3,
        perturb_length=5e-4,
    )
    return dataclasses.replace(simulate_session(load_robot("ur5"), cfg), joint_names=list(UR))


def reordered(session: Session, order: list[int], names: list[str] | None = None) -> Session:
    """The session with its joint-state columns (and names) in ``order``."""
    chosen = [(names or session.joint_names)[k] for k in order]
    return dataclasses.replace(session, joint_names=chosen, joint_q=session.joint_q[:, order])


@pytest.fixture(scope="module")
def logs(session: Session, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The session in chain order and as the driver orders it, as MCAP files."""
    out = tmp_path_factory.mktemp("names")
    paths = {"ordered": out / "ordered.mcap", "driver": out / "driver.mcap"}
    write_session(session, paths["ordered"])
    write_session(reordered(session, ALPHABETICAL), paths["driver"])
    return paths


def sqlite3_bag(mcap: Path, bag: Path, compression: str = "none") -> Path:
    """The MCAP file's messages copied into a rosbag2 bag in sqlite3 storage by rosbags'
    writer (``compression``: none, message or file, zstd)."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    writer = Writer(bag, version=8, storage_plugin=StoragePlugin.SQLITE3)
    if compression != "none":
        writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with open(mcap, "rb") as f, writer:
        connections = {}
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.topic not in connections:
                assert schema is not None
                connections[channel.topic] = writer.add_connection(
                    channel.topic, schema.name, typestore=store
                )
            writer.write(connections[channel.topic], message.log_time, message.data)
    return bag


def fk_rms_against_truth(result: Identification, session: Session) -> float:
    """RMS (m) of the result's FK from the truth's at random joint vectors within the limits."""
    ex = result.extraction
    assert ex is not None
    rng = np.random.default_rng(0)
    lim = load_robot("ur5").limits
    Q = rng.uniform(lim[:, 0], lim[:, 1], size=(500, 6)) * 0.5
    truth = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    return float(np.sqrt(np.mean(np.sum((got - truth) ** 2, axis=1))))


def processed(path: Path, nominal: DHModel | None = None) -> Identification:
    """``dhlog process PATH --nominal ur5 --model geometric``."""
    model = dh_model_from("ur5") if nominal is None else nominal
    return process_log(path, ProcessOptions(nominal=model, model=ModelRequest("geometric")))


@pytest.fixture(scope="module")
def ordered_result(logs: dict[str, Path]) -> Identification:
    return processed(logs["ordered"])


def assert_same_table(a: Identification, b: Identification) -> None:
    """Two results of the same samples: the same table, base and tool (to rounding: the
    decoded columns are the same numbers, the fit the same arithmetic)."""
    assert a.extraction is not None and b.extraction is not None
    x, y = a.extraction.standard, b.extraction.standard
    for field in ("theta_offset", "d_offset", "a", "alpha"):
        np.testing.assert_allclose(getattr(x, field), getattr(y, field), rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.extraction.tool_point, b.extraction.tool_point, atol=1e-9)
    assert a.validation is not None and b.validation is not None
    assert a.validation.rms == pytest.approx(b.validation.rms, rel=1e-6)


def test_the_drivers_order_gives_the_ordered_logs_table(
    logs: dict[str, Path], session: Session, ordered_result: Identification
) -> None:
    """The UR driver's alphabetical /joint_states with --nominal ur5: matched by name, the
    same table as the log in chain order, at the statistical limit (FK against the truth
    within 0.1 mm; it was 420 mm FK RMS when joined by position)."""
    driver = processed(logs["driver"])
    assert driver.log.joint_names == UR
    assert [j.name for j in driver.joints] == UR
    assert driver.log.joint_order is not None and driver.log.joint_order.how == "name"
    assert_same_table(driver, ordered_result)
    assert driver.implausible == ()
    assert driver.validation is not None and driver.validation.rms < 1e-4
    assert fk_rms_against_truth(driver, session) < 1e-4


@pytest.mark.parametrize("compression", ["none", "message", "file"])
def test_a_sqlite3_bag_reads_as_its_mcap(
    logs: dict[str, Path], tmp_path: Path, compression: str
) -> None:
    """The driver's log in rosbag2 sqlite3 storage (as Humble records by default), written by
    rosbags, uncompressed or zstd per message or per file: the same tables as the MCAP file."""
    bag = sqlite3_bag(logs["driver"], tmp_path / "bag", compression)
    assert list(bag.glob("*.db3*"))
    a, b = read_log(bag, joint_names=UR), read_log(logs["driver"], joint_names=UR)
    assert a.path == str(bag) and a.joint_names == b.joint_names == UR
    assert a.points.equals(b.points)
    assert a.joints is not None and b.joints is not None and a.joints.equals(b.joints)
    assert a.base is not None and b.base is not None and a.base.equals(b.base)
    assert a.pipeline_reason is not None and "sqlite3 storage" in a.pipeline_reason
    assert not any("dhlog-db3" in w for w in a.warnings)  # the copy is never named


def test_a_sqlite3_bag_processes_to_the_ordered_logs_table(
    logs: dict[str, Path], tmp_path: Path, ordered_result: Identification
) -> None:
    """``dhlog process BAG --nominal ur5`` on the driver's bag in sqlite3 storage, the bag
    folder and its .db3 file alone (without message definitions, as Humble writes it): the
    table of the ordered MCAP log."""
    bag = sqlite3_bag(logs["driver"], tmp_path / "bag")
    db3 = tmp_path / "humble.db3"
    db3.write_bytes(next(bag.glob("*.db3")).read_bytes())
    with sqlite3.connect(db3) as db:  # Humble's storage holds no message definitions
        db.execute("DELETE FROM message_definitions")
    assert_same_table(processed(bag), ordered_result)
    out = tmp_path / "out"
    run = CliRunner().invoke(
        app,
        ["process", str(db3), "--nominal", "ur5", "--model", "geometric", "--out", str(out)],
    )
    assert run.exit_code == 0, run.output
    document = json.loads((out / "humble.dh.json").read_text())
    assert [j["name"] for j in document["joints"]] == UR
    ex = ordered_result.extraction
    assert ex is not None
    np.testing.assert_allclose(
        [row["a"] for row in document["standard_dh"]], ex.standard.a, rtol=0, atol=1e-9
    )


def test_a_damaged_db3_is_one_error(tmp_path: Path) -> None:
    """A damaged .db3, a folder of .db3 files without its metadata.yaml: one error each."""
    folder = tmp_path / "copied"
    folder.mkdir()
    (folder / "run_0.db3").write_bytes(b"")
    with pytest.raises(DhlogError, match=r"without the bag's metadata\.yaml"):
        read_log(folder)
    bad = tmp_path / "broken.db3"
    bad.write_bytes(b"SQLite format 3\x00" + b"\x01" * 500)
    with pytest.raises(DhlogError, match=r"broken\.db3"):
        read_log(bad)
    run = CliRunner().invoke(app, ["process", str(bad), "--out", str(tmp_path / "o")])
    assert run.exit_code == 2 and "Traceback" not in run.output


def joint_state_bag(path: Path, session: Session, names_of: object) -> None:
    """The session's points and joint states written by rosbags (MCAP storage), message k's
    joints named and ordered by ``names_of(k)`` (a list of (name, value index or None: a
    gripper's joint, 0.01 rad))."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types

    def header(t: int) -> Any:
        stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id="")

    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        pc = writer.add_connection(
            "/tracker/point", "geometry_msgs/msg/PointStamped", typestore=store
        )
        jc = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for t, p in zip(session.point_t_ns.tolist(), session.point_xyz, strict=True):
            msg = T["geometry_msgs/msg/PointStamped"](
                header=header(t), point=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2])
            )
            writer.write(pc, t, store.serialize_cdr(msg, "geometry_msgs/msg/PointStamped"))
        for k, (t, q) in enumerate(zip(session.joint_t_ns.tolist(), session.joint_q, strict=True)):
            layout = names_of(k)  # type: ignore[operator]
            msg = T["sensor_msgs/msg/JointState"](
                header=header(t),
                name=[n for n, _ in layout],
                position=np.array([0.01 if i is None else q[i] for _, i in layout]),
                velocity=np.zeros(0),
                effort=np.zeros(0),
            )
            writer.write(jc, t, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))


def test_joints_are_matched_in_any_order_with_a_grippers_left_out(
    session: Session, tmp_path: Path
) -> None:
    """The order changes from message to message, a gripper's joint rides along, and a
    gripper's own joint states share the topic: the chain's joints are read by name, the
    gripper is left out and named once, its own messages left out."""
    rng = np.random.default_rng(1)

    def names_of(k: int) -> list[tuple[str, int | None]]:
        if k % 7 == 3:
            return [("robotiq_85_left_knuckle_joint", None)]
        layout: list[tuple[str, int | None]] = [(n, i) for i, n in enumerate(UR)]
        layout.append(("robotiq_85_left_knuckle_joint", None))
        return [layout[i] for i in rng.permutation(len(layout))]

    bag = tmp_path / "shuffled"
    joint_state_bag(bag, session, names_of)
    log = read_log(bag, joint_names=UR)
    assert log.joint_names == UR and log.joints is not None
    kept = np.arange(session.joint_t_ns.size) % 7 != 3
    np.testing.assert_array_equal(log.joints["t_ns"].to_numpy(), session.joint_t_ns[kept])
    np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), session.joint_q[kept])
    said = [w for w in log.warnings if "robotiq_85_left_knuckle_joint" in w]
    assert len(said) == 1 and "left out" in said[0]
    assert log.set_aside == {}


def test_names_behind_a_drivers_prefix_are_matched(session: Session, tmp_path: Path) -> None:
    """A driver started with a tf_prefix (``ur_``): matched by name behind it, said so."""
    path = tmp_path / "prefixed.mcap"
    write_session(reordered(session, ALPHABETICAL, [f"ur_{n}" for n in UR]), path)
    log = read_log(path, joint_names=UR)
    assert log.joint_names == [f"ur_{n}" for n in UR]
    assert log.joints is not None
    np.testing.assert_array_equal(log.joints.drop("t_ns").to_numpy(), session.joint_q)
    assert any("'ur_'" in w for w in log.warnings)


def test_names_that_do_not_match_are_one_error_naming_both(
    session: Session, tmp_path: Path
) -> None:
    """Another robot's names (or a nominal of another robot): one error naming the stream's
    and the nominal's names and the fix; through the CLI, exit 2 with no traceback."""
    path = tmp_path / "kuka.mcap"
    kuka = [f"joint_a{k + 1}" for k in range(6)]
    write_session(dataclasses.replace(session, joint_names=kuka), path)
    with pytest.raises(JointNamesMismatchError) as caught:
        read_log(path, joint_names=UR, joint_source="ur5")
    message = str(caught.value)
    assert "joint_a1" in message and "shoulder_pan_joint" in message
    assert "[joints] names" in message and "joints[].name" in message
    run = CliRunner().invoke(
        app, ["process", str(path), "--nominal", "ur5", "--out", str(tmp_path / "o")]
    )
    assert run.exit_code == 2 and "joint_a1" in run.output and "Traceback" not in run.output


def unnamed(model: DHModel) -> DHModel:
    """The nominal as a DH file without joints[].name gives it (joint_1 … joint_n)."""
    names = tuple(f"joint_{k + 1}" for k in range(model.table.n))
    return dataclasses.replace(model, joint_names=names)


def test_a_permutation_the_data_reveal_is_judged_implausible(
    session: Session, logs: dict[str, Path], tmp_path: Path
) -> None:
    """No names decide (a nominal without joint names; then a log without names, its columns
    numbered): the driver's order is found from the points — joints 1 and 3 swapped — and the
    result, still written, is judged implausible with the permutation and the fix named. The
    ordered log is not."""
    nominal = unnamed(dh_model_from("ur5"))
    found = processed(logs["driver"], nominal)
    assert len(found.implausible) == 1
    reason = found.implausible[0]
    assert "joint 1 = column 3 (shoulder_pan_joint)" in reason
    assert "joint 3 = column 1 (elbow_joint)" in reason
    assert "joints[].name" in reason and "[joints] names" in reason
    assert found.extraction is not None  # the result is kept
    assert suspected_permutation(segment_log(read_log(logs["ordered"])), nominal) is None
    # columns numbered in the log's order (an export's J1 … J6), the library's named nominal
    numbered = tmp_path / "numbered.mcap"
    columns = dataclasses.replace(
        reordered(session, ALPHABETICAL), joint_names=[f"J{k + 1}" for k in range(6)]
    )
    write_session(columns, numbered)
    log = read_log(numbered, joint_names=UR)
    assert log.joint_order is not None and log.joint_order.how == "number"
    permuted = suspected_permutation(segment_log(log), dh_model_from("ur5"))
    assert permuted is not None and permuted.order == (2, 1, 0, 3, 4, 5)
    assert permuted.as_given > 0.1 and permuted.rms < 5e-3  # decimetres against millimetres


def test_a_permutation_the_data_reveal_exits_with_the_implausible_code(
    session: Session, tmp_path: Path
) -> None:
    """The same through ``dhlog process``: columns numbered J1 … J6 in the driver's order and
    ``--nominal ur5``: the result is written, marked ``plausible: false`` with the permutation
    named, the console's last line says so, and the exit is 4 (EXIT_IMPLAUSIBLE), not 0."""
    numbered = tmp_path / "numbered.mcap"
    columns = dataclasses.replace(
        reordered(session, ALPHABETICAL), joint_names=[f"J{k + 1}" for k in range(6)]
    )
    write_session(columns, numbered)
    out = tmp_path / "o"
    run = CliRunner().invoke(
        app, ["process", str(numbered), "--nominal", "ur5", "--no-rrd", "--out", str(out)]
    )
    assert run.exit_code == 4, run.output
    assert "Traceback" not in run.output
    doc = json.loads((out / "numbered.dh.json").read_text())
    assert doc["plausible"] is False
    assert len(doc["implausible"]) == 1
    assert "joint 1 = column 3" in doc["implausible"][0]
    assert "implausible" in run.output.strip().splitlines()[-1]
    assert (out / "numbered.dh.csv").is_file()  # the rest is written too


@pytest.mark.parametrize(
    ("found", "model", "pipeline", "names", "how"),
    [
        (["b", "a"], ["a", "b"], None, ("a", "b"), "name"),
        (["wrist", "elbow", "grip"], ["elbow", "wrist"], None, ("elbow", "wrist"), "name"),
        (["joint_2", "joint_1"], None, None, ("joint_1", "joint_2"), "number"),
        (["A2", "A1"], ["x", "y"], None, ("A1", "A2"), "number"),
        (["b", "a"], None, None, ("b", "a"), "order"),
        (["b", "a"], ["joint_1", "joint_2"], None, ("b", "a"), "order"),
        (["b", "a"], ["x", "y"], ("a", "b"), ("a", "b"), "pipeline"),
        (["l/a", "l/b"], ["a", "b"], None, ("l/a", "l/b"), "prefix"),
    ],
)
def test_chain_order_rules(
    found: list[str],
    model: list[str] | None,
    pipeline: tuple[str, ...] | None,
    names: tuple[str, ...],
    how: str,
) -> None:
    got = chain_order(found, model, path="log", topic="/joint_states", pipeline=pipeline)
    assert (got.names, got.how) == (names, how)


@pytest.mark.parametrize(
    ("found", "model"),
    [
        (["b", "c"], ["a", "b"]),  # one missing
        (["left_a", "right_a", "b"], ["a", "b"]),  # two arms: a prefix matches twice
    ],
)
def test_chain_order_refuses_names_that_do_not_decide(found: list[str], model: list[str]) -> None:
    with pytest.raises(JointNamesMismatchError, match=r"\[a, b\]"):
        chain_order(found, model, path="log", topic="/joint_states")


def test_numbered_names() -> None:
    assert numbers(["joint_1", "J2", "A3", "axis 4", "q5", "theta6"]) == [1, 2, 3, 4, 5, 6]
    assert numbers(["joint_1", "joint_3"]) is None  # not 1 … n
    assert numbers(["elbow_joint"]) is None


def test_dhlog_import_keeps_the_joint_names(tmp_path: Path) -> None:
    """An export with a UR arm's joint columns (here in alphabetical order): ``dhlog import``
    writes them in chain order under their names, and the log is matched to ur5 by name."""
    rng = np.random.default_rng(2)
    q = rng.uniform(-90, 90, size=(12, 6))
    header = ["Point Name", "X [mm]", "Y [mm]", "Z [mm]"] + [f"{UR[k]} [deg]" for k in ALPHABETICAL]
    rows = [
        [f"P{i}", *map(str, rng.normal(size=3) * 500), *(str(q[i, k]) for k in ALPHABETICAL)]
        for i in range(12)
    ]
    export = tmp_path / "ur.csv"
    export.write_text("\n".join(",".join(r) for r in [header, *rows]) + "\n")
    run = CliRunner().invoke(app, ["import", str(export), "-o", str(tmp_path / "ur.mcap")])
    assert run.exit_code == 0, run.output
    log = read_log(tmp_path / "ur.mcap", joint_names=UR)
    assert log.joint_names == UR and log.joint_order is not None
    assert log.joint_order.how == "name" and log.joints is not None
    first = log.joints.drop("t_ns").to_numpy()[0]
    np.testing.assert_allclose(np.degrees(first), q[0], atol=1e-9)


def test_the_simulator_writes_the_drivers_joint_states(tmp_path: Path) -> None:
    """``dhlog simulate ur5 --driver-joints``: the joint states named and ordered as UR's
    driver publishes them, the truth in chain order under the same names; a robot without
    driver names is refused."""
    out = tmp_path / "ur5.mcap"
    args = ["simulate", "ur5", "-o", str(out), "--protocol", "random-poses", "--poses", "8"]
    run = CliRunner().invoke(app, [*args, "--driver-joints", "--joint-rate", "20"])
    assert run.exit_code == 0, run.output
    log = read_log(out)
    assert log.joint_names == [UR[k] for k in ALPHABETICAL]
    truth = json.loads((tmp_path / "ur5.truth.json").read_text())
    assert [j["name"] for j in truth["joints"]] == UR
    matched = read_log(out, joint_names=UR)
    assert log.joints is not None and matched.joints is not None
    np.testing.assert_array_equal(
        matched.joints.drop("t_ns").to_numpy(),
        log.joints.drop("t_ns").to_numpy()[:, np.argsort(ALPHABETICAL)],
    )
    refused = CliRunner().invoke(
        app, ["simulate", "puma560", "-o", str(tmp_path / "p.mcap"), "--driver-joints"]
    )
    assert refused.exit_code == 1 and "joint_names" in refused.output  # a usage error


def test_a_drivers_bag_validates_a_calibration_whose_log_numbered_its_joints(
    session: Session, logs: dict[str, Path], tmp_path: Path
) -> None:
    """A calibration from a log naming its joints joint_1 … joint_6 (an import's, a simulator's)
    with --nominal ur5, validated on the UR driver's bag (alphabetical, UR names): matched by
    the nominal's names, scored as the log in chain order (it was joined by position: 'no
    footing places' it, 659 mm, exit 4)."""
    numbered = tmp_path / "numbered.mcap"
    write_session(
        reordered(session, list(range(6)), [f"joint_{k + 1}" for k in range(6)]), numbered
    )
    result = process_log(
        numbered,
        ProcessOptions(
            nominal=dh_model_from("ur5"),
            model=ModelRequest("geometric"),
            validate=tuple([logs["driver"], logs["ordered"]]),
        ),
    )
    assert result.not_scored == () and result.implausible == ()
    scored = [h for h in result.holdout if h.kind == "log"]
    assert len(scored) == 2
    assert scored[0].calibrated.rms == pytest.approx(scored[1].calibrated.rms, rel=1e-9)
    assert scored[0].calibrated.rms < 1e-4
