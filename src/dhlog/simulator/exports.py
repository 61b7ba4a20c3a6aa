"""A simulated session of still poses as a laser tracker's 6-DoF export: one row a stop, as a
Leica Tracker Pilot or a T-Mac export writes it — ``Point Name``, ``X [mm]``, ``Y [mm]``,
``Z [mm]``, ``U(95)  [mm]`` (the 95 % radius of the mean position's 3-D error), the probe's
orientation as the quaternion ``Q0 Q1 Q2 Q3`` (scalar first: Q0 = w),
and the robot's joints ``j1 … jn`` (degrees; a prismatic joint's mm) — for
``dhlog import --format leica`` (``dhlog simulate --leica-export``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.model.dh import JointType
from dhlog.simulator.session import Session


class ExportError(DhlogError):
    """A session that cannot be written as a tracker's export."""


#: The 95 % radius of a 3-D isotropic Gaussian, in units of its σ per coordinate.
U95_FACTOR = 2.7954834829151074
#: the smallest U95 the export states, mm
U95_FLOOR_MM = 0.005


def stop_counts(session: Session) -> list[int]:
    """The tracker samples of each still pose (:func:`stop_means`' grouping)."""
    which = _stops(session)
    return [int(np.count_nonzero(which == k)) for k in range(session.poses.shape[0])]


def _stops(session: Session) -> np.ndarray:
    """Each tracker sample's still pose (−1: none)."""
    Q = session.poses
    t = session.point_t_ns.astype(np.float64)
    tj = session.joint_t_ns.astype(np.float64)
    q = np.column_stack([np.interp(t, tj, session.joint_q[:, j]) for j in range(Q.shape[1])])
    which = np.full(t.size, -1)
    for k, pose in enumerate(Q):
        which[np.max(np.abs(q - pose), axis=1) < 1e-6] = k
    return which


def stop_means(session: Session) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    """Each still pose's joint vector (k, n), the mean of its samples' positions (k, 3) and the
    chordal mean of their orientations (k, 3, 3; None without a 6-DoF probe): a sample belongs
    to the pose its encoders' values (interpolated at its stamp) are within 1 µrad of."""
    Q = session.poses
    if Q.size == 0 or session.joint_q.size == 0:
        raise ExportError(
            "a tracker's export holds one row a still pose: simulate a still-pose protocol "
            "(random-poses, line, curve) with encoders."
        )
    which = _stops(session)
    counts = np.bincount(which[which >= 0], minlength=Q.shape[0])
    if np.any(counts == 0):
        raise ExportError(
            f"{int(np.count_nonzero(counts == 0))} still pose(s) have no tracker sample: "
            "raise the tracker rate or the dwell."
        )
    P = np.stack([session.point_xyz[which == k].mean(axis=0) for k in range(Q.shape[0])])
    R = None
    if session.point_rotation is not None:
        R = np.stack(
            [
                nearest_rotation(session.point_rotation[which == k].sum(axis=0))
                for k in range(len(Q))
            ]
        )
    return Q, P, R


def leica_export(session: Session) -> str:
    """The session's still poses as a Leica 6-DoF export (see the module docstring)."""
    from scipy.spatial.transform import Rotation

    Q, P, R = stop_means(session)
    if R is None:
        raise ExportError("a 6-DoF export needs the probe's orientation: simulate --six-dof.")
    quat = Rotation.from_matrix(R).as_quat(scalar_first=True)
    revolute = np.array([t is JointType.REVOLUTE for t in session.joint_types])
    joints = np.where(revolute, np.degrees(Q), Q * 1e3)
    n = Q.shape[1]
    header = ["Point Name", "X [mm]", "Y [mm]", "Z [mm]", "U(95)  [mm]", "Q0", "Q1", "Q2", "Q3"]
    counts = np.array([max(c, 1) for c in stop_counts(session)], dtype=np.float64)
    # the 95 % radius of a 3-D Gaussian of σ per coordinate: 2.7955 σ, never below the
    # tracker's own floor (a tracker states no U95 under a few µm, whatever the scatter: a
    # quieter simulated session still exports what a real one would; dhlog import refuses a
    # U95 of under 1 µm σ as a unit slip)
    u95 = np.maximum(U95_FACTOR * session.config.noise / np.sqrt(counts) * 1e3, U95_FLOOR_MM)
    rows = [",".join([*header, *(f"j{j + 1}" for j in range(n))])]
    for k in range(Q.shape[0]):
        cells = [f"P{k + 1:04d}", *(f"{v * 1e3:.6f}" for v in P[k]), f"{u95[k]:.4f}"]
        cells += [f"{v:.9f}" for v in quat[k]]
        cells += [f"{v:.6f}" for v in joints[k]]
        rows.append(",".join(cells))
    return "\n".join(rows) + "\n"


def write_leica_export(session: Session, path: str | Path) -> None:
    """:func:`leica_export` written to ``path`` atomically."""
    from dhlog.io.writer import atomic_output

    text = leica_export(session).encode("utf-8")
    with atomic_output(path) as f:
        f.write(text)
