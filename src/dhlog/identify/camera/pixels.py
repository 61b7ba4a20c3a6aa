"""A camera's measurement model (:class:`PixelModel`, a
:class:`~dhlog.identify.fit.measure.Measurement`): the whole model's maximum-likelihood fit in
pixels, every detected board corner an observation.

The model is the tracker's (:class:`~dhlog.identify.fit.axismodel.AxisModel` with a target frame):
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
fitted axes as for a tracker (:func:`~dhlog.identify.read.extract.extract_dh`): the base's pose in M
is the camera's (eye-to-hand) or the board's (eye-in-hand) pose in the robot's base frame, the
carried frame on the flange the board's mount (eye-to-hand) or the camera's (eye-in-hand: the
hand-eye calibration).

Each corner's residual (predicted − detected, px) is weighted by one σ in pixels, the data's
own (a robust scale at the start, then χ²/dof at the optimum), and a corner beyond
``threshold`` σ (a false detection) is held out by a truncated quadratic. Levenberg–Marquardt
steps within the directions the corners determine (:class:`~dhlog.identify.fit.whole.Determined`);
the covariance is ``(JᵀJ)⁻¹ σ²`` there.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.measure import FromJacobian, MeasuredFit, fit_measured, place_by_lm
from dhlog.identify.fit.placement import Stand
from dhlog.identify.fit.prediction import predict_columns, predict_orientation, prefix_motions
from dhlog.model.dh import StandardDH
from dhlog.vision.camera import Intrinsics

SETUPS = ("eye-to-hand", "eye-in-hand")


#: a block of corners as sites (:meth:`Corners.sites`)
_Sites = tuple[FloatArray, NDArray[np.intp], FloatArray, NDArray[np.intp]]


@dataclass(frozen=True)
class Corners:
    """The pixel observations of one camera: ``Q`` (f, n) each frame's joint values;
    ``frame`` (N,) each corner's frame (an index into ``Q``); ``points`` (N, 3) the corner in
    the board's frame from its centre (m); ``uv`` (N, 2) where it was detected (px)."""

    Q: FloatArray
    frame: NDArray[np.intp]
    points: FloatArray
    uv: FloatArray
    #: with several cameras (:class:`CamerasModel`), each corner's camera (N,; 0 the first)
    camera: NDArray[np.intp] | None = None

    @property
    def frames(self) -> int:
        return int(self.Q.shape[0])

    def frame_slices(self) -> list[slice]:
        """Each frame's corners as a slice (the corners stand in frame order, as
        :func:`~dhlog.identify.camera.poses.corners_of` and :meth:`of_frames` give them): one
        search, not a mask over every corner a frame."""
        if self.frame.size and np.any(np.diff(self.frame) < 0):
            raise ValueError("the corners are not in frame order")
        edges = np.searchsorted(self.frame, np.arange(self.frames + 1)).tolist()
        return [slice(a, b) for a, b in itertools.pairwise(edges)]

    def distinct(self) -> tuple[FloatArray, NDArray[np.intp], FloatArray, NDArray[np.intp]]:
        """The distinct joint vectors (u, n) and each frame's (f,), the distinct board points
        (P, 3) and each corner's (N,): equal values give equal predictions, so frames of a
        still pose share theirs (computed once a set of corners, then kept)."""
        kept = self.__dict__.get("_distinct")
        if kept is None:
            Qd, q_of = distinct_rows(self.Q)
            Pd, p_of = distinct_rows(self.points)
            kept = (Qd, q_of, Pd, p_of)
            object.__setattr__(self, "_distinct", kept)
        return kept

    def sites(self, sl: slice) -> tuple[FloatArray, NDArray[np.intp], FloatArray, NDArray[np.intp]]:
        """The corners ``sl`` as sites — each distinct (joint vector, board point) among them,
        whose prediction is one for all its corners: the distinct joint vectors (u, n), each
        site's among them (s,), each site's board point (3, s) and each corner's site (c,).
        Kept a slice once found: a fit asks for the same blocks at every step."""
        kept: dict[tuple[int, int], _Sites] = self.__dict__.setdefault("_sites", {})
        at = (int(sl.start or 0), int(sl.stop if sl.stop is not None else self.uv.shape[0]))
        found = kept.get(at)
        if found is None:
            Qd, q_of, Pd, p_of = self.distinct()
            key = q_of[self.frame[sl]] * Pd.shape[0] + p_of[sl]
            site, inv = np.unique(key, return_inverse=True)
            used, back = np.unique(site // Pd.shape[0], return_inverse=True)
            found = (Qd[used], back.astype(np.intp), Pd[site % Pd.shape[0]].T, inv.astype(np.intp))
            kept[at] = found
        return found

    def of_frames(self, chosen: NDArray[np.bool_]) -> Corners:
        """The observations of the frames ``chosen`` (f,) only, renumbered."""
        index = np.cumsum(chosen) - 1
        keep = chosen[self.frame]
        return Corners(
            self.Q[chosen],
            index[self.frame[keep]].astype(np.intp),
            self.points[keep],
            self.uv[keep],
            None if self.camera is None else self.camera[keep],
        )


def distinct_rows(A: FloatArray) -> tuple[FloatArray, NDArray[np.intp]]:
    """The distinct rows of ``A`` (m, k) in lexicographic order and each row's index among
    them — ``np.unique(A, axis=0, return_inverse=True)`` by one ``lexsort`` of the columns
    (``unique``'s sort of rows as records takes 12× as long on a camera log's corners)."""
    if A.shape[0] == 0:
        return A[:0], np.zeros(0, np.intp)
    order = np.lexsort(A.T[::-1])
    ranked = A[order]
    new = np.empty(ranked.shape[0], dtype=bool)
    new[0] = True
    np.any(ranked[1:] != ranked[:-1], axis=1, out=new[1:])
    index = np.empty(ranked.shape[0], dtype=np.intp)
    index[order] = np.cumsum(new) - 1
    return ranked[new], index


@dataclass(frozen=True)
class PixelModel:
    """The camera measurement model: the set-up and the intrinsics; with ``refine``, the
    intrinsics' parameters (fx, fy, cx, cy and the lens coefficients) follow the model's."""

    setup: str
    intrinsics: Intrinsics
    refine: bool = False

    #: a corner's pixel: two components
    dim: int = 2
    #: corners per block of the normal equations (:meth:`normal_block`): its work is per
    #: distinct joint vector and board point, its memory ~0.5 kB a site, so blocks larger than
    #: a tracker's keep the calls few where still poses repeat one prediction over many frames
    block: ClassVar[int] = 100_000

    def count(self, data: Corners) -> int:
        return int(data.uv.shape[0])

    def observed(self, data: Corners, sl: slice) -> FloatArray:
        return data.uv[sl]

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

    def place(
        self,
        table: StandardDH,
        reference_pose: FloatArray,
        T_measurement_base: FloatArray,
        tool_point: FloatArray,
        tool_rotation: FloatArray | None,
        data: Corners,
        *,
        far: float = math.inf,
    ) -> tuple[AxisModel, PixelModel]:
        """The camera's placement: Levenberg–Marquardt in pixels
        (:func:`~dhlog.identify.fit.measure.place_by_lm`; ``far``: the robust scale, px, from
        which no placement is near the corners)."""
        if tool_rotation is None:
            raise ValueError("a camera's placement carries a frame: give its tool_rotation.")
        return place_by_lm(
            table,
            reference_pose,
            Stand(T_measurement_base, tool_point, tool_rotation),
            self,
            data,
            far=far,
        )

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
        used, back = np.unique(data.frame[sl], return_inverse=True)
        return self._seen(model, layout, bases, data.Q[used], back, data.points[sl].T)

    def _seen(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        Q: FloatArray,
        back: NDArray[np.intp],
        c: FloatArray,
    ) -> tuple[FloatArray, FloatArray | None]:
        """Board points ``c`` (3, k) seen at the joint vectors ``Q[back]`` in the camera's
        frame (k, 3), and with ``layout`` their Jacobian (size, 3, k)."""
        prefix = prefix_motions(model, Q)
        p, Jp = predict_columns(model, Q, layout, bases, None, prefix)
        if layout is None or bases is None:
            R = _rotations(model, Q)
            Jo = None
        else:
            R, Jo = predict_orientation(model, Q, layout, bases, prefix)
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
        if layout is None:  # each distinct (joint vector, board point) projected once
            Q, back, c, inv = data.sites(sl)
            X, _ = self._seen(model, None, None, Q, back, c)
            return self.intrinsics.project(X)[inv], None
        X, JX = self.in_camera(model, layout, bases, data, sl)
        assert JX is not None
        uv, jp, ji = self.intrinsics.project_jacobian(X)
        J = np.einsum("kab,sbk->kas", jp, JX)
        if self.refine:
            J = np.concatenate([J, ji], axis=2)
        return uv, J

    def normal_block(
        self,
        model: AxisModel,
        layout: ParameterLayout,
        bases: list[tuple[FloatArray, FloatArray]],
        data: Corners,
        sl: slice,
        limit: float,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The corners ``sl``' residuals (c, 2: predicted − detected) and, over those whose
        residual norm is within ``limit``, their ``JᵀJ`` (size + extra, size + extra) and
        ``Jᵀr`` (size + extra,) — the sums :meth:`predict`'s Jacobian gives, taken by the chain
        rule through each frame's Jacobian ``G`` (6, size) of the carried frame's motion (its
        origin's shift and its turn in M): a corner's 2 × size row is ``B G`` with ``B`` its own
        2 × 6, so a frame's corners enter as ``Gᵀ (Σ BᵀB) G`` instead of one wide row each. A
        board point seen at one joint vector in several frames (a still pose held) is one site:
        predicted once, its ``BᵀB`` counted once a corner within ``limit``, its ``Bᵀ`` times their
        residuals' sum — the same sums."""
        # the sites: each distinct (joint vector, board point) of the corners, predicted once
        Q, back, c, inv = data.sites(sl)
        prefix = prefix_motions(model, Q)
        p, Jp = predict_columns(model, Q, layout, bases, None, prefix)
        R, Jo = predict_orientation(model, Q, layout, bases, prefix)
        assert Jp is not None
        Rk, pk = R[:, :, back], p[:, back]
        if self.setup == "eye-to-hand":
            w = np.einsum("ijk,jk->ik", Rk, c)  # X = p + R c: dX = dp − [R c]× dω
            X = pk + w
        else:
            w = c - pk  # X = Rᵀ (c − p): dX = −Rᵀ (dp − [c − p]× dω)
            X = np.einsum("jik,jk->ik", Rk, w)
        uv, jp, ji = self.intrinsics.project_jacobian(X.T)
        r = uv[inv] - data.uv[sl]
        nrm = np.sqrt(np.sum(r**2, axis=1))
        finite = np.isfinite(nrm)
        use = finite & (nrm <= limit)
        width = layout.size + self.extra
        if limit == np.inf and not finite.all():
            # a corner behind the camera taken in: its row of the Jacobian is NaN, so are the sums
            return r, np.full((width, width), np.nan), np.full(width, np.nan)
        # a site's corners within the limit: their count and the sum of their residuals
        sites = c.shape[1]
        n = np.bincount(inv[use], minlength=sites).astype(np.float64)
        rs = np.stack([np.bincount(inv[use], r[use, a], sites) for a in (0, 1)], axis=1)
        on = n > 0
        jpu, wu, fu, nu, ru = jp[on], w[:, on].T, back[on], n[on], rs[on]
        if self.setup != "eye-to-hand":
            jpu = -np.einsum("kaj,ijk->kai", jpu, Rk[:, :, on])  # ∂uv/∂(c − p) of X = Rᵀ(c − p)
        B = np.empty((jpu.shape[0], 2, 6))
        B[:, :, :3] = jpu
        B[:, :, 3:] = np.cross(wu[:, None, :], jpu)  # a (−[w]×) = w × a for a row a
        f = Q.shape[0]
        BtB = _frame_sums(fu, np.einsum("kai,kaj,k->kij", B, B, nu), f)  # (f, 6, 6)
        Btr = _frame_sums(fu, np.einsum("kai,ka->ki", B, ru), f)  # (f, 6)
        size = layout.size
        G = np.concatenate([Jp, Jo], axis=1).transpose(2, 1, 0).reshape(6 * f, size)
        Hk = G.T @ np.matmul(BtB, G.reshape(f, 6, size)).reshape(6 * f, size)
        gk = G.T @ Btr.reshape(-1)
        if not self.refine:
            return r, Hk, gk
        e = self.extra
        jiu = ji[on]
        cross = _frame_sums(fu, np.einsum("kai,kaj,k->kij", B, jiu, nu), f)  # (f, 6, e)
        Hke = G.T @ cross.reshape(6 * f, e)
        Hee = np.einsum("kai,kaj,k->ij", jiu, jiu, nu)
        H = np.block([[Hk, Hke], [Hke.T, Hee]])
        return r, H, np.concatenate([gk, np.einsum("kai,ka->i", jiu, ru)])


@dataclass(frozen=True)
class CamerasModel(FromJacobian):
    """Several fixed cameras seeing one board on the flange (eye-to-hand), a
    :class:`~dhlog.identify.fit.measure.Measurement`: M is the first camera's frame; camera k ≥ 1
    sits at ``poses[k]`` (4×4, in M), six parameters of its own each (a small rotation about
    M's axes, then a shift), fitted with the model; each camera's intrinsics held. The data are
    :class:`Corners` with ``camera`` set."""

    intrinsics: tuple[Intrinsics, ...]
    poses: tuple[FloatArray, ...]
    dim: int = 2
    setup: str = "eye-to-hand"

    @property
    def extra(self) -> int:
        return 6 * (len(self.intrinsics) - 1)

    def count(self, data: Corners) -> int:
        return int(data.uv.shape[0])

    def observed(self, data: Corners, sl: slice) -> FloatArray:
        return data.uv[sl]

    def moved(self, delta: FloatArray) -> CamerasModel:
        poses = [self.poses[0]]
        for k in range(1, len(self.poses)):
            d = delta[6 * (k - 1) : 6 * k]
            T = self.poses[k].copy()
            T[:3, :3] = rotation_from_vector(d[:3]) @ T[:3, :3]
            T[:3, 3] = T[:3, 3] + d[3:]
            poses.append(T)
        return replace(self, poses=tuple(poses))

    def place(
        self,
        table: StandardDH,
        reference_pose: FloatArray,
        T_measurement_base: FloatArray,
        tool_point: FloatArray,
        tool_rotation: FloatArray | None,
        data: Corners,
        *,
        far: float = math.inf,
    ) -> tuple[AxisModel, CamerasModel]:
        """The cameras' placement: Levenberg–Marquardt in pixels, the
        further cameras' poses with it (:func:`~dhlog.identify.fit.measure.place_by_lm`)."""
        if tool_rotation is None:
            raise ValueError("a camera's placement carries a frame: give its tool_rotation.")
        return place_by_lm(
            table,
            reference_pose,
            Stand(T_measurement_base, tool_point, tool_rotation),
            self,
            data,
            far=far,
        )

    def in_camera(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Corners,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        """The corners ``sl`` in their own camera's frame (c, 3), and their Jacobian
        (size, 3, c) over the model's local parameters (the cameras' own not included)."""
        X, J = PixelModel("eye-to-hand", self.intrinsics[0]).in_camera(
            model, layout, bases, data, sl
        )
        assert data.camera is not None
        cam = data.camera[sl]
        out = X.copy()
        Jout = None if J is None else J.copy()
        for k in range(1, len(self.poses)):
            at = cam == k
            if not at.any():
                continue
            R, t = self.poses[k][:3, :3], self.poses[k][:3, 3]
            out[at] = (X[at] - t) @ R
            if Jout is not None and J is not None:
                Jout[:, :, at] = np.einsum("ji,sjc->sic", R, J[:, :, at])
        return out, Jout

    def predict(
        self,
        model: AxisModel,
        layout: ParameterLayout | None,
        bases: list[tuple[FloatArray, FloatArray]] | None,
        data: Corners,
        sl: slice,
    ) -> tuple[FloatArray, FloatArray | None]:
        X_M, J_M = PixelModel("eye-to-hand", self.intrinsics[0]).in_camera(
            model, layout, bases, data, sl
        )
        assert data.camera is not None
        cam = data.camera[sl]
        c = X_M.shape[0]
        uv = np.full((c, 2), np.nan)
        size = 0 if layout is None else layout.size
        J = None if J_M is None else np.zeros((c, 2, size + self.extra))
        for k in range(len(self.poses)):
            at = cam == k
            if not at.any():
                continue
            R, t = self.poses[k][:3, :3], self.poses[k][:3, 3]
            v = X_M[at] - t
            X = v @ R
            if J is None or J_M is None:
                uv[at] = self.intrinsics[k].project(X)
                continue
            uv_k, jp, _ = self.intrinsics[k].project_jacobian(X)
            uv[at] = uv_k
            JX = np.einsum("ji,sjc->sic", R, J_M[:, :, at])
            J[at, :, :size] = np.einsum("kab,sbk->kas", jp, JX)
            if k:
                o = size + 6 * (k - 1)
                # X_k = Rᵀ (X − t): a turn δω of the camera gives Rᵀ [X − t]× δω, a shift −Rᵀ δt
                skew = np.zeros((v.shape[0], 3, 3))
                skew[:, 0, 1], skew[:, 0, 2] = -v[:, 2], v[:, 1]
                skew[:, 1, 0], skew[:, 1, 2] = v[:, 2], -v[:, 0]
                skew[:, 2, 0], skew[:, 2, 1] = -v[:, 1], v[:, 0]
                J[at, :, o : o + 3] = np.einsum("kab,cb,kcd->kad", jp, R, skew)
                J[at, :, o + 3 : o + 6] = -np.einsum("kab,cb->kac", jp, R)
        return uv, J


def _frame_sums(frame: NDArray[np.intp], values: FloatArray, frames: int) -> FloatArray:
    """``values`` (k, …) summed per ``frame`` (k,) into (frames, …): by runs of one frame
    where ``frame`` is in order (the corners stand in frame order), else unbuffered."""
    out = np.zeros((frames, *values.shape[1:]))
    if frame.size and np.all(frame[1:] >= frame[:-1]):
        starts = np.flatnonzero(np.concatenate([[True], frame[1:] != frame[:-1]]))
        out[frame[starts]] = np.add.reduceat(values, starts, axis=0)
    else:
        np.add.at(out, frame, values)
    return out


def _rotations(model: AxisModel, Q: FloatArray) -> FloatArray:
    """The carried frame's orientation (3, 3, f) at ``Q``."""
    layout = ParameterLayout.of(model.types, rotation=True)
    R, _ = predict_orientation(model, Q, layout, model.bases())
    return R


PixelFit = MeasuredFit


def fit_pixels(
    start: AxisModel,
    measurement: PixelModel,
    data: Corners,
    *,
    threshold: float = 5.0,
    within: FloatArray | None = None,
    sigma_px: float | None = None,
) -> MeasuredFit:
    """:func:`~dhlog.identify.fit.measure.fit_measured` of a camera's corners (the carried frame's
    orientation is part of the model)."""
    if start.tool_rotation is None:
        raise ValueError("the pixel fit needs the model's carried frame (tool_rotation)")
    return fit_measured(
        start, measurement, data, threshold=threshold, within=within, sigma=sigma_px
    )
