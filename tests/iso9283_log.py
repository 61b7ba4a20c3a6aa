"""A small ISO 9283 pose test written as a real ROS 2 MCAP log, with its truth (for
tests/test_iso9283_run.py and benchmarks/iso9283.py until they use ``dhlog simulate --protocol
iso9283``).

A KR5 off its nominal (each a, d 0.3 mm, each θ offset 0.3 mrad, seeded) visits five joint
targets in cycles P1 → P5 → P4 → P3 → P2 (the standard's); each visit's attained position is the
true model's forward kinematics of the commanded joints plus a random offset (``repeat`` m per
coordinate: the robot's repeatability) plus a linear drift; each arrival overshoots along its
approach with a damped oscillation. The tracker samples the target at ``rate`` Hz through the
motion and the dwells with ``noise`` m per coordinate. /joint_states follow the commanded
trajectory; /joint_command holds the current move's target (10 Hz). The truth holds each visit's
noise-free attained position.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.writer import CompressionType, Writer

from dhlog.io import ros2
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot

NAMES = [f"joint_{k + 1}" for k in range(6)]
#: the standard's cycle P1 → P5 → P4 → P3 → P2 (clause 7.2.1), as indices of P1 … P5
CYCLE = (0, 4, 3, 2, 1)
#: The five commanded joint targets (rad): a KR5 pose and four moves about it.
Q0 = np.radians([10.0, -60.0, 100.0, 5.0, 40.0, 10.0])
OFFSETS = np.radians(
    [
        [0, 0, 0, 0, 0, 0],
        [12, -6, 8, 0, -5, 0],
        [12, 6, -6, 4, 5, 0],
        [-12, 6, -6, 0, 5, 10],
        [-12, -6, 8, -4, -5, 0],
    ]
)


@dataclass
class IsoLog:
    """What :func:`write_iso_log` wrote: the log, the true model's file, and the truth."""

    log: Path
    true_model: Path
    targets: np.ndarray  # (5, 6) commanded joints P1 … P5
    #: per visit: pose index 0…4, the noise-free attained position (M), cycle (1-based)
    pose: list[int] = field(default_factory=list)
    attained: list[np.ndarray] = field(default_factory=list)
    cycle: list[int] = field(default_factory=list)
    T_measurement_base: np.ndarray = field(default_factory=lambda: np.eye(4))
    true_table: StandardDH | None = None
    tool: np.ndarray = field(default_factory=lambda: np.zeros(3))


def _true_robot(seed: int) -> tuple[StandardDH, np.ndarray]:
    kr5 = load_robot("kr5")
    rng = np.random.default_rng(seed)
    t = kr5.table
    table = StandardDH(
        t.joint_types,
        t.theta_offset + rng.normal(0, 3e-4, 6),
        t.d_offset + rng.normal(0, 3e-4, 6),
        t.a + rng.normal(0, 3e-4, 6),
        t.alpha + rng.normal(0, 3e-4, 6),
    )
    return table, kr5.tool_point


def _placement() -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("zyx", [150.0, 2.0, -1.0], degrees=True).as_matrix()
    T[:3, 3] = [2.5, -0.8, -0.9]
    return T


def write_true_model(path: Path, table: StandardDH, T: np.ndarray, tool: np.ndarray) -> None:
    """The true robot as a TOML DH file (metres, radians) with its placement and tool."""
    rows = "\n".join(
        f"[[standard_dh]]\ntheta_offset = {float(table.theta_offset[k])!r}\nd_offset = "
        f"{float(table.d_offset[k])!r}\na = {float(table.a[k])!r}\n"
        f"alpha = {float(table.alpha[k])!r}\n"
        for k in range(table.n)
    )
    base = (
        "[base]\nT_measurement_base = ["
        + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in T)
        + "]\n"
    )
    tool_text = "[tool]\npoint = [" + ", ".join(repr(float(v)) for v in tool) + "]\n"
    path.write_text(rows + "\n" + base + "\n" + tool_text, encoding="utf-8")


def write_iso_log(
    path: Path,
    *,
    cycles: int = 4,
    seed: int = 0,
    noise: float = 1e-5,
    rate: float = 100.0,
    repeat: float = 2e-5,
    overshoot: float = 2e-4,
    drift: float = 0.0,
    commanded: bool = True,
    move: float = 1.0,
    dwell: float = 2.0,
    cycle: tuple[int, ...] = CYCLE,
) -> IsoLog:
    """Write the test (see the module docstring); ``drift`` m per hour along x of the
    measurement frame; ``cycle``: the pose indices each cycle visits, in order."""
    rng = np.random.default_rng(seed + 1000)
    table, tool = _true_robot(seed)
    T = _placement()
    targets = Q0 + OFFSETS
    true_model = path.with_suffix(".true.toml")
    write_true_model(true_model, table, T, tool)
    out = IsoLog(path, true_model, targets, T_measurement_base=T, true_table=table, tool=tool)

    def fk(q: np.ndarray) -> np.ndarray:
        return np.asarray(fk_point(table, q, tool, T_base=T))

    order = [k for _ in range(cycles) for k in cycle]
    dt = 1.0 / rate
    t_all, xyz_all = [], []
    jt, jq, ct, cq = [], [], [], []
    t0 = 0.0
    q_prev = targets[order[0]] - np.radians(3.0)  # the start: a little off P1
    off_prev = np.zeros(3)
    tau, freq = 0.08, 4.0
    for j, k in enumerate(order):
        q = targets[k]
        off = rng.normal(0, repeat, 3) + np.array([drift * (t0 + move) / 3600.0, 0.0, 0.0])
        a_prev = fk(q_prev) + off_prev
        attained = fk(q) + off
        u = attained - a_prev
        u /= np.linalg.norm(u)
        t = np.arange(0.0, move + dwell, dt)
        s = np.clip(t / move, 0.0, 1.0)
        s = s * s * (3 - 2 * s)
        qs = q_prev + s[:, None] * (q - q_prev)
        p = fk(qs) + (1 - s)[:, None] * off_prev + s[:, None] * off
        after = np.clip(t - move, 0.0, None)
        wobble = overshoot * np.exp(-after / tau) * np.sin(2 * np.pi * freq * after)
        p += np.where(t > move, wobble, 0.0)[:, None] * u
        t_all.append(t0 + t)
        xyz_all.append(p)
        jt.append(t0 + t)
        jq.append(qs)
        tc = np.arange(0.0, move + dwell, 0.1)
        ct.append(t0 + tc)
        cq.append(np.tile(q, (tc.size, 1)))
        out.pose.append(k)
        out.attained.append(attained)
        out.cycle.append(j // len(cycle) + 1)
        t0 += move + dwell
        q_prev, off_prev = q, off
    start = 1_763_700_000_000_000_000
    t_pts = np.concatenate(t_all)
    xyz = np.concatenate(xyz_all) + rng.normal(0, noise, (t_pts.size, 3))

    def ns(t: np.ndarray) -> np.ndarray:
        return (start + np.round(t * 1e9)).astype(np.int64)

    streams = [
        (
            "/tracker/point",
            ros2.POINT_STAMPED,
            ns(t_pts),
            ros2.encode_point_stamped(ns(t_pts), xyz, "tracker"),
        ),
        (
            "/joint_states",
            ros2.JOINT_STATE,
            ns(np.concatenate(jt)),
            ros2.encode_joint_state(ns(np.concatenate(jt)), NAMES, np.concatenate(jq)),
        ),
    ]
    if commanded:
        tcs = ns(np.concatenate(ct))
        streams.append(
            (
                "/joint_command",
                ros2.JOINT_STATE,
                tcs,
                ros2.encode_joint_state(tcs, NAMES, np.concatenate(cq)),
            )
        )
    with open(path, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="tests/iso9283_log.py")
        schemas = {
            name: writer.register_schema(name, "ros2msg", ros2.MSGDEFS[name].encode())
            for name in (ros2.POINT_STAMPED, ros2.JOINT_STATE)
        }
        events: list[tuple[int, int, bytes]] = []
        for topic, schema, times, payloads in streams:
            cid = writer.register_channel(topic, "cdr", schemas[schema])
            events.extend((int(t), cid, p) for t, p in zip(times, payloads, strict=True))
        events.sort(key=lambda e: e[0])
        for stamp, channel, payload in events:
            writer.add_message(channel, stamp, payload, stamp)
        writer.finish()  # type: ignore[no-untyped-call]
    meta = {"pose": out.pose, "cycle": out.cycle, "attained": [a.tolist() for a in out.attained]}
    path.with_suffix(".iso.json").write_text(json.dumps(meta), encoding="utf-8")
    return out
