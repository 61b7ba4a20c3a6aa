"""The whole model's maximum-likelihood fit in pixels: every detected board corner is an
observation (issue 32, item 4).

The model is the tracker's (:class:`~dhlog.identify.axismodel.AxisModel` with a target frame):
the joint axes as lines in a measurement frame M, and the frame the chain carries (its origin
``target``, its orientation ``tool_rotation`` at the reference pose). What differs is the
measurement model (:class:`PixelModel`):

- **eye-to-hand**: M is the camera's frame; the carried frame is the board's (its centre), so a
  corner ``c`` (in the board's frame, from its centre) is at ``X = p(q) + R(q) c`` in the camera;
- **eye-in-hand**: M is the board's frame (from its centre); the carried frame is the camera's,
  so a corner ``c`` (in M) is at ``X = R(q)ᵀ (c − p(q))`` in the camera.

``X`` is projected through the intrinsics (:meth:`dhlog.vision.camera.Intrinsics.project`,
OpenCV's lens models and their Jacobian). The intrinsics are held, or refined with the model
where the data determine them (``refine_intrinsics``). The DH table and base are read off the
fitted axes as for a tracker (:func:`~dhlog.identify.extract.extract_dh`): the base's pose in M
is the camera's (eye-to-hand) or the board's (eye-in-hand) pose in the robot's base frame, the
carried frame on the flange the board's mount (eye-to-hand) or the camera's (eye-in-hand: the
hand-eye calibration).

Each corner's residual (predicted − detected, px) is weighted by one σ in pixels, the data's
own (a robust scale at the start, then χ²/dof at the optimum), and a corner beyond
``threshold`` σ (a false detection) is held out by a truncated quadratic. Levenberg–Marquardt
steps within the directions the corners determine (:class:`~dhlog.identify.whole.Determined`);
the covariance is ``(JᵀJ)⁻¹ σ²`` there.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.identify.axismodel import AxisModel, ParameterLayout
from dhlog.identify.prediction import predict_columns, predict_orientation, prefix_motions
from dhlog.identify.whole import Determined, WholeFit
from dhlog.model.dh import StandardDH
from dhlog.vision.camera import Intrinsics

#: Median of a 2-dof chi variable (|r|/σ of an isotropic 2-D residual).
CHI2_MEDIAN = 1.1774
#: Corners per block of the normal equations.
BLOCK = 20000
#: Expected decrease of the cost below which the fit has converged.
CONVERGED = 1e-4

SETUPS = ("eye-to-hand", "eye-in-hand")


@dataclass(frozen=True)
class Corners:
    """The pixel observations of one camera: ``Q`` (f, n) each frame's joint values;
    ``frame`` (N,) each corner's frame (an index into ``Q``); ``points`` (N, 3) the corner in
    the board's frame from its centre (m); ``uv`` (N, 2) where it was detected (px)."""

    Q: FloatArray
    frame: NDArray[np.intp]
    points: FloatArray
    uv: FloatArray

    @property
    def frames(self) -> int:
        return int(self.Q.shape[0])

    def of_frames(self, chosen: NDArray[np.bool_]) -> Corners:
        """The observations of the frames ``chosen`` (f,) only, renumbered."""
        index = np.cumsum(chosen) - 1
        keep = chosen[self.frame]
        return Corners(
            self.Q[chosen],
            index[self.frame[keep]].astype(np.intp),
            self.points[keep],
            self.uv[keep],
        )


@dataclass(frozen=True)
class PixelModel:
    """The camera measurement model: the set-up and the intrinsics; with ``refine``, the
    intrinsics' parameters (fx, fy, cx, cy and the lens coefficients) follow the model's."""

    setup: str
    intrinsics: Intrinsics
    refine: bool = False

    @property
    def extra(self) -> int:
        """Parameters of the measurement model beyond the kinematic model's."""
        return 4 + self.intrinsics.coefficients.size if self.refine else 0

    def moved(self, delta: FloatArray) -> PixelModel:
        """The intrinsics moved by ``delta`` (``extra``,)."""
        if not self.refine:
            return self
        c = self.intrinsics
        K = c.K.copy()
        K[0, 0] += delta[0]
        K[1, 1] += delta[1]
        K[0, 2] += delta[2]
        K[1, 2] += delta[3]
        return replace(self, intrinsics=replace(c, K=K, coefficients=c.coefficients + delta[4:]))

    def in_camera(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Corners,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        """The corners ``sl`` in the camera's frame (c, 3) and, with ``layout``, their
        Jacobian (size, 3, c) with respect to the model's local parameters."""
        frames = data.frame[sl]
        used, back = np.unique(frames, return_inverse=True)
        Q = data.Q[used]
        prefix = prefix_motions(model, Q)
        p, Jp = predict_columns(model, Q, layout, bases, None, prefix)
        if layout is None or bases is None:
            R = _rotations(model, Q)
            Jo = None
        else:
            R, Jo = predict_orientation(model, Q, layout, bases, prefix)
        c = data.points[sl].T  # (3, k)
        Rk, pk = R[:, :, back], p[:, back]
        if self.setup == "eye-to-hand":
            Rc = np.einsum("ijk,jk->ik", Rk, c)
            X = pk + Rc
            if Jp is None or Jo is None:
                return X.T, None
            J = Jp[:, :, back] + np.cross(Jo[:, :, back], Rc[None], axis=1)
            return X.T, J
        v = c - pk
        X = np.einsum("jik,jk->ik", Rk, v)
        if Jp is None or Jo is None:
            return X.T, None
        t = Jp[:, :, back] + np.cross(Jo[:, :, back], v[None], axis=1)
        J = -np.einsum("jik,sjk->sik", Rk, t)
        return X.T, J

    def predict(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Corners,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        """The corners ``sl``' pixels (c, 2) and, with ``layout``, their Jacobian
        (c, 2, size + extra) with respect to the model's and the intrinsics' parameters."""
        X, JX = self.in_camera(model, layout, bases, data, sl)
        if JX is None:
            return self.intrinsics.project(X), None
        uv, jp, ji = self.intrinsics.project_jacobian(X)
        J = np.einsum("kab,sbk->kas", jp, JX)
        if self.refine:
            J = np.concatenate([J, ji], axis=2)
        return uv, J


def _rotations(model: AxisModel, Q: FloatArray) -> FloatArray:
    """The carried frame's orientation (3, 3, f) at ``Q``."""
    layout = ParameterLayout.of(model.types, rotation=True)
    R, _ = predict_orientation(model, Q, layout, model.bases())
    return R


@dataclass
class PixelFit:
    """The fit: ``whole`` (the kinematic model, its covariance — marginal over the
    intrinsics when they were refined —, χ²/dof 1 by construction of σ), the measurement model
    at the optimum, ``sigma_px`` the corners' σ (px), each corner's residual ``residuals``
    (N, 2, px: predicted − detected) and whether it entered (``inliers`` (N,)), and the
    intrinsics' covariance (``extra`` × ``extra``; None when held)."""

    whole: WholeFit
    measurement: PixelModel
    sigma_px: float
    residuals: FloatArray
    inliers: NDArray[np.bool_]
    intrinsics_covariance: FloatArray | None
    full_covariance: FloatArray

    @property
    def rms_px(self) -> float:
        r = self.residuals[self.inliers]
        return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) if r.size else math.nan


def residuals(model: AxisModel, measurement: PixelModel, data: Corners) -> FloatArray:
    """Each corner's residual (N, 2, px) at ``model``: predicted − detected."""
    out = np.empty((data.uv.shape[0], 2))
    for start in range(0, out.shape[0], BLOCK):
        sl = slice(start, min(start + BLOCK, out.shape[0]))
        uv, _ = measurement.predict(model, None, None, data, sl)
        out[sl] = uv - data.uv[sl]
    return out


def _normal(
    model: AxisModel,
    layout: ParameterLayout,
    measurement: PixelModel,
    data: Corners,
    limit: float,
) -> tuple[FloatArray, FloatArray, float, int, float, FloatArray]:
    """``JᵀJ``, ``Jᵀr`` (px units) over the corners within ``limit`` px, the truncated cost,
    the inlier count, their sum of squares and every corner's residual norm."""
    bases = model.bases()
    size = layout.size + measurement.extra
    H, g = np.zeros((size, size)), np.zeros(size)
    N = data.uv.shape[0]
    norms = np.empty(N)
    cost, count, chi2 = 0.0, 0, 0.0
    for start in range(0, N, BLOCK):
        sl = slice(start, min(start + BLOCK, N))
        uv, J = measurement.predict(model, layout, bases, data, sl)
        assert J is not None
        r = uv - data.uv[sl]
        nrm = np.sqrt(np.sum(r**2, axis=1))
        nrm = np.where(np.isfinite(nrm), nrm, np.inf)  # behind the camera: an outlier
        norms[sl] = nrm
        use = nrm <= limit
        cost += float(np.sum(np.minimum(nrm, limit) ** 2))
        Ju = J[use].reshape(-1, size)
        ru = r[use].reshape(-1)
        H += Ju.T @ Ju
        g += Ju.T @ ru
        count += int(np.count_nonzero(use))
        chi2 += float(ru @ ru)
    return H, g, cost, count, chi2, norms


_Normal = tuple[FloatArray, FloatArray, float, int, float, FloatArray]


def _moved(
    model: AxisModel,
    measurement: PixelModel,
    layout: ParameterLayout,
    delta: FloatArray,
) -> tuple[AxisModel, PixelModel]:
    k = layout.size
    return model.moved(delta[:k], layout, model.bases()), measurement.moved(delta[k:])


def _levenberg_marquardt(
    model: AxisModel,
    measurement: PixelModel,
    layout: ParameterLayout,
    data: Corners,
    limit: float,
    within: FloatArray | None,
    max_iterations: int,
) -> tuple[
    AxisModel, PixelModel, tuple[FloatArray, FloatArray, float, int, float, FloatArray], int
]:
    state = _normal(model, layout, measurement, data, limit)
    determined = Determined.of(state[0], within)
    lam = 1e-6
    it = 0
    while it < max_iterations:
        it += 1
        H, g, cost = state[0], state[1], state[2]
        try:
            delta = determined.solve(H, g, lam)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        if float(-(g @ delta)) < CONVERGED:
            model, measurement = _moved(model, measurement, layout, delta)
            state = _normal(model, layout, measurement, data, limit)
            break
        trial, trial_m = _moved(model, measurement, layout, delta)
        ts = _normal(trial, layout, trial_m, data, limit)
        if ts[2] <= cost + 1e-12 * max(cost, 1.0):
            done = cost - ts[2] < 1e-12 * cost
            model, measurement, state = trial, trial_m, ts
            lam = max(lam / 10.0, 1e-12)
            if done:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return model, measurement, state, it


def fit_pixels(
    start: AxisModel,
    measurement: PixelModel,
    data: Corners,
    *,
    threshold: float = 5.0,
    within: FloatArray | None = None,
    max_iterations: int = 50,
    sigma_px: float | None = None,
    progress: Callable[[float], None] | None = None,
) -> PixelFit:
    """Levenberg–Marquardt of ``start`` (its target frame: the board's or the camera's, see the
    module docstring) and, with ``measurement.refine``, the intrinsics, to the corners
    ``data``. ``within`` (size, r): the kinematic model moves along these directions only
    (parameter units; the intrinsics, when refined, freely). ``sigma_px``: the corners' σ
    when known (else the data's own); ``threshold``: the outlier cut in σ."""
    if start.tool_rotation is None:
        raise ValueError("the pixel fit needs the model's target frame (tool_rotation)")
    layout = ParameterLayout.of(start.types, rotation=True)
    size = layout.size + measurement.extra
    if within is not None and measurement.extra:
        top = np.zeros((size, within.shape[1] + measurement.extra))
        top[: layout.size, : within.shape[1]] = within
        top[layout.size :, within.shape[1] :] = np.eye(measurement.extra)
        within = top
    N = data.uv.shape[0]
    if 2 * N <= size:
        raise DegenerateGeometryError(
            f"the pixel fit has {N} corners (2 residuals each) for {size} parameters: "
            "keep more frames with the board in view."
        )
    # the start's robust scale judges the first pass; the optimum's judges the second
    r0 = residuals(start, measurement, data)
    n0 = np.sqrt(np.sum(r0**2, axis=1))
    n0 = n0[np.isfinite(n0)]
    scale = float(np.median(n0)) / CHI2_MEDIAN if n0.size else 1.0
    model, meas = start, measurement
    iterations = 0
    for rounds in range(2):
        if progress is not None:
            progress(0.5 * rounds)
        limit = threshold * max(scale, 1e-6)
        model, meas, state, it = _levenberg_marquardt(
            model, meas, layout, data, limit, within, max_iterations
        )
        iterations += it
        scale = (
            sigma_px if sigma_px is not None else math.sqrt(state[4] / max(2 * state[3] - size, 1))
        )
    H, _, _, count, chi2, norms = state
    determined = Determined.of(H, within)
    if determined.basis.shape[1] == 0:
        raise DegenerateGeometryError("the corners determine none of the model's parameters.")
    dof = max(2 * count - determined.basis.shape[1], 1)
    sigma2 = chi2 / dof if sigma_px is None else sigma_px**2
    cov = determined.inverse(H) * sigma2
    k = layout.size
    frames_in = np.zeros(data.frames, dtype=bool)
    frames_in[data.frame[norms <= limit]] = True
    whole = WholeFit(
        model=model,
        layout=layout,
        covariance=np.asarray(cov[:k, :k], dtype=np.float64),
        inliers=frames_in,
        chi2_dof=1.0 if sigma_px is None else float(chi2 / dof) / sigma_px**2,
        n_points=int(count),
        iterations=iterations,
        bases=model.bases(),
        determined=Determined.of(H[:k, :k], None if within is None else within[:k]),
        limit=float(limit),
    )
    res = residuals(model, meas, data)
    return PixelFit(
        whole,
        meas,
        math.sqrt(sigma2),
        res,
        norms <= limit,
        np.asarray(cov[k:, k:], dtype=np.float64) if meas.extra else None,
        np.asarray(cov, dtype=np.float64),
    )


def place(
    table: StandardDH,
    reference_pose: FloatArray,
    T_measurement_base: FloatArray,
    tool_point: FloatArray,
    tool_rotation: FloatArray,
    measurement: PixelModel,
    data: Corners,
    *,
    threshold: float = 5.0,
    max_iterations: int = 50,
) -> AxisModel:
    """``table`` placed on the corners, its geometry held: the base's pose in M and the
    carried frame (``tool_point``, ``tool_rotation``) on the flange — the camera's pose and the
    board's mount — by Levenberg–Marquardt in pixels along :func:`rigid_directions`, the model
    rebuilt exactly from the table at each step (so the table never drifts); first on every
    corner, then with the corners beyond ``threshold`` times the robust scale held out. How a
    nominal is scored on one footing with the calibration."""
    from dhlog.model.fk import fk_frames

    meas = replace(measurement, refine=False)
    state = (T_measurement_base, tool_point, tool_rotation)

    def build(st: tuple[FloatArray, FloatArray, FloatArray]) -> AxisModel:
        return AxisModel.of_table(table, reference_pose, st[1], st[0], tool_rotation=st[2])

    def step(
        st: tuple[FloatArray, FloatArray, FloatArray], d: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        G = np.eye(4)
        G[:3, :3], G[:3, 3] = rotation_from_vector(d[:3]), d[3:6]
        T = G @ st[0]
        F = fk_frames(table, reference_pose, T_base=T)[-1][:3, :3]
        return T, st[1] + F.T @ d[6:9], F.T @ rotation_from_vector(d[9:12]) @ F @ st[2]

    model = build(state)
    layout = ParameterLayout.of(model.types, rotation=True)
    limit = math.inf
    for _ in range(2):
        normal = _normal(model, layout, meas, data, limit)
        lam = 1e-4
        for _ in range(max_iterations):
            H, g, cost = normal[0], normal[1], normal[2]
            W = rigid_directions(model, layout)
            Hw, gw = W.T @ H @ W, W.T @ g
            try:
                d = np.linalg.solve(Hw + lam * np.diag(np.maximum(np.diag(Hw), 1e-30)), -gw)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial_state = step(state, np.asarray(d, dtype=np.float64))
            trial = build(trial_state)
            tn = _normal(trial, layout, meas, data, limit)
            if tn[2] <= cost:
                done = cost - tn[2] < 1e-10 * max(cost, 1e-30)
                state, model, normal = trial_state, trial, tn
                lam = max(lam / 10.0, 1e-12)
                if done:
                    break
            else:
                lam *= 10.0
                if lam > 1e8:
                    break
        norms = normal[5]
        finite = norms[np.isfinite(norms)]
        limit = threshold * max(float(np.median(finite)) / CHI2_MEDIAN, 1e-6)
    return model


def rigid_directions(model: AxisModel, layout: ParameterLayout) -> FloatArray:
    """The local-parameter directions (size, 12) of placing ``model`` anew: a rigid motion of
    the whole chain in M (3 turns about M's axes, 3 shifts), then the carried frame's origin
    (3) and orientation (3) on the flange — the freedom a nominal has when it is placed on
    the corners (the camera's pose and the board's mount), its geometry held."""
    bases = model.bases()
    W = np.zeros((layout.size, 12))
    basis = np.eye(3)
    for col in range(6):
        w = basis[col] if col < 3 else np.zeros(3)
        t = basis[col - 3] if col >= 3 else np.zeros(3)
        for i, axis in enumerate(model.axes):
            u, v = bases[i]
            k = layout.axis_at[i]
            W[k, col], W[k + 1, col] = w @ u, w @ v
            if len(layout.names) > k + 2 and layout.names[k + 2].endswith("shift_u"):
                moved = np.cross(w, axis.point) + t
                W[k + 2, col], W[k + 3, col] = moved @ u, moved @ v
        at = layout.target_at
        W[at : at + 3, col] = np.cross(w, model.target) + t
        assert layout.rotation_at is not None
        W[layout.rotation_at : layout.rotation_at + 3, col] = w
    at = layout.target_at
    W[at : at + 3, 6:9] = np.eye(3)
    assert layout.rotation_at is not None
    W[layout.rotation_at : layout.rotation_at + 3, 9:12] = np.eye(3)
    return W
