"""The attained positions of an ISO 9283 test carried into the robot's base frame.

With a calibration result, its ``T_measurement_base`` (the tracker where it stood for the
calibration) carries the attained positions into the base frame, and a tracker moved since the
calibration is named (:func:`_tracker_moved`); otherwise the nominal is registered on the
attained barycentres (a rigid best fit of its forward kinematics at the commanded joints,
:func:`dhlog.identify.fit.register.register_nominal`, the nominal's tool point kept): the fit
absorbs the part of the error a rigid motion explains, so AP is lower than against the
controller's own base frame — the report says so. Without a model the positions stay in the
measurement frame: repeatability, stabilisation and drift of the barycentre need no model;
accuracy is not computed.
"""

from __future__ import annotations

import numpy as np

from dhlog.errors import DhlogError, Iso9283Error
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel
from dhlog.iso9283.cycles import (
    Segmented,
)
from dhlog.model.fk import fk_point


def _base_positions(
    seg: Segmented,
    nominal: DHModel | None,
    calibrated: DHModel | None,
    notes: list[str],
) -> tuple[FloatArray | None, str, str]:
    """The transform from the measurement frame into the nominal's base frame (None: the
    report stays in the measurement frame), its frame's name and how it was found."""
    if calibrated is not None:
        T_mb = calibrated.T_base
        base = nominal.T_base if nominal is not None else np.eye(4)
        _tracker_moved(seg, calibrated, notes)
        return (
            base @ np.linalg.inv(T_mb),
            "base",
            f"the result's T_measurement_base ({calibrated.source}): the tracker where it stood "
            "for the calibration",
        )
    if nominal is None:
        return None, "measurement", "none: no model given (positions in the tracker's frame)"
    if seg.pose_q is None:
        notes.append(
            "no commanded joints: the nominal cannot be registered; positions stay in the "
            "tracker's frame and accuracy is not computed."
        )
        return None, "measurement", "none: no commanded joints to register the nominal on"
    from dhlog.identify.fit.register import register_nominal

    named = [(k, seg.of_pose(n)) for k, n in enumerate(seg.poses) if seg.of_pose(n)]
    if len(named) < 3:
        notes.append(
            f"{len(named)} pose(s) visited: the nominal needs three to be registered on; "
            "accuracy is not computed (give --result)."
        )
        return None, "measurement", "none: fewer than three poses to register the nominal on"
    Q = np.array([seg.pose_q[k] for k, _ in named])
    P = np.array([np.mean([v.position for v in vs], axis=0) for _, vs in named])
    try:
        reg = register_nominal(nominal.table, Q, P, tool_point=nominal.tool_point, fit_tool=False)
    except (DhlogError, np.linalg.LinAlgError) as exc:  # a degenerate set of poses
        notes.append(f"the nominal could not be registered on the poses ({exc}).")
        return None, "measurement", "none: the registration failed"
    if reg.rms > FAR_RMS:
        raise Iso9283Error(
            "the base frame",
            f"the nominal {nominal.source}, placed as well as it can be on the {len(named)} poses' "
            f"attained barycentres, misses them by {reg.rms * 1e3:.1f} mm RMS — no robot's "
            f"nominal is that far off",
            "check that --nominal is this robot's, that the log's lengths are in the pipeline's "
            "unit and that the commanded joints are in radians",
        )
    notes.append(
        "the base frame is the nominal registered on the attained barycentres (a rigid best fit): "
        "it absorbs the error a rigid motion explains, so AP is lower than against the "
        "controller's base; give --result for the calibration's placement."
    )
    return (
        nominal.T_base @ np.linalg.inv(reg.T_measurement_base),
        "base",
        f"the nominal registered on the {len(named)} poses' attained barycentres (rigid best "
        f"fit, RMS {reg.rms * 1e3:.3f} mm)",
    )


#: A model that misses the poses by more than this RMS (m) after its best rigid placement is not
#: this robot's (or the log's units or the commanded joints' are not what they are read as): a
#: real robot's nominal is off by millimetres at most.
FAR_RMS = 0.01


#: A tracker moved since the calibration: the calibrated model, placed by the result, misses the
#: test's barycentres by more than this RMS (m) ...
MOVED_RMS = 1e-4


#: ... and a rigid re-placement of the model on them removes this much of it (RMS ratio): a
#: model error is not rigid; a tracker moved (or knocked) is.
MOVED_RATIO = 3.0


def _tracker_moved(seg: Segmented, calibrated: DHModel, notes: list[str]) -> None:
    """Say so where the result's placement of the tracker does not hold for this test: the
    calibrated model at the commanded joints misses the attained barycentres by more than
    :data:`MOVED_RMS`, and a rigid re-placement of the same model removes most of it
    (:data:`MOVED_RATIO`): the tracker stood elsewhere than for the calibration, and AP before
    and after (both in the result's base frame) carry that move."""
    if seg.pose_q is None:
        return
    named = [(k, seg.of_pose(n)) for k, n in enumerate(seg.poses) if seg.of_pose(n)]
    if len(named) < 3:
        return
    from dhlog.identify.fit.register import register_nominal

    Q = calibrated.joint_values(np.array([seg.pose_q[k] for k, _ in named]))
    P = np.array([np.mean([v.position for v in vs], axis=0) for _, vs in named])
    predicted = fk_point(calibrated.table, Q, calibrated.tool_point, T_base=calibrated.T_base)
    placed = float(np.sqrt(np.mean(np.sum((P - predicted) ** 2, axis=1))))
    if placed <= MOVED_RMS:
        return
    try:
        reg = register_nominal(
            calibrated.table, Q, P, tool_point=calibrated.tool_point, fit_tool=False
        )
    except (DhlogError, np.linalg.LinAlgError):  # a degenerate set of poses: nothing to say
        return
    if reg.rms > FAR_RMS:
        raise Iso9283Error(
            "the base frame",
            f"the calibration {calibrated.source}, placed as well as it can be on the "
            f"{len(named)} poses' barycentres, misses them by {reg.rms * 1e3:.1f} mm RMS",
            "check that --result is this robot's calibration and the log's lengths are in the "
            "pipeline's unit",
        )
    if placed > MOVED_RATIO * reg.rms:
        notes.append(
            f"the tracker has likely moved since the calibration: the calibrated model, placed "
            f"by {calibrated.source}'s T_measurement_base, misses the {len(named)} poses' "
            f"barycentres by {placed * 1e3:.3f} mm RMS, and a rigid re-placement of it by "
            f"{reg.rms * 1e3:.3f} mm; AP before and after carry the move. Measure the test "
            "with the tracker where it stood for the calibration, or run without --result "
            "(the nominal registered on the poses)."
        )


def _moved(T: FloatArray | None, p: FloatArray) -> FloatArray:
    return p if T is None else np.asarray(p @ T[:3, :3].T + T[:3, 3], dtype=np.float64)
