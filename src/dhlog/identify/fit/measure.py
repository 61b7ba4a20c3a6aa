"""One measurement model for every instrument: what a tracker's point, a 6-DoF probe and a
camera's pixel have in common for the whole-model fit.

The kinematic model is one (:class:`~dhlog.identify.fit.axismodel.AxisModel`: the joint axes as
lines in a measurement frame M and the frame the chain carries); an instrument is a
:class:`Measurement`: its observations' count and dimension, its prediction of them from the
model with the Jacobian (with respect to the model's local parameters and its own, e.g. a
camera's intrinsics), and how its own parameters move. On that interface alone this module
gives

- :func:`fit_measured`: the maximum likelihood (Levenberg–Marquardt within the directions the
  observations determine, :class:`~dhlog.identify.fit.whole.Determined`; a truncated quadratic per
  observation against gross outliers; σ the data's own or given; the covariance
  ``(JᵀJ)⁻¹ σ²``) — the :class:`~dhlog.identify.fit.whole.WholeFit` the DH extraction, the
  uncertainty (:func:`~dhlog.identify.read.uncertainty.whole_uncertainty`) and the result take;
- :func:`residuals` and :func:`rms` for held-out scoring;
- each measurement's :meth:`Measurement.place`: a nominal table placed on the observations
  (the base in M and the carried frame on the flange; its geometry held), the "before" of a
  held-out check — the tracker's through the one placement of points
  (:func:`~dhlog.identify.fit.placement.place_on`), a camera's by Levenberg–Marquardt in
  pixels (:func:`place_by_lm`).

Implementations: :class:`PointMeasurement` (a tracker's target point in M: the reference form of
the tracker's fit, whose streamed, chunked fast path for logs of millions of samples is
:func:`~dhlog.identify.fit.whole.fit_whole_model`; ``tests/test_measurement_model.py`` checks the
two agree) and :class:`~dhlog.identify.camera.pixels.PixelModel` (a camera's corners). A further
instrument (a stereo pair, a motion-capture marker set, a CMM probe) is one more class with
``count``, ``dim``, ``observed``, ``predict``, ``extra``, ``moved`` and ``place``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.lm import levenberg_marquardt
from dhlog.identify.fit.placement import Stand, place_on
from dhlog.identify.fit.prediction import predict_columns
from dhlog.identify.fit.whole import Determined, WholeFit
from dhlog.model.dh import StandardDH

#: Observations per block of the normal equations.
BLOCK = 20000
#: Expected decrease of the cost below which the fit has converged (in σ² units of the data).
CONVERGED = 1e-4
#: Median of a chi variable of 1, 2, 3 degrees of freedom (|r|/σ of an isotropic residual).
CHI_MEDIAN = {1: 0.6745, 2: 1.1774, 3: 1.5382}

M = TypeVar("M", bound="Measurement")


class Measurement(Protocol):
    """An instrument's measurement model over its data (the data's type is the model's own:
    points, corners, …)."""

    @property
    def dim(self) -> int:
        """Components of one observation (3 a point, 2 a pixel)."""
        ...

    @property
    def extra(self) -> int:
        """Parameters of the measurement model itself (0: none fitted)."""
        ...

    @property
    def block(self) -> int:
        """Observations a block of the passes over the data."""
        ...

    def count(self, data: Any) -> int:
        """The observations in ``data``."""
        ...

    def observed(self, data: Any, sl: slice) -> FloatArray:
        """The observations ``sl`` (c, dim)."""
        ...

    def predict(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Any,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        """The predicted observations ``sl`` (c, dim) and, with ``layout``, their Jacobian
        (c, dim, layout.size + extra): the model's local parameters, then its own."""
        ...

    def normal_block(
        self,
        model: AxisModel,
        layout: ParameterLayout,
        bases: list[tuple[FloatArray, FloatArray]],
        data: Any,
        sl: slice,
        limit: float,
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """The observations ``sl``' residuals (c, dim) and, over those within ``limit``, their
        ``JᵀJ`` and ``Jᵀr``, where the measurement sums them itself (a camera: frame by frame);
        None: the pass forms them from :meth:`predict`'s Jacobian."""
        ...

    def moved(self: M, delta: FloatArray) -> M:
        """The measurement model with its own parameters moved by ``delta`` (extra,)."""
        ...

    def place(
        self: M,
        table: StandardDH,
        reference_pose: FloatArray,
        T_measurement_base: FloatArray,
        tool_point: FloatArray,
        tool_rotation: FloatArray | None,
        data: Any,
    ) -> tuple[AxisModel, M]:
        """``table`` placed on the observations ``data``, its geometry held: the base's pose
        in M and the carried frame on the flange (``tool_point``, ``tool_rotation``: the
        start and what the observations do not determine), with the measurement model's own
        parameters where it fits them — how a nominal is put on a session. Returns the placed
        model (:meth:`AxisModel.of_table` at ``reference_pose``) and the measurement model."""
        ...


class FromJacobian:
    """A :class:`Measurement` whose passes form the normal equations from :meth:`predict`'s
    Jacobian, :data:`BLOCK` observations a block (a tracker's point, several cameras): its
    ``normal_block`` is None."""

    block: ClassVar[int] = BLOCK

    def normal_block(
        self,
        model: AxisModel,
        layout: ParameterLayout,
        bases: list[tuple[FloatArray, FloatArray]],
        data: Any,
        sl: slice,
        limit: float,
    ) -> None:
        return None


@dataclass(frozen=True)
class Points:
    """A tracker's samples: joint values ``Q`` (m, n), the target's positions ``P`` (m, 3)."""

    Q: FloatArray
    P: FloatArray


@dataclass(frozen=True)
class PointMeasurement(FromJacobian):
    """A tracker's target point in M (one σ for all: the data's own)."""

    dim: int = 3
    extra: int = 0

    def count(self, data: Points) -> int:
        return int(data.P.shape[0])

    def observed(self, data: Points, sl: slice) -> FloatArray:
        return data.P[sl]

    def predict(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Points,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        p, J = predict_columns(model, data.Q[sl], layout, bases)
        return p.T, None if J is None else np.transpose(J, (2, 1, 0))

    def moved(self, delta: FloatArray) -> PointMeasurement:
        return self

    def place(
        self,
        table: StandardDH,
        reference_pose: FloatArray,
        T_measurement_base: FloatArray,
        tool_point: FloatArray,
        tool_rotation: FloatArray | None,
        data: Points,
    ) -> tuple[AxisModel, PointMeasurement]:
        """The tracker's placement (:func:`~dhlog.identify.fit.placement.place_on`:
        closed-form starts, robust least squares, the gross outliers set aside — as
        :func:`~dhlog.identify.fit.register.register_nominal`): the base in M and the target
        point on the flange; the carried frame's orientation kept (points have none)."""
        from dhlog.model.fk import fk_frames

        frames = fk_frames(table, data.Q)[:, -1]
        got = place_on(
            frames[:, :3, :3],
            frames[:, :3, 3],
            data.P,
            stand=Stand(T_measurement_base, tool_point),
            point=True,
        )
        model = AxisModel.of_table(
            table, reference_pose, got.tool, got.T, tool_rotation=tool_rotation
        )
        return model, self


@dataclass(frozen=True)
class MeasuredFit:
    """A fit by :func:`fit_measured`: ``whole`` (the kinematic model and its covariance —
    marginal over the measurement model's own parameters when they were fitted), the
    measurement model at the optimum, ``sigma`` the observations' σ per component (their unit),
    each observation's residual ``residuals`` (N, dim: predicted − observed) and whether it
    entered (``inliers``), the measurement model's own covariance (None when held) and the
    covariance of every parameter fitted."""

    whole: WholeFit
    measurement: Any
    sigma: float
    residuals: FloatArray
    inliers: NDArray[np.bool_]
    own_covariance: FloatArray | None
    full_covariance: FloatArray

    @property
    def rms(self) -> float:
        """RMS of the inliers' residual norms."""
        return rms(self.residuals[self.inliers])


def rms(res: FloatArray) -> float:
    """RMS of residual norms (N, dim), NaN rows left out (NaN when none)."""
    v = np.sum(res**2, axis=1)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v))) if v.size else math.nan


def residuals(model: AxisModel, measurement: Measurement, data: Any) -> FloatArray:
    """Each observation's residual (N, dim) at ``model``: predicted − observed."""
    N = measurement.count(data)
    out = np.empty((N, measurement.dim))
    step = measurement.block
    for start in range(0, N, step):
        sl = slice(start, min(start + step, N))
        pred, _ = measurement.predict(model, None, None, data, sl)
        out[sl] = pred - measurement.observed(data, sl)
    return out


_Normal = tuple[FloatArray, FloatArray, float, int, float, FloatArray]


def _normal(
    model: AxisModel,
    layout: ParameterLayout,
    measurement: Measurement,
    data: Any,
    limit: float,
) -> _Normal:
    """``JᵀJ``, ``Jᵀr`` over the observations within ``limit`` (residual norm, their unit),
    the truncated cost, the inlier count, their sum of squares and every residual norm."""
    bases = model.bases()
    size = layout.size + measurement.extra
    H, g = np.zeros((size, size)), np.zeros(size)
    N = measurement.count(data)
    norms = np.empty(N)
    cost, count, chi2 = 0.0, 0, 0.0
    step = measurement.block
    for start in range(0, N, step):
        sl = slice(start, min(start + step, N))
        J: FloatArray | None = None
        # a measurement may sum its block's normal equations itself (a camera: frame by frame)
        summed = measurement.normal_block(model, layout, bases, data, sl, limit)
        if summed is not None:
            r, Hb, gb = summed
        else:
            pred, J = measurement.predict(model, layout, bases, data, sl)
            assert J is not None
            r = pred - measurement.observed(data, sl)
        nrm = np.sqrt(np.sum(r**2, axis=1))
        nrm = np.where(np.isfinite(nrm), nrm, np.inf)  # no prediction (behind a camera): out
        norms[sl] = nrm
        use = nrm <= limit
        cost += float(np.sum(np.minimum(nrm, limit) ** 2))
        ru = r[use].reshape(-1)
        if J is not None:
            Ju = J[use].reshape(-1, size)
            Hb, gb = Ju.T @ Ju, Ju.T @ ru
        H += Hb
        g += gb
        count += int(np.count_nonzero(use))
        chi2 += float(ru @ ru)
    return H, g, cost, count, chi2, norms


def _moved(
    model: AxisModel, measurement: M, layout: ParameterLayout, delta: FloatArray
) -> tuple[AxisModel, M]:
    k = layout.size
    return model.moved(delta[:k], layout, model.bases()), measurement.moved(delta[k:])


@dataclass(frozen=True)
class _Point(Generic[M]):
    """A point of the fit: the model, the measurement model and their normal equations."""

    model: AxisModel
    measurement: M
    normal: _Normal

    @property
    def H(self) -> FloatArray:
        return self.normal[0]

    @property
    def g(self) -> FloatArray:
        return self.normal[1]

    @property
    def cost(self) -> float:
        return self.normal[2]


def _levenberg_marquardt(
    model: AxisModel,
    measurement: M,
    layout: ParameterLayout,
    data: Any,
    limit: float,
    within: FloatArray | None,
    max_iterations: int,
    scale: float,
) -> tuple[AxisModel, M, _Normal, int]:
    start = _Point(model, measurement, _normal(model, layout, measurement, data, limit))
    determined = Determined.of(start.H, within)

    def trial(point: _Point[M], delta: FloatArray) -> _Point[M]:
        moved, moved_m = _moved(point.model, point.measurement, layout, delta)
        return _Point(moved, moved_m, _normal(moved, layout, moved_m, data, limit))

    final, it = levenberg_marquardt(
        start,
        solve=determined.solve,
        trial=trial,
        settle=trial,  # the last, small step evaluated too
        small=CONVERGED * scale**2,
        floor=1e-300,
        max_iterations=max_iterations,
    )
    return final.model, final.measurement, final.normal, it


def fit_measured(
    start: AxisModel,
    measurement: M,
    data: Any,
    *,
    threshold: float = 5.0,
    within: FloatArray | None = None,
    max_iterations: int = 50,
    sigma: float | None = None,
    progress: Callable[[float], None] | None = None,
) -> MeasuredFit:
    """Levenberg–Marquardt of ``start`` and the measurement model's own parameters to the
    observations ``data``: a first round judged on the start's robust scale, a second on the
    optimum's. ``within`` (size, r): the kinematic model moves along these directions only
    (parameter units; the measurement's own parameters freely). ``sigma``: the observations'
    σ per component when known (else the data's own, χ²/dof at the optimum); ``threshold``:
    the outlier cut in σ (of the residual norm)."""
    rotation = start.tool_rotation is not None
    layout = ParameterLayout.of(start.types, rotation=rotation)
    size = layout.size + measurement.extra
    if within is not None and measurement.extra:
        top = np.zeros((size, within.shape[1] + measurement.extra))
        top[: layout.size, : within.shape[1]] = within
        top[layout.size :, within.shape[1] :] = np.eye(measurement.extra)
        within = top
    N, d = measurement.count(data), measurement.dim
    if d * N <= size:
        raise DegenerateGeometryError(
            f"the fit has {N} observations ({d} components each) for {size} parameters: "
            "measure more poses."
        )
    n0 = np.sqrt(np.sum(residuals(start, measurement, data) ** 2, axis=1))
    n0 = n0[np.isfinite(n0)]
    scale = float(np.median(n0)) / CHI_MEDIAN.get(d, math.sqrt(d)) if n0.size else 1.0
    model, meas = start, measurement
    iterations = 0
    limit = math.inf
    state: _Normal | None = None
    for rounds in range(2):
        if progress is not None:
            progress(0.5 * rounds)
        limit = threshold * max(scale, 1e-12)
        model, meas, state, it = _levenberg_marquardt(
            model, meas, layout, data, limit, within, max_iterations, scale
        )
        iterations += it
        scale = sigma if sigma is not None else math.sqrt(state[4] / max(d * state[3] - size, 1))
    assert state is not None
    H, _, _, count, chi2, norms = state
    determined = Determined.of(H, within)
    if determined.basis.shape[1] == 0:
        raise DegenerateGeometryError("the observations determine none of the parameters.")
    dof = max(d * count - determined.basis.shape[1], 1)
    sigma2 = chi2 / dof if sigma is None else sigma**2
    cov = determined.inverse(H) * sigma2
    k = layout.size
    inliers = norms <= limit
    whole = WholeFit(
        model=model,
        layout=layout,
        covariance=np.asarray(cov[:k, :k], dtype=np.float64),
        inliers=inliers,
        chi2_dof=1.0 if sigma is None else float(chi2 / dof) / sigma**2,
        n_points=int(count),
        iterations=iterations,
        bases=model.bases(),
        determined=(
            Determined.of(H[:k, :k], None if within is None else within[:k])
            if within is None or np.any(within[:k])
            else None  # the model held: only the measurement's own parameters moved
        ),
        limit=float(limit),
    )
    return MeasuredFit(
        whole,
        meas,
        math.sqrt(sigma2),
        residuals(model, meas, data),
        inliers,
        np.asarray(cov[k:, k:], dtype=np.float64) if meas.extra else None,
        np.asarray(cov, dtype=np.float64),
    )


def place_by_lm(
    table: StandardDH,
    reference_pose: FloatArray,
    stand: Stand,
    measurement: M,
    data: Any,
    *,
    threshold: float = 5.0,
    max_iterations: int = 50,
    far: float = math.inf,
) -> tuple[AxisModel, M]:
    """``table`` at ``reference_pose`` placed on the corners from ``stand`` (where it stands:
    its base, tool point and tool frame, which it must have), its geometry held: the base's pose
    in M and the carried frame on the flange — the camera's pose and the board's mount —
    by Levenberg–Marquardt in pixels along :func:`rigid_directions` (a camera's
    :meth:`Measurement.place`), the model rebuilt exactly from the table at each step (so the
    table never drifts); first on every corner, then with the corners beyond ``threshold``
    times the robust scale held out (not when the first round's robust scale is ``far`` or
    more: no placement near the observations). How a nominal is scored on one footing with the
    calibration."""
    from dhlog.model.fk import fk_frames

    meas = measurement
    tool_rotation = stand.R_tool
    assert tool_rotation is not None, "a camera's placement carries a frame"
    state = (stand.T, stand.tool, tool_rotation)

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
    layout = ParameterLayout.of(model.types, rotation=tool_rotation is not None)
    k, extra = layout.size, meas.extra
    limit = math.inf
    for round_ in range(2):
        normal = _normal(model, layout, meas, data, limit)
        lam = 1e-4
        for _ in range(max_iterations):
            H, g, cost = normal[0], normal[1], normal[2]
            W = np.zeros((k + extra, 12 + extra))  # the placement, then the measurement's own
            W[:k, :12] = rigid_directions(model, layout)
            W[k:, 12:] = np.eye(extra)
            Hw, gw = W.T @ H @ W, W.T @ g
            try:
                d = np.linalg.solve(Hw + lam * np.diag(np.maximum(np.diag(Hw), 1e-30)), -gw)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            dd: FloatArray = np.asarray(d, dtype=np.float64)
            if not np.all(np.isfinite(dd)):
                lam *= 10.0
                if lam > 1e8:
                    break
                continue
            trial_state = step(state, dd[:12])
            trial, trial_m = build(trial_state), meas.moved(dd[12:])
            tn = _normal(trial, layout, trial_m, data, limit)
            if tn[2] <= cost:
                # converged: the decrease below a millionth of the cost (the placement's own
                # noise is far above it; a tenth of a per cent of σ in each parameter)
                done = cost - tn[2] < 1e-6 * max(cost, 1e-30)
                state, model, meas, normal = trial_state, trial, trial_m, tn
                lam = max(lam / 10.0, 1e-12)
                if done:
                    break
            else:
                lam *= 10.0
                if lam > 1e8:
                    break
        norms = normal[5]
        finite = norms[np.isfinite(norms)]
        scale = float(np.median(finite)) / CHI_MEDIAN.get(meas.dim, 1.0) if finite.size else 0.0
        if round_ == 0 and not scale < far:
            break  # no placement found near the observations: judging outliers adds nothing
        limit = threshold * max(scale, 1e-12)
    return model, meas


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
