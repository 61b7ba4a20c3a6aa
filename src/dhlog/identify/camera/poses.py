"""Each frame's board pose by OpenCV's PnP (:func:`board_poses`), those poses as a 6-DoF target's
log for the tracker's run to start from (:func:`pose_log`), the corners as the pixel fit takes
them (:func:`corners_of`, :func:`stacked`), and PnP refined from where a result puts the board
(:func:`refined_poses`, :func:`pnp_points`: the mm figure of the held-out check).
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import polars as pl
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.pixels import Corners, PixelFit
from dhlog.identify.fit.axismodel import ParameterLayout
from dhlog.identify.fit.prediction import predict as predict_points
from dhlog.identify.fit.prediction import predict_orientation
from dhlog.io.pipeline import pipeline_by_name
from dhlog.io.reader import LogData
from dhlog.vision.camera import Intrinsics, planar_pose

#: the largest PnP reprojection RMS (px) a frame's pose may have to enter the start
PNP_RMS = 5.0


def transform(R: FloatArray, t: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def shift(o: FloatArray) -> FloatArray:
    return transform(np.eye(3), o)


# ---------------------------------------------------------------------------------------------
# PnP


def board_poses(obs: Observations, intrinsics: Intrinsics) -> tuple[FloatArray, FloatArray]:
    """Each frame's board pose in the camera (f, 4, 4) by OpenCV's PnP (IPPE for a planar
    board, refined by Levenberg–Marquardt), and its reprojection RMS (f,) px (NaN: failed)."""
    points = obs.board.object_points()
    f = obs.frames
    T = np.tile(np.eye(4), (f, 1, 1))
    rms = np.full(f, np.nan)
    fisheye = intrinsics.model == "equidistant"
    for k in range(f):
        obj = points[obs.ids[k]].astype(np.float64)
        uv = obs.uv[k].astype(np.float64).reshape(-1, 1, 2)
        if obj.shape[0] < 4:
            continue
        if fisheye:
            norm = cv2.fisheye.undistortPoints(uv, intrinsics.K, intrinsics.coefficients)
            K, D = np.eye(3), np.zeros(5)
            img = norm
        else:
            K, D, img = intrinsics.K, intrinsics.coefficients, uv
        pose = planar_pose(obj, np.asarray(img, dtype=np.float64), K, D)
        if pose is None:
            continue
        R, t = pose
        T[k] = transform(R, t)
        X = obj @ R.T + t
        pred = intrinsics.project(X)
        rms[k] = float(np.sqrt(np.nanmean(np.sum((pred - obs.uv[k]) ** 2, axis=1))))
    return T, rms


def pose_log(
    obs: Observations, T_cam_board: FloatArray, setup: str, use: NDArray[np.bool_]
) -> LogData:
    """The frames' poses as a 6-DoF target's log (the tracker run's input): the board's centre
    in the camera (eye-to-hand) or the camera in the board's centred frame (eye-in-hand)."""
    from dhlog.io.decode.frames import ORIENTATION_COLUMNS

    o = board_centre(obs)
    T = T_cam_board[use] @ shift(o)
    if setup == "eye-in-hand":
        T = np.asarray(np.linalg.inv(T), dtype=np.float64)
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat(canonical=True)
    t = obs.t_ns[use]
    points = pl.DataFrame({"t_ns": t, "x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3]})
    points = points.with_columns(
        pl.Series(name, quat[:, k]) for k, name in enumerate(ORIENTATION_COLUMNS)
    )
    # the joint values at each frame, as the encoders' stream: one sample at each frame's stamp
    q = obs.q[use]
    joints = pl.DataFrame({"t_ns": t, **{f"q_{j + 1}": q[:, j] for j in range(q.shape[1])}})
    base = pipeline_by_name("ros2_tracker")
    assert base is not None
    point = replace(base.streams["point"], orientation=True)
    # the encoders are known at the frames only: a joint's motion is judged over the frames
    # around each (1.5 frame intervals each side), not the tracker's 50 ms
    gaps = np.diff(t)
    spacing = float(np.median(gaps)) * 1e-9 if gaps.size else 0.0
    window = max(base.segmentation.motion_window, 1.5 * spacing)
    # and they were joined at each frame's stamp already (frames.observe): no clock offset to find
    segmentation = replace(
        base.segmentation,
        motion_window=min(window, 3600.0),
        clock_offset=0.0,
        clock_offset_fixed=True,
    )
    pipe = replace(base, streams={**base.streams, "point": point}, segmentation=segmentation)
    return LogData(obs.path, pipe, points, joints, list(obs.joint_names), None, None)


def board_centre(obs: Observations) -> FloatArray:
    """The board's centre in its frame (the carried frame's origin: better conditioned than
    a corner of the board)."""
    pts = obs.board.object_points()
    centre: FloatArray = np.asarray((pts.min(axis=0) + pts.max(axis=0)) / 2.0, dtype=np.float64)
    return centre


def corners_of(obs: Observations, use: NDArray[np.bool_]) -> Corners:
    """The pixel observations of the frames ``use``, the corners from the board's centre."""
    points = obs.board.object_points() - board_centre(obs)
    frames = np.flatnonzero(use)
    ids = [obs.ids[k] for k in frames]
    counts = np.array([i.size for i in ids], dtype=np.intp)
    return Corners(
        obs.q[use],
        np.repeat(np.arange(frames.size, dtype=np.intp), counts),
        points[np.concatenate(ids)] if ids else np.zeros((0, 3)),
        np.vstack([obs.uv[k] for k in frames]) if ids else np.zeros((0, 2)),
    )


def of_frames(obs: Observations, frames: tuple[int | None, int | None]) -> Observations:
    """``obs`` with the frames whose index on the topic is in ``[first, end)`` only (None: from
    the first, to the last); the tally and kept images as they were."""
    first = -1 if frames[0] is None else frames[0]
    end = np.iinfo(np.int64).max if frames[1] is None else frames[1]
    keep = (obs.frame >= first) & (obs.frame < end)
    chosen = np.flatnonzero(keep)
    return replace(
        obs,
        t_ns=obs.t_ns[keep],
        frame=obs.frame[keep],
        q=obs.q[keep],
        ids=[obs.ids[k] for k in chosen],
        uv=[obs.uv[k] for k in chosen],
        warnings=(
            *obs.warnings,
            f"--frames {'' if frames[0] is None else frames[0]}:"
            f"{'' if frames[1] is None else frames[1]}: {chosen.size} of {obs.frames} frames "
            "with the board kept.",
        ),
    )


def refined_poses(
    obs: Observations, fit: PixelFit, data: Corners, use: NDArray[np.bool_]
) -> FloatArray:
    """Each frame's board pose in the camera (f, 4, 4) by PnP refined (OpenCV's
    Levenberg–Marquardt) from where the fitted model puts the board: the frame's own pose in
    the result's basin (a planar board's pose has a mirror solution of nearly the same
    reprojection error at oblique views, which a PnP from scratch may take), from the corners
    ``use`` (N,) only (the fit's inliers)."""
    model = fit.whole.model
    layout = ParameterLayout.of(model.types, rotation=True)
    p, _ = predict_points(model, data.Q)
    R, _ = predict_orientation(model, data.Q, layout, model.bases())
    o = board_centre(obs)
    c = fit.measurement.intrinsics
    points = obs.board.object_points()
    T = np.tile(np.eye(4), (data.frames, 1, 1))
    spans = data.frame_slices()
    for f in range(data.frames):
        carried = transform(R[:, :, f], p[f])
        if fit.measurement.setup == "eye-to-hand":
            T0 = carried @ shift(-o)
        else:
            T0 = np.linalg.inv(carried) @ shift(-o)
        mine = use[spans[f]]
        if np.count_nonzero(mine) < 4:
            T[f] = T0
            continue
        obj = points[obs.ids[f]][mine]
        uv = obs.uv[f][mine].reshape(-1, 1, 2).astype(np.float64)
        if c.model == "equidistant":
            img, K, D = cv2.fisheye.undistortPoints(uv, c.K, c.coefficients), np.eye(3), np.zeros(5)
        else:
            img, K, D = uv, c.K, c.coefficients
        rvec0 = np.asarray(cv2.Rodrigues(T0[:3, :3])[0], dtype=np.float64).reshape(3, 1)
        tvec0 = np.ascontiguousarray(T0[:3, 3], dtype=np.float64).reshape(3, 1)
        try:  # (OpenCV takes a (3,) tvec without complaint and returns garbage rotations)
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, D, rvec0.copy(), tvec0.copy())
        except cv2.error:
            T[f] = T0
            continue
        T[f] = transform(
            np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64),
            np.asarray(tvec, dtype=np.float64).ravel(),
        )
    return T


def pnp_points(
    obs: Observations, T_cb: FloatArray, data: Corners, sigma_px: float
) -> tuple[FloatArray, FloatArray]:
    """Each corner where its frame's PnP pose puts it in the camera (N, 3), and the variance
    (N,: the trace of its 3×3 covariance, m²) the pose's own noise gives it: the pose's
    covariance ``σ² (JᵀJ)⁻¹`` from OpenCV's projection Jacobian at the corners' σ."""
    X = np.empty((data.uv.shape[0], 3))
    var = np.full(data.uv.shape[0], np.nan)
    points = data.points + board_centre(obs)
    c = obs.intrinsics
    for f, at in enumerate(data.frame_slices()):
        T = T_cb[f]
        X[at] = points[at] @ T[:3, :3].T + T[:3, 3]
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        try:
            if c.model == "equidistant":
                _, J = cv2.fisheye.projectPoints(
                    points[at].reshape(1, -1, 3), rvec, T[:3, 3], c.K, c.coefficients
                )
                J = np.asarray(J).reshape(-1, 15)[:, 8:14]
            else:
                _, J = cv2.projectPoints(points[at], rvec, T[:3, 3], c.K, c.coefficients)
                J = np.asarray(J)[:, :6]
            cov = np.linalg.inv(J.T @ J) * sigma_px**2  # (rvec, t)
        except (cv2.error, np.linalg.LinAlgError):
            continue
        # a corner moves by −[R x]× δr (to first order, δr about the rotation vector) + δt:
        # A = [−[R x]× Jr, I] (k, 3, 6), its variance the trace of A cov Aᵀ, every corner at once
        Rx = points[at] @ T[:3, :3].T
        skew = np.zeros((Rx.shape[0], 3, 3))
        skew[:, 0, 1], skew[:, 0, 2] = -Rx[:, 2], Rx[:, 1]
        skew[:, 1, 0], skew[:, 1, 2] = Rx[:, 2], -Rx[:, 0]
        skew[:, 2, 0], skew[:, 2, 1] = -Rx[:, 1], Rx[:, 0]
        A = np.concatenate(
            [-skew @ _rodrigues_jacobian(rvec.ravel()), np.broadcast_to(np.eye(3), skew.shape)],
            axis=2,
        )
        var[at] = np.einsum("kij,jl,kil->k", A, cov, A)
    return X, var


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rodrigues_jacobian(r: FloatArray) -> FloatArray:
    """The small rotation (in the rotated frame's parent) per change of the rotation vector
    ``r``: the left Jacobian of SO(3)."""
    theta = float(np.linalg.norm(r))
    if theta < 1e-9:
        return np.eye(3)
    K = _skew(r / theta)
    return np.asarray(
        np.eye(3) + (1 - math.cos(theta)) / theta * K + (theta - math.sin(theta)) / theta * (K @ K),
        dtype=np.float64,
    )


def stacked(observations: list[Observations]) -> Corners:
    """Every camera's corners in one :class:`Corners` (frames numbered across the cameras,
    each corner's camera)."""
    parts = [corners_of(o, np.ones(o.frames, dtype=bool)) for o in observations]
    offsets = np.cumsum([0] + [c.frames for c in parts[:-1]])
    return Corners(
        np.vstack([c.Q for c in parts]),
        np.concatenate([c.frame + off for c, off in zip(parts, offsets, strict=True)]).astype(
            np.intp
        ),
        np.vstack([c.points for c in parts]),
        np.vstack([c.uv for c in parts]),
        np.concatenate([np.full(c.uv.shape[0], k, dtype=np.intp) for k, c in enumerate(parts)]),
    )
