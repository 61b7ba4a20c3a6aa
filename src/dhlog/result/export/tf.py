"""A result as ROS 2 tf (``--format tf``): a launch file (YAML; ``ros2 launch FILE``) that puts the
calibrated robot into tf (:func:`tf_document`).

For a tracker's result the launch file publishes, as ``tf2_ros static_transform_publisher``
nodes (ROS 2 Humble and later: ``--x … --qw --frame-id --child-frame-id``):

* the robot's base → the tracker's measurement frame (``base_link`` → ``measurement``, the
  inverse of the result's ``T_measurement_base``): the tracker's frame as a child of the robot,
  so that it never gives a frame a second parent (the robot's root often has one, ``world``);
* the flange → the measured target (``flange`` → ``tool0``: the result's tool point);

in the frames of ``dhlog export --format urdf`` (``base_link`` = DH frame 1, ``flange`` = DH
frame n+1); with a template, in the template's own links (its root → ``dhlog_measurement``, its
last moving joint's child → ``dhlog_target``), placed as the calibrated template places them.

The calibrated joints themselves reach tf through ``robot_state_publisher`` with the calibrated
URDF: the launch argument ``description`` (a URDF path) starts it (``robot_description`` =
the file's text) and, since that URDF already holds both frames as fixed joints, leaves the two
static publishers out. A camera calibration's result gives its hand-eye frames
(:func:`dhlog.result.export.camera.static_transforms_document`).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable
from dhlog.result.export.camera import (
    read_hand_eye,
    static_transform_args,
    static_transforms_document,
)
from dhlog.result.export.expand import read_description
from dhlog.result.export.source import load_table
from dhlog.result.export.template import calibrate_template
from dhlog.result.export.urdf import rpy_matrix

#: the launch argument that starts robot_state_publisher with a calibrated URDF
DESCRIPTION_ARG = "description"


def _fixed_joint(robot: ET.Element, name: str) -> tuple[str, FloatArray]:
    """A fixed joint the calibrated template added: its parent link and origin (4×4)."""
    joint = next(j for j in robot.findall("joint") if j.get("name") == name)
    parent = joint.find("parent")
    origin = joint.find("origin")
    assert parent is not None and origin is not None  # written by calibrate_template
    T = rpy_matrix(*(float(v) for v in origin.get("rpy", "0 0 0").split()))
    T[:3, 3] = [float(v) for v in origin.get("xyz", "0 0 0").split()]
    return str(parent.get("link")), T


def _static(lines: list[str], name: str, args: str, condition: str) -> None:
    lines += [
        "  - node:",
        "      pkg: tf2_ros",
        "      exec: static_transform_publisher",
        f"      name: {name}",
        f"      args: {json.dumps(args)}",
        f"      unless: {json.dumps(condition)}",
    ]


def tf_document(
    result_path: str | Path,
    *,
    template: str | Path | None = None,
    joint_names: tuple[str, ...] = (),
    xacro_args: Mapping[str, str] | None = None,
) -> str:
    """The launch file of a result: a camera calibration's hand-eye frames, or a tracker
    result's robot frames (the module's docstring) — with ``template`` (a URDF, or a xacro
    expanded first) in its links, its joints matched by ``joint_names`` (default the result's)."""
    source = printable(str(result_path))
    data, _, model = load_table(result_path)
    if read_hand_eye(data, source) is not None:
        if template is not None:
            raise DHFileError(
                source,
                "is a camera calibration, whose static transforms are in the URDF export's "
                "frames; export them without --template.",
            )
        return static_transforms_document(result_path)
    if template is None:
        frames = [
            ("base_link", "measurement", np.asarray(np.linalg.inv(model.T_base), np.float64)),
            ("flange", "tool0", _translation(model.tool_point)),
        ]
        described = f"dhlog export {Path(source).name} --format urdf"
    else:
        robot, src = read_description(template, xacro_args)
        calibrate_template(result_path, robot, src, joint_names=joint_names)
        root, B = _fixed_joint(robot, "dhlog_measurement_fixed")
        last, T_target = _fixed_joint(robot, "dhlog_target_fixed")
        frames = [(root, "dhlog_measurement", B), (last, "dhlog_target", T_target)]
        described = f"dhlog export {Path(source).name} --format urdf --template {Path(src).name}"
    names = ", ".join(f"{parent} -> {child}" for parent, child, _ in frames)
    condition = f'$(eval \'"$(var {DESCRIPTION_ARG})" != ""\')'
    command = f"$(command 'cat $(var {DESCRIPTION_ARG})')"
    lines = [
        f"# ROS 2 tf of the calibration in {Path(source).name}, written by dhlog export.",
        "# Run: ros2 launch <this file>   (ROS 2 Humble or later: tf2_ros's --x ... --qw, "
        "--frame-id, --child-frame-id).",
        f"# Static transforms {names}: the tracker's measurement frame and the measured",
        "# target in the robot's frames"
        + (
            " (base_link = DH frame 1, flange = DH frame n+1, as in --format urdf;"
            if template is None
            else " (the template's links, placed as the calibrated template places them;"
        ),
        "# rename the frame ids to links of your description that are these frames).",
        "# The calibrated joints: the URDF written by",
        f"#   {described} -o robot.urdf",
        f"# published by robot_state_publisher: ros2 launch <this file> {DESCRIPTION_ARG}:="
        "robot.urdf",
        "# (that URDF holds both frames above as fixed joints, so the static publishers are "
        "then left out).",
        "launch:",
        "  - arg:",
        f"      name: {DESCRIPTION_ARG}",
        '      default: ""',
        '      description: "a calibrated URDF for robot_state_publisher (empty: none)"',
        "  - node:",
        "      pkg: robot_state_publisher",
        "      exec: robot_state_publisher",
        "      name: robot_state_publisher",
        "      param:",
        "        - name: robot_description",
        f"          value: {json.dumps(command)}",
        f"      if: {json.dumps(condition)}",
    ]
    for parent, child, T in frames:
        _static(lines, f"{child}_static_tf", static_transform_args(T, parent, child), condition)
    return "\n".join(lines) + "\n"


def _translation(p: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, 3] = p
    return T
