"""The hand-eye product: the fixed part's pose in the robot's base frame and the mounted part's on
the flange, with σ propagated from the fit's covariance by central differences (one camera:
:func:`hand_eye`; several: :func:`cameras_std`).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.pixels import PixelFit
from dhlog.identify.camera.poses import shift, transform
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.read.propagate import Extractor


def hand_eye(
    fit: PixelFit,
    extract: Extractor,
    setup: str,
    centre: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The fixed part's pose in the robot's base frame (the camera eye-to-hand, the board
    eye-in-hand) and the mounted part's on the flange, with their σ (rotation vector, rad;
    translation, m) propagated from the fit's covariance by central differences."""
    whole = fit.whole
    layout, model = whole.layout, whole.model

    def poses(m: AxisModel) -> tuple[FloatArray, FloatArray]:
        ex = extract(list(m.axes), m.target, None)
        T_base_M = np.linalg.inv(ex.T_measurement_base)
        T_M_flange = ex.frames[-1]
        assert m.tool_rotation is not None
        T_M_carried = transform(m.tool_rotation, m.target)
        T_flange_carried = np.linalg.inv(T_M_flange) @ T_M_carried
        if setup == "eye-to-hand":  # M is the camera; the carried frame the board's centre
            return np.asarray(T_base_M, dtype=np.float64), T_flange_carried @ shift(-centre)
        return T_base_M @ shift(-centre), np.asarray(T_flange_carried, dtype=np.float64)

    T_fixed, T_mounted = poses(model)
    bases = model.bases()

    def vec(T1: FloatArray, T2: FloatArray) -> FloatArray:
        out = []
        for T, T0 in ((T1, T_fixed), (T2, T_mounted)):
            dR = T[:3, :3] @ T0[:3, :3].T
            out.append(Rotation.from_matrix(dR).as_rotvec())
            out.append(T[:3, 3] - T0[:3, 3])
        return np.concatenate(out)

    size = layout.size
    J = np.zeros((12, size))
    scale = np.sqrt(np.clip(np.diag(whole.covariance), 0.0, None))
    for k in range(size):
        h = max(float(scale[k]), 1e-9)
        d = np.zeros(size)
        d[k] = h
        plus = vec(*poses(model.moved(d, layout, bases)))
        minus = vec(*poses(model.moved(-d, layout, bases)))
        J[:, k] = (plus - minus) / (2 * h)
    cov = J @ whole.covariance @ J.T
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return T_fixed, T_mounted, std[:6], std[6:]


def cameras_std(fit: PixelFit, extract: Extractor) -> list[FloatArray]:
    """Each camera's pose in the base frame: its σ (rotation vector rad, translation m; 6) by
    central differences over every fitted parameter (the model's and the cameras' own)."""
    whole, meas = fit.whole, fit.measurement
    layout, model = whole.layout, whole.model
    k0 = layout.size
    bases = model.bases()

    def poses(d: FloatArray) -> list[FloatArray]:
        m = model.moved(d[:k0], layout, bases)
        T_base_M = np.linalg.inv(extract(list(m.axes), m.target, None).T_measurement_base)
        return [T_base_M @ T for T in meas.moved(d[k0:]).poses]

    zero = poses(np.zeros(fit.full_covariance.shape[0]))

    def vec(Ts: list[FloatArray]) -> FloatArray:
        out = []
        for T, T0 in zip(Ts, zero, strict=True):
            out.append(Rotation.from_matrix(T[:3, :3] @ T0[:3, :3].T).as_rotvec())
            out.append(T[:3, 3] - T0[:3, 3])
        return np.concatenate(out)

    cov = fit.full_covariance
    size = cov.shape[0]
    J = np.zeros((6 * len(zero), size))
    scale = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for k in range(size):
        h = max(float(scale[k]), 1e-9)
        d = np.zeros(size)
        d[k] = h
        J[:, k] = (vec(poses(d)) - vec(poses(-d))) / (2 * h)
    std = np.sqrt(np.clip(np.diag(J @ cov @ J.T), 0.0, None))
    return [std[6 * k : 6 * k + 6] for k in range(len(zero))]
