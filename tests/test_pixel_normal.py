"""The camera's normal equations summed frame by frame
(:meth:`dhlog.identify.camera.pixels.PixelModel.normal_block`) against the same sums over the full
Jacobian of every corner (:meth:`~dhlog.identify.camera.pixels.PixelModel.predict`, built corner by
corner with its own chain rule), on corners projected through the simulator's rig: both set-ups,
the intrinsics held and refined, every corner and a cut that holds some out, each pose held for
three frames (a still pose: the frames share their prediction, their noise their own).

The two are the same sums in another order, so they agree to rounding: relative to the largest
entry, 1e-9 (the entries span ~12 decades, px/rad against px/px; float64 rounding of a
20 000-term sum is ~1e-12 of its largest term)."""

from __future__ import annotations

import numpy as np
import pytest

import camera_rig as cams
from dhlog.identify.camera.pixels import PixelModel, distinct_rows
from dhlog.identify.fit.axismodel import ParameterLayout
from dhlog.simulator.camera import CAMERA


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
@pytest.mark.parametrize("refine", [False, True])
def test_frame_sums_are_the_full_jacobians(setup: str, refine: bool) -> None:
    robot, true, rig, Q = cams.session(setup, 5, poses=30)
    Q = np.repeat(Q, 3, axis=0)
    ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng(2))
    data = cams.data(Q, ids, uv)
    assert data.distinct()[0].shape[0] == Q.shape[0] // 3
    model = cams.model(rig, robot.table, robot.n)  # the nominal: residuals of a few px
    layout = ParameterLayout.of(model.types, rotation=True)
    bases = model.bases()
    measurement = PixelModel(setup, CAMERA, refine=refine)
    sl = slice(0, measurement.count(data))
    pred, J = measurement.predict(model, layout, bases, data, sl)
    assert J is not None
    r_full = pred - data.uv
    nrm = np.sqrt(np.sum(r_full**2, axis=1))
    for limit in (np.inf, float(np.median(nrm))):  # every corner, then about half
        use = nrm <= limit
        assert 0 < use.sum() <= nrm.size
        Ju = J[use].reshape(-1, layout.size + measurement.extra)
        r, H, g = measurement.normal_block(model, layout, bases, data, sl, limit)
        np.testing.assert_allclose(r, r_full, rtol=0, atol=1e-9)
        H_full, g_full = Ju.T @ Ju, Ju.T @ r_full[use].reshape(-1)
        assert np.max(np.abs(H - H_full)) < 1e-9 * np.max(np.abs(H_full))
        assert np.max(np.abs(g - g_full)) < 1e-9 * np.max(np.abs(g_full))
    # the pixels alone, each site projected once and handed to its corners, are the same
    # corners' pixels, over all of them and over a part that cuts a still pose in two
    for part in (sl, slice(7, measurement.count(data) - 11)):
        alone, none = measurement.predict(model, None, None, data, part)
        assert none is None
        np.testing.assert_allclose(alone, pred[part], rtol=0, atol=1e-9)


@pytest.mark.parametrize("rows, width, repeats", [(0, 3, 1), (1, 6, 1), (54, 3, 500), (20, 6, 7)])
def test_distinct_rows_are_numpys_unique_rows(rows: int, width: int, repeats: int) -> None:
    """The corners' distinct board points and joint vectors by one lexsort: the rows and the
    inverse ``np.unique(axis=0)`` gives (a signed zero counts as zero, as there)."""
    rng = np.random.default_rng(rows + width)
    base = rng.normal(size=(rows, width)).round(1)  # rounded: rows that share columns
    if rows:
        base[0, 0] = -0.0
    A = base[rng.integers(0, max(rows, 1), rows * repeats)] if rows else base
    if rows > 1:
        A = np.vstack([A, np.abs(base[:1])])  # +0.0 where a row has −0.0
    want, want_of = np.unique(A, axis=0, return_inverse=True)
    got, got_of = distinct_rows(A)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got_of, want_of.reshape(-1))
