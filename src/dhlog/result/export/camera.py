"""A camera calibration's hand-eye product for the exports: the result's ``camera``
block (or its ``cameras`` list) read untrusted (:func:`read_hand_eye`), placed in the URDF as
fixed links (:func:`add_camera_links`) and written as ROS 2 static transforms
(:func:`static_transforms_document`).

Frames, following ROS's conventions (REP 103, REP 105):

* ``<name>_optical_frame`` — the camera's frame as the calibration measured it: OpenCV's
  (x right, y down, z forward; REP 103's ``_optical`` suffix), the frame of ``T_base_camera``
  (``T_flange_camera``) and of the intrinsics;
* ``<name>_link`` — the same origin in REP 103's body axes (x forward, y left, z up), the frame a
  camera's mesh and its driver's other frames hang on; ``<name>_link`` → ``<name>_optical_frame``
  is the fixed turn rpy (−π/2, 0, −π/2) (quaternion −½, ½, −½, ½) every ROS camera driver uses;
* ``calibration_board`` — the board's frame (its corners' frame: the first corner's origin, x
  along the rows, z out of the printed face) where the calibration placed it.

``<name>`` is the camera's topic without its image-transport tail (``/camera/image_raw/compressed``
→ ``camera``, ``/camera/color/image_raw`` → ``camera_color``). The parents are the frames of the
URDF export: ``base_link`` (DH frame 1, the frame of the result's ``T_base_*``) for a camera or
board fixed in the cell, ``flange`` (DH frame n+1, of ``T_flange_*``) for one on the flange.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable
from dhlog.result.export.source import load_table
from dhlog.result.fields import FieldReader

#: ``<name>_link`` → ``<name>_optical_frame``: the optical axes (x right, y down, z forward) in
#: the body axes (x forward, y left, z up); rpy (−π/2, 0, −π/2).
T_LINK_OPTICAL = np.array(
    [[0.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
#: The URDF export's links the hand-eye poses are given in: the base (DH frame 1), the flange.
PARENTS = {"base": "base_link", "flange": "flange"}
#: The most cameras read from a result's ``cameras`` list.
MAX_CAMERAS = 64
#: How far from a rotation the 3×3 part of a pose may be (the JSON's digits round it).
ROTATION_TOLERANCE = 1e-6
#: The tail of an image topic that names its transport or encoding, not the camera.
_TRANSPORT = ("compressed", "compresseddepth", "theora", "zstd", "ffmpeg", "h264", "foxglove")
BOARD = "calibration_board"


@dataclass(frozen=True)
class PlacedFrame:
    """A frame the calibration placed: ``field`` (``T_base_camera``, …), ``parent`` (``base`` or
    ``flange``), ``T`` (4×4, m; the frame in its parent), the σ of its translation (m) and of a
    small rotation about the parent's x, y, z (rad; None: unknown)."""

    field: str
    parent: str
    T: FloatArray
    translation_std: tuple[float | None, ...]
    rotation_std: tuple[float | None, ...]


@dataclass(frozen=True)
class CameraFrames:
    """One camera: its ``topic``, ``setup``, the frames' stem ``name`` and its optical frame's
    pose (:class:`PlacedFrame`)."""

    topic: str
    setup: str
    name: str
    pose: PlacedFrame

    @property
    def link(self) -> str:
        return f"{self.name}_link"

    @property
    def optical_frame(self) -> str:
        return f"{self.name}_optical_frame"

    @property
    def T_parent_link(self) -> FloatArray:
        """``<name>_link`` in the parent: the optical frame's pose turned back to body axes."""
        return np.asarray(self.pose.T @ np.linalg.inv(T_LINK_OPTICAL), dtype=np.float64)


@dataclass(frozen=True)
class HandEye:
    """A result's hand-eye product: each camera's frames, and the board's (None: not given)."""

    cameras: tuple[CameraFrames, ...]
    board: PlacedFrame | None


def frame_name(topic: str) -> str:
    """A ROS frame stem from an image topic: its parts without the image and transport tail,
    joined by ``_``, each run of other characters than letters, digits and ``_`` one ``_``
    (``camera`` when nothing is left)."""
    parts = [p for p in topic.split("/") if p]
    while parts and (parts[-1].lower() in _TRANSPORT or parts[-1].lower().startswith("image")):
        parts.pop()
    name = re.sub(r"[^A-Za-z0-9_]+", "_", "_".join(parts)).strip("_")[:64]
    if not name:
        return "camera"
    return name if name[0].isalpha() else f"camera_{name}"


def _pose(f: FieldReader, block: dict[str, Any], at: str, field: str) -> PlacedFrame:
    """``<at>.<field>`` (a rigid 4×4, m) and ``<at>.<field>_std``."""
    where = f"{at}.{field}"
    rows = f.array(f.get(block, field, at, null=True), where)
    if len(rows) != 4:
        f.fail(where, f"must be a 4×4 matrix, not {len(rows)} rows")
    values = [f.vector(r, f"{where}[{k}]", 4) for k, r in enumerate(rows)]
    T = np.array(values, dtype=np.float64)
    R = T[:3, :3]
    if (
        np.max(np.abs(R.T @ R - np.eye(3))) > ROTATION_TOLERANCE
        or np.linalg.det(R) <= 0
        or np.max(np.abs(T[3] - [0.0, 0.0, 0.0, 1.0])) > ROTATION_TOLERANCE
    ):
        f.fail(where, "must be a rigid transform (a rotation, a translation, last row 0 0 0 1)")
    for k in range(3):
        f.number(T[k, 3], f"{where}[{k}][3]", "length")
    T[3] = [0.0, 0.0, 0.0, 1.0]
    std_at = f"{where}_std"
    std = f.get_obj(block, f"{field}_std", at)
    assert std is not None
    out: list[tuple[float | None, ...]] = []
    for key in ("translation_m", "rotation_rad"):
        values_std = f.vector(f.get(std, key, std_at, null=True), f"{std_at}.{key}", 3, null=True)
        for k, v in enumerate(values_std):
            if v is not None and v < 0:
                f.fail(f"{std_at}.{key}[{k}]", f"is {v:.6g}; a standard deviation is not negative")
        out.append(tuple(values_std))
    parent = "base" if field.startswith("T_base_") else "flange"
    return PlacedFrame(field, parent, T, out[0], out[1])


def _setup(f: FieldReader, block: dict[str, Any], at: str) -> str:
    setup = f.get_text(block, "setup", at)
    assert setup is not None
    if setup not in ("eye-to-hand", "eye-in-hand"):
        f.fail(f"{at}.setup", f"must be eye-to-hand or eye-in-hand, not {printable(setup)[:40]!r}")
    return setup


def _camera(f: FieldReader, block: dict[str, Any], at: str) -> CameraFrames:
    topic = f.get_text(block, "topic", at)
    assert topic is not None
    setup = _setup(f, block, at)
    field = "T_base_camera" if setup == "eye-to-hand" else "T_flange_camera"
    return CameraFrames(topic, setup, frame_name(topic), _pose(f, block, at, field))


def read_hand_eye(data: dict[str, Any], source: str) -> HandEye | None:
    """The result's hand-eye product, every field used checked (a fault a
    :class:`~dhlog.result.fields.ResultFieldError` naming the field); None: no ``camera`` block
    (a tracker's result). With a ``cameras`` list, its cameras (``camera`` is the first's)."""
    f = FieldReader(source)
    block = f.get_obj(data, "camera", required=False)
    listed = f.array_or_null(data.get("cameras"), "cameras", most=MAX_CAMERAS)
    if block is None and not listed:
        return None
    cameras: list[CameraFrames] = []
    for k, item in enumerate(listed or []):
        cameras.append(_camera(f, f.obj(item, f"cameras[{k}]"), f"cameras[{k}]"))
    board = None
    if block is not None:
        first = _camera(f, block, "camera")
        if not cameras:
            cameras.append(first)
        field = "T_flange_board" if first.setup == "eye-to-hand" else "T_base_board"
        board = _pose(f, block, "camera", field)
    taken = {"base"}  # base_link is the robot's
    named = []
    for cam in cameras:
        name, k = cam.name, 2
        while name in taken:
            name, k = f"{cam.name}_{k}", k + 1
        taken.add(name)
        named.append(CameraFrames(cam.topic, cam.setup, name, cam.pose))
    return HandEye(tuple(named), board)


# ---------------------------------------------------------------------------------------------
# the URDF


def camera_link_names(hand_eye: HandEye, prefix: str = "") -> list[str]:
    """The links and joints :func:`add_camera_links` adds (each name after ``prefix``)."""
    names = []
    for cam in hand_eye.cameras:
        names += [cam.link, cam.optical_frame, f"{cam.name}_joint", f"{cam.name}_optical_joint"]
    if hand_eye.board is not None:
        names += [BOARD, f"{BOARD}_joint"]
    return [prefix + name for name in names]


def add_camera_links(
    robot: ET.Element,
    hand_eye: HandEye,
    origin: Callable[[ET.Element, FloatArray], None],
    *,
    parents: dict[str, tuple[str, FloatArray]] | None = None,
    prefix: str = "",
) -> list[ET.Element]:
    """Add to ``robot`` (a URDF's root) each camera's ``<name>_link`` (fixed joint
    ``<name>_joint`` from its parent) and ``<name>_optical_frame`` (``<name>_optical_joint``),
    and the board's ``calibration_board``, each name after ``prefix``; ``origin(joint, T)``
    writes a joint's ``<origin>``; ``parents`` maps ``base``/``flange`` to a link of the URDF and
    that frame in it (default: ``base_link`` and ``flange`` themselves). A name the URDF already
    has gets a suffix. The elements added, in order."""
    where = parents or {role: (link, np.eye(4)) for role, link in PARENTS.items()}
    links = {e.get("name") for e in robot.iter("link")}
    joints = {e.get("name") for e in robot.iter("joint")}
    added: list[ET.Element] = []

    def unique(name: str, taken: set[str | None]) -> str:
        out, k = prefix + name, 2
        while out in taken:
            out, k = f"{prefix}{name}_{k}", k + 1
        taken.add(out)
        return out

    def fixed(parent: str, child: str, joint_name: str, T: FloatArray) -> None:
        added.append(ET.SubElement(robot, "link", name=child))
        joint = ET.SubElement(robot, "joint", name=unique(joint_name, joints), type="fixed")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        origin(joint, T)
        added.append(joint)

    for cam in hand_eye.cameras:
        link = unique(cam.link, links)
        optical = unique(cam.optical_frame, links)
        parent, T_parent_role = where[cam.pose.parent]
        fixed(parent, link, f"{cam.name}_joint", T_parent_role @ cam.T_parent_link)
        fixed(link, optical, f"{cam.name}_optical_joint", T_LINK_OPTICAL)
    if hand_eye.board is not None:
        board = unique(BOARD, links)
        parent, T_parent_role = where[hand_eye.board.parent]
        fixed(parent, board, f"{BOARD}_joint", T_parent_role @ hand_eye.board.T)
    return added


# ---------------------------------------------------------------------------------------------
# ROS 2 static transforms


def quaternion_xyzw(R: FloatArray) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w; w ≥ 0, ROS's order) of the rotation ``R`` (3×3)."""
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R).as_quat()
    if q[3] < 0:
        q = -q
    return float(q[0]), float(q[1]), float(q[2]), float(q[3])


def static_transform_args(T: FloatArray, parent: str, child: str) -> str:
    """``tf2_ros static_transform_publisher``'s arguments (ROS 2 Humble and later) for the
    transform ``T`` (4×4, m) of ``child`` in ``parent``."""
    x, y, z = (float(v) for v in T[:3, 3])
    qx, qy, qz, qw = quaternion_xyzw(T[:3, :3])
    numbers = (("x", x), ("y", y), ("z", z), ("qx", qx), ("qy", qy), ("qz", qz), ("qw", qw))
    return (
        " ".join(f"--{k} {v:.17g}" for k, v in numbers)
        + f" --frame-id {parent} --child-frame-id {child}"
    )


def _sigma(pose: PlacedFrame) -> str:
    def shown(values: tuple[float | None, ...], scale: float, digits: int) -> str:
        return " ".join("unknown" if v is None else f"{v * scale:.{digits}f}" for v in values)

    return (
        f"σ translation x y z {shown(pose.translation_std, 1e3, 4)} mm, rotation about "
        f"{PARENTS[pose.parent]}'s x y z {shown(pose.rotation_std, 180 / math.pi, 5)}° "
        f"({shown(pose.rotation_std, 1.0, 7)} rad)"
    )


def _node(lines: list[str], name: str, args: str) -> None:
    lines += [
        "  - node:",
        "      pkg: tf2_ros",
        "      exec: static_transform_publisher",
        f"      name: {name}",
        f'      args: "{args}"',
    ]


def static_transforms_document(result_path: str | Path) -> str:
    """A ROS 2 launch file (YAML; ``ros2 launch FILE``) of ``tf2_ros static_transform_publisher``
    nodes: each camera's ``<name>_link`` in its parent and ``<name>_optical_frame`` in
    ``<name>_link``, and the board's ``calibration_board``; each pose's σ in a comment, and the
    parent → optical frame transform as one ``ros2 run`` command. The frames are the URDF
    export's. A result without a ``camera`` block is refused."""
    source = printable(str(result_path))
    data, _, _ = load_table(result_path)
    hand_eye = read_hand_eye(data, source)
    if hand_eye is None:
        raise DHFileError(
            source,
            "has no camera block, so no hand-eye pose to export as static transforms (a "
            "tracker's result); give the result of a camera calibration, or export the model "
            "with --format urdf.",
        )
    lines = [
        f"# ROS 2 static transforms of the hand-eye calibration in {Path(source).name}, written "
        "by dhlog export.",
        "# Run: ros2 launch <this file>   (ROS 2 Humble or later: tf2_ros's --x ... --qw, "
        "--frame-id, --child-frame-id).",
        "# Frames as in dhlog export --format urdf: base_link = DH frame 1 (the result's base "
        "frame), flange = DH frame n+1",
        "# (another description's own flange may be turned from it, e.g. the UR description's; "
        "rename the frame ids to links that are these frames);",
        "# <camera>_optical_frame = the calibrated camera frame (OpenCV's: x right, y down, z "
        "forward; REP 103's optical frame),",
        "# <camera>_link = the same origin in body axes (x forward, y left, z up), turned to the "
        "optical frame by rpy (-pi/2, 0, -pi/2).",
        "# If your camera driver publishes its own <camera>_link -> optical frame, drop that node "
        "and publish the",
        "# parent -> optical frame transform given below in place of the parent -> link one.",
        "launch:",
    ]
    for cam in hand_eye.cameras:
        parent = PARENTS[cam.pose.parent]
        direct = static_transform_args(cam.pose.T, parent, cam.optical_frame)
        lines += [
            f"  # {cam.name}: {printable(cam.topic)[:200]}, {cam.setup}, {cam.pose.field}",
            f"  # {_sigma(cam.pose)}",
            f"  # {parent} -> {cam.optical_frame} directly: ros2 run tf2_ros "
            f"static_transform_publisher {direct}",
        ]
        _node(
            lines,
            f"{cam.link}_static_tf",
            static_transform_args(cam.T_parent_link, parent, cam.link),
        )
        _node(
            lines,
            f"{cam.optical_frame}_static_tf",
            static_transform_args(T_LINK_OPTICAL, cam.link, cam.optical_frame),
        )
    if hand_eye.board is not None:
        board = hand_eye.board
        parent = PARENTS[board.parent]
        lines += [f"  # {BOARD}: the board's corner frame, {board.field}", f"  # {_sigma(board)}"]
        _node(lines, f"{BOARD}_static_tf", static_transform_args(board.T, parent, BOARD))
    return "\n".join(lines) + "\n"
