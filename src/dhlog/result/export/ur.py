"""A 6R result as the Universal Robots ROS 2 description's calibration file, in the factory's
shape: the ``kinematics:`` block ``ur_calibration`` writes from a robot's factory DH parameters
and ``ur_description`` loads (``config/<ur_type>/default_kinematics.yaml``, or the file given as
``kinematics_params_file``).

The factory's construction (``ur_calibration/src/calibration.cpp`` of the UR ROS 2 driver):
each DH row ``Rz(θ) Tz(d) Tx(a) Rx(α)`` is split in two segments, ``S_i = Rz(θ_i) Tz(d_i)``
(which turns with joint ``i``) and ``P_i = Tx(a_i) Rx(α_i)``; ``shoulder`` is ``S_1``, each
following entry ``P_(i-1) S_i`` (so ``shoulder.z`` = d1, ``forearm.x`` = a2, ``wrist_1.x`` = a3,
``wrist_1.z`` = d4, ``wrist_2.y`` = −d5, ``wrist_3.y`` = d6), and ``P_6`` (zero on a UR) is not
in the file. Before that, the ``d`` of joints 2 and 3 (ill-determined on the three parallel
axes) is moved onto joint 4 by the factory's axis correction, keeping the kinematics. The
description composes ``base_link`` → ``base_link_inertia`` (π about z) → each entry as the
joint's origin (``xyz``, URDF ``rpy``) → the joint about z; so ``base_link_inertia`` (and the
description's ``base`` frame, the controller's base) is DH frame 1.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw, wrap_angle
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable
from dhlog.model.dh import HayatiDH, JointType, StandardDH
from dhlog.result.check import MAX_RESULT_BYTES, read_limited
from dhlog.result.export.source import load_table
from dhlog.result.export.urdf import rpy_matrix

#: The UR description's joints, in chain order, and their entries in ``kinematics:``.
UR_ENTRIES = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: base_link → base_link_inertia, wrist_3_link → flange → tool0 in the UR description (rpy).
UR_BASE_INERTIA = (0.0, 0.0, math.pi)
UR_FLANGE = (0.0, -math.pi / 2, -math.pi / 2)
UR_TOOL0 = (math.pi / 2, 0.0, math.pi / 2)
#: The keys of one entry, in the factory file's order.
UR_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class URKinematics:
    """The six entries (x, y, z in m; roll, pitch, yaw in rad, URDF's fixed-axis convention),
    the target in ``tool0`` (m) and where the robot stands."""

    entries: tuple[tuple[float, float, float, float, float, float], ...]
    tcp: FloatArray
    #: base_link_inertia (DH frame 1 on the UR branch) in the measurement frame M, 4×4
    T_base: FloatArray


def _rz(theta: float) -> FloatArray:
    T = np.eye(4)
    c, s = math.cos(theta), math.sin(theta)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _tz(d: float) -> FloatArray:
    T = np.eye(4)
    T[2, 3] = d
    return T


def _segments(table: StandardDH) -> tuple[list[FloatArray], list[FloatArray], list[bool]]:
    """Each row at encoder zero as ``S_i = Rz(θ_i) Tz(d_i)`` and the rest ``P_i = S_i⁻¹ A_i``
    (``Tx(a) Rx(α)`` on a DH row, ``Tx(a) Rx(α) Ry(β)`` on a Hayati row), and whether a row is
    a DH row (the factory's axis correction applies to those)."""
    rows = table.link_transforms(np.zeros(table.n))
    hayati = table.hayati if isinstance(table, HayatiDH) else [False] * table.n
    S, P = [], []
    for i in range(table.n):
        s = _rz(float(table.theta_offset[i])) @ _tz(float(table.d_offset[i]))
        S.append(s)
        P.append(np.linalg.inv(s) @ rows[i])
    return S, P, [not h for h in hayati]


def _ur_branch(S: list[FloatArray], P: list[FloatArray], T_base: FloatArray) -> FloatArray:
    """The segments turned (in place) onto the UR arms' branch, and the base on it.

    A turn ``ψ_k`` of DH frame ``k + 1`` about its z axis (``S_k P_k → Rz(−ψ_(k−1)) S_k P_k
    Rz(ψ_k)``, the base ``T_base Rz(ψ_0)``) changes no forward kinematics: ψ = π negates ``a``
    and ``α`` of a row and moves θ by π. The rows are turned so that α1 > 0, a2 < 0, a3 < 0,
    α4 > 0, α5 < 0 and θ1 is within π/2 of zero, as in UR's published tables; a fit may return
    any of these branches."""
    # per row, the entry of P (sin α at [2, 1], a at [0, 3]) and the sign it must not have
    wrong = ((2, 1, -1.0), (0, 3, 1.0), (0, 3, 1.0), (2, 1, -1.0), (2, 1, 1.0))
    psi = [0.0] * 7  # psi[k]: the turn of DH frame k + 1 (psi[0]: the base)
    for row, (r, c, sign) in enumerate(wrong):
        psi[row + 1] = math.pi if sign * float(P[row][r, c]) > 0 else 0.0
    theta1 = math.atan2(float(S[0][1, 0]), float(S[0][0, 0])) + psi[1]
    psi[0] = math.pi if math.cos(theta1) < 0 else 0.0
    for i in range(len(S)):
        S[i] = _rz(psi[i + 1] - psi[i]) @ S[i]
        P[i] = _rz(-psi[i + 1]) @ P[i] @ _rz(psi[i + 1])
    return np.asarray(T_base @ _rz(psi[0]))


def _correct_axis(S: list[FloatArray], P: list[FloatArray], i: int) -> None:
    """The factory's axis correction of joint ``i`` (0-based; ``Calibration::correctAxis``):
    its ``d`` set to 0, its θ and ``a`` chosen so that the next joint's frame origin lies where
    the next axis meets joint ``i``'s xy plane (``a`` negative, as on every UR arm), and the next
    joint's ``d`` lengthened by the same move along its axis; the kinematics are unchanged."""
    d = float(S[i][2, 3])
    if d == 0.0:
        return
    theta = math.atan2(float(S[i][1, 0]), float(S[i][0, 0]))
    a = float(P[i][0, 3])
    alpha = math.atan2(float(P[i][2, 1]), float(P[i][2, 2]))
    root = S[i] @ P[i]
    origin, axis = root[:3, 3], root[:3, 2]
    if abs(float(axis[2])) < 1e-6:
        raise DHFileError(
            "result",
            f"joint {i + 2}'s axis lies in joint {i + 1}'s xy plane, which a UR calibration "
            "cannot hold; export a UR result.",
        )
    s = -float(origin[2]) / float(axis[2])
    point = origin + s * axis
    length = float(np.linalg.norm(point))
    if abs(a) > 0:  # a negative link length, as on every UR arm
        new_theta, new_a = math.atan2(float(point[1]), float(point[0])) - math.pi, -length
    else:
        new_theta, new_a = math.atan2(float(point[1]), float(point[0])), length
    S[i] = _rz(new_theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    P[i] = _rz(theta - new_theta)
    P[i][:3, :3] = P[i][:3, :3] @ np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    P[i][0, 3] = new_a
    S[i + 1] = S[i + 1] @ _tz(-s)


def factory_rpy(R: FloatArray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of ``R`` on the factory file's branch: the factory writes Eigen's
    x-y-z angles, whose roll lies in [0, π], so a roll near −π/2 is written as (roll + π,
    π − pitch, yaw + π), the same rotation (``wrist_3``: π/2, π, π). A roll within π/4 of zero
    keeps its sign, so a calibrated file diffs entry by entry against the factory one."""
    roll, pitch, yaw = roll_pitch_yaw(R)
    if roll < -math.pi / 4:
        roll, pitch, yaw = roll + math.pi, wrap_angle(math.pi - pitch), wrap_angle(yaw + math.pi)
    return roll, pitch, yaw


def ur_kinematics(
    table: StandardDH,
    tool_point: FloatArray,
    T_base: FloatArray,
    flange_d: float | None = None,
) -> URKinematics:
    """The factory-shaped entries of a six-joint revolute table, the target (``tool_point``, in
    the last DH frame) in the description's ``tool0``, and ``base_link_inertia`` in M.

    Past joint 6 the file has the flange at ``d6`` along axis 6 with θ6 = 0; the rest of the last
    row (θ6, a6, α6: zero on a UR, and on a fit the last frame's convention aiming it at the
    target) is carried by the TCP. ``flange_d``: the flange's ``d6`` (the nominal's), for a
    result whose target point cannot place the flange along axis 6; the TCP takes the rest.
    """
    S, P, dh_rows = _segments(table)
    for i in (1, 2):  # as the factory corrects its raw table, then onto UR's branch
        if dh_rows[i]:
            _correct_axis(S, P, i)
    base = _ur_branch(S, P, T_base)
    d6 = float(S[5][2, 3]) if flange_d is None else float(flange_d)
    last = S[5] @ P[5]  # joint 6's row at q6 = 0 past wrist_3's origin
    S[5] = _tz(d6)
    origins = [S[0]] + [P[i] @ S[i + 1] for i in range(5)]
    entries = []
    for T in origins:
        r, p, y = factory_rpy(T[:3, :3])
        x, yy, z = (float(v) for v in T[:3, 3])
        entries.append((x, yy, z, r, p, y))
    to_tool0 = rpy_matrix(*UR_FLANGE) @ rpy_matrix(*UR_TOOL0)
    flange_to_target = np.linalg.inv(S[5]) @ last
    tcp = (np.linalg.inv(to_tool0) @ flange_to_target @ np.r_[tool_point, 1.0])[:3]
    return URKinematics(tuple(entries), tcp, base)


def _number(value: float) -> str:
    """A value as the factory file writes it: 0 as ``0``, else the shortest exact repr."""
    return "0" if value == 0.0 else repr(float(value))


def ur_calibration(
    result_path: str | Path, nominal: StandardDH | None = None
) -> tuple[str, FloatArray]:
    """The UR description's calibration file of a 6R result in the factory's shape, and the
    target in ``tool0`` (m) — the TCP to set on the controller.

    ``nominal``: the robot's nominal table, whose d6 places the flange (a target point cannot:
    a result's last row puts it at the target's foot on axis 6, d6 = 0, and the TCP's z takes
    the flange offset); without it the file says so.

    ``hash`` names this calibration (``dhlog_`` + the result's SHA-256 prefix): the UR driver
    compares it with the controller's own calibration checksum and reports a mismatch, which is
    expected — this file describes the measured robot, not the controller's model.
    """
    source = str(result_path)
    _, table, model = load_table(result_path)
    if table.n != 6 or any(t is not JointType.REVOLUTE for t in table.joint_types):
        raise DHFileError(
            source, f"a UR calibration needs six revolute joints; this result has {table.n}."
        )
    if nominal is not None and nominal.n != 6:
        raise DHFileError(source, f"the nominal has {nominal.n} joints; a UR has six.")
    flange_d = None if nominal is None else float(nominal.d_offset[5])
    kin = ur_kinematics(table, model.tool_point, model.T_base, flange_d)
    tcp = kin.tcp
    base = ", ".join(f"{float(v):.17g}" for v in kin.T_base.ravel())
    flange = (
        f"# the flange at the nominal's d6 = {flange_d!r} m along axis 6."
        if flange_d is not None
        else "# d6 as the result has it (give the nominal, --nominal, for the flange's d6)."
    )
    digest = hashlib.sha256(read_limited(result_path, MAX_RESULT_BYTES, "result JSON"))
    lines = [
        f"# written by dhlog export from {printable(Path(source).name)}: the kinematics of the "
        "measured",
        "# robot in the shape of the UR factory calibration (ur_calibration) that the Universal",
        "# Robots ROS 2 description loads as kinematics_params_file. base_link_inertia (and the",
        "# description's base frame) = DH frame 1; joint zero = encoder zero. The target (TCP)",
        "# in tool0, in m (set it on the controller):",
        f"#   tcp: [{tcp[0]:.17g}, {tcp[1]:.17g}, {tcp[2]:.17g}]",
        flange,
        "# base_link_inertia in the measurement frame (4x4, row by row, m):",
        f"#   T_measurement_base: [{base}]",
        "kinematics:",
    ]
    for entry, values in zip(UR_ENTRIES, kin.entries, strict=True):
        lines.append(f"  {entry}:")
        lines.extend(
            f"    {key}: {_number(value)}" for key, value in zip(UR_KEYS, values, strict=True)
        )
    lines.append(f"  hash: dhlog_{digest.hexdigest()[:16]}")
    return "\n".join(lines) + "\n", tcp
