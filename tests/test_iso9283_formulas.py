"""ISO 9283:1998 characteristics (dhlog.iso9283.formulas) on cases computed by hand, their
invariances, and the inputs they refuse."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dhlog.errors import DhlogError, Iso9283Error, NonFiniteError, ShapeError
from dhlog.iso9283.formulas import (
    distance_accuracy,
    drift,
    matrix_from_abc,
    multi_directional,
    orientation_abc,
    orientation_deviation,
    path_accuracy,
    path_velocity,
    pose_accuracy,
    pose_repeatability,
    speeds_from_positions,
    stabilisation,
    stabilisation_over_cycles,
)

MM = 1e-3
C = np.array([1.2, -0.4, 0.9])


def Rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def Ry(b: float) -> np.ndarray:
    return np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])


def Rz(c: float) -> np.ndarray:
    return np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])


# --- orientation components -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("R", "abc"),
    [
        (Rx(math.pi / 6), (math.pi / 6, 0.0, 0.0)),
        (Ry(-0.3), (0.0, -0.3, 0.0)),
        (Rz(math.pi / 2), (0.0, 0.0, math.pi / 2)),
        (Rz(0.3) @ Ry(0.2) @ Rx(0.1), (0.1, 0.2, 0.3)),
        (Rz(-2.5) @ Ry(1.2) @ Rx(3.0), (3.0, 1.2, -2.5)),
    ],
)
def test_orientation_abc_of_known_rotations(R: np.ndarray, abc: tuple[float, float, float]) -> None:
    np.testing.assert_allclose(orientation_abc(R), abc, atol=1e-12)
    np.testing.assert_allclose(matrix_from_abc(abc), R, atol=1e-12)


def test_orientation_abc_at_b_90_degrees_puts_the_turn_in_c() -> None:
    R = Rz(0.7) @ Ry(math.pi / 2) @ Rx(0.2)  # = Rz(0.5) Ry(90°)
    abc = orientation_abc(R)
    np.testing.assert_allclose(abc, (0.0, math.pi / 2, 0.5), atol=1e-7)
    np.testing.assert_allclose(matrix_from_abc(abc), R, atol=1e-7)


def test_orientation_abc_broadcasts_over_leading_axes() -> None:
    rng = np.random.default_rng(3)
    abc = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(4, 5, 3))
    np.testing.assert_allclose(orientation_abc(matrix_from_abc(abc)), abc, atol=1e-10)


def test_orientation_deviation_is_the_rotation_about_the_base_axes() -> None:
    R_c = Rz(1.1) @ Ry(-0.6) @ Rx(2.0)  # far from the identity
    for axis, R_d in enumerate((Rx(2e-3), Ry(2e-3), Rz(2e-3))):
        expected = np.zeros(3)
        expected[axis] = 2e-3
        np.testing.assert_allclose(orientation_deviation(R_d @ R_c, R_c), expected, atol=1e-15)


# --- 7.2.1 / 7.2.2 pose accuracy and repeatability ---------------------------------------------


def test_square_corners_around_an_offset_barycentre() -> None:
    # four corners of a 4 mm square centred 1 mm (x) and 2 mm (z) from the commanded point
    offset = np.array([1.0, 0.0, 2.0]) * MM
    corners = np.array([[2, 2, 0], [-2, 2, 0], [-2, -2, 0], [2, -2, 0]]) * MM
    attained = C + offset + corners
    ap = pose_accuracy(attained, C)
    np.testing.assert_allclose(ap.barycentre, C + offset, atol=1e-15)
    np.testing.assert_allclose(ap.AP_xyz, offset, atol=1e-15)
    assert ap.AP_P == pytest.approx(math.sqrt(5.0) * MM, rel=1e-12)
    rp = pose_repeatability(attained)
    # every corner lies 2√2 mm from the barycentre: l̄ = 2√2 mm, S_l = 0
    np.testing.assert_allclose(rp.l_j, 2 * math.sqrt(2) * MM, rtol=1e-12)
    assert rp.S_l == pytest.approx(0.0, abs=1e-15)
    assert rp.RP_l == pytest.approx(2 * math.sqrt(2) * MM, rel=1e-12)


def test_repeatability_with_unequal_distances() -> None:
    # attained at −3, −1, +1, +3 mm along x: l = 3, 1, 1, 3 mm, l̄ = 2 mm,
    # S_l = √((1 + 1 + 1 + 1)/3) mm = √(4/3) mm, RP = 2 + 3√(4/3) = 2 + 2√3 mm
    attained = C + np.array([[-3, 0, 0], [-1, 0, 0], [1, 0, 0], [3, 0, 0]]) * MM
    rp = pose_repeatability(attained)
    assert rp.l_mean == pytest.approx(2 * MM, rel=1e-12)
    assert rp.S_l == pytest.approx(math.sqrt(4 / 3) * MM, rel=1e-12)
    assert rp.RP_l == pytest.approx((2 + 2 * math.sqrt(3)) * MM, rel=1e-12)
    doc = rp.document()
    assert doc["RP_l_m"] == rp.RP_l and doc["n"] == 4 and doc["RP_abc_rad"] is None


def test_orientation_accuracy_and_repeatability() -> None:
    R_c = Rz(0.8) @ Ry(0.3) @ Rx(-1.0)
    eps = np.array([-3.0, -1.0, 1.0, 3.0]) * 1e-4
    # attained: about the base's x by eps_j, all 2e-3 rad about the base's z off the command
    R_att = np.array([Rx(e) @ Rz(2e-3) @ R_c for e in eps])
    ap = pose_accuracy(np.tile(C, (4, 1)), C, R_att, R_c)
    assert ap.AP_abc is not None
    np.testing.assert_allclose(ap.AP_abc, [0.0, 0.0, 2e-3], atol=2e-7)  # second order: 3e-4·2e-3
    rp = pose_repeatability(np.tile(C, (4, 1)), R_att)
    assert rp.S_abc is not None and rp.RP_abc is not None
    S_a = math.sqrt((9 + 1 + 1 + 9) / 3) * 1e-4  # sample std of eps
    np.testing.assert_allclose(rp.S_abc, [S_a, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(rp.RP_abc, [3 * S_a, 0.0, 0.0], atol=1e-12)
    assert rp.RP_l == 0.0


def test_repeatability_is_invariant_to_a_rigid_motion_of_all_points() -> None:
    rng = np.random.default_rng(7)
    attained = C + rng.normal(scale=0.05 * MM, size=(30, 3))
    R_att = matrix_from_abc(rng.normal(scale=1e-4, size=(30, 3)))
    rp = pose_repeatability(attained, R_att)
    R = Rz(0.4) @ Ry(-0.2) @ Rx(1.3)
    moved = pose_repeatability(attained + np.array([10.0, -3.0, 2.0]), R_att)
    turned = pose_repeatability(attained @ R.T)
    assert moved.RP_l == pytest.approx(rp.RP_l, rel=1e-9)
    assert turned.RP_l == pytest.approx(rp.RP_l, rel=1e-9)
    assert moved.RP_abc is not None and rp.RP_abc is not None
    np.testing.assert_allclose(moved.RP_abc, rp.RP_abc, rtol=1e-12)
    # the orientation repeatability does not depend on where the mean orientation lies
    rp_far = pose_repeatability(attained, R_att @ (Rz(2.0) @ Ry(1.0) @ Rx(-2.5)))
    assert rp_far.RP_abc is not None
    np.testing.assert_allclose(rp_far.RP_abc, rp.RP_abc, rtol=1e-6)


def test_accuracy_is_zero_when_the_barycentre_is_the_commanded_point() -> None:
    rng = np.random.default_rng(11)
    spread = rng.normal(scale=0.1 * MM, size=(30, 3))
    attained = C + spread - spread.mean(axis=0)
    ap = pose_accuracy(attained, C)
    assert ap.AP_P == pytest.approx(0.0, abs=1e-15)
    assert ap.document()["AP_abc_rad"] is None


# --- 7.2.3 multi-directional, 7.3 distance, 7.6 drift -------------------------------------------


def test_multi_directional_variation() -> None:
    bary = C + np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0]]) * MM  # a 3-4-5 triangle
    abc = np.array([[1e-4, 0, 0], [-2e-4, 5e-5, 0], [0, 0, 3e-4]])
    md = multi_directional(bary, abc)
    assert md.vAP_P == pytest.approx(5 * MM, rel=1e-12)
    assert md.vAP_abc is not None
    np.testing.assert_allclose(md.vAP_abc, [3e-4, 5e-5, 3e-4], atol=1e-18)


def test_distance_accuracy_and_repeatability() -> None:
    c1, c2 = C, C + np.array([1.0, 0.0, 0.0])
    e = np.array([1.0, 2.0, 3.0]) * 1e-4
    p1 = np.tile(c1, (3, 1))
    p2 = c2 + np.column_stack([e, np.zeros(3), np.zeros(3)])
    dc = distance_accuracy(p1, p2, c1, c2)
    # D_j = 1 + e_j: D̄ = 1.0002, AD = 0.2 mm, S_D = std(1, 2, 3)·0.1 mm = 0.1 mm, RD = 0.3 mm
    assert dc.D_c == pytest.approx(1.0, rel=1e-15)
    assert dc.AD_P == pytest.approx(2e-4, rel=1e-9)
    assert dc.RD == pytest.approx(3e-4, rel=1e-9)
    np.testing.assert_allclose(dc.AD_xyz, [2e-4, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(dc.RD_xyz, [3e-4, 0.0, 0.0], atol=1e-15)


def test_drift_of_accuracy_and_repeatability() -> None:
    line = np.array([[-3, 0, 0], [-1, 0, 0], [1, 0, 0], [3, 0, 0]]) * MM
    rp_unit = 2 + 2 * math.sqrt(3)  # RP of the ±1, ±3 pattern in its unit
    first = C + np.array([0.0, 3.0, 4.0]) * MM + line  # AP 5 mm, RP rp_unit mm
    middle = C + np.array([0.0, 0.0, 9.0]) * MM + line
    last = C + np.array([0.0, 6.0, 8.0]) * MM + 0.5 * line  # AP 10 mm, RP rp_unit/2 mm
    d = drift([first, middle, last], C)
    assert d.dAP == pytest.approx(5 * MM, rel=1e-12)
    assert d.dRP == pytest.approx(rp_unit / 2 * MM, rel=1e-12)
    assert d.shift == pytest.approx(5 * MM, rel=1e-12)
    np.testing.assert_allclose(d.AP, [5 * MM, 9 * MM, 10 * MM], rtol=1e-12)


# --- 7.4 / 7.5 stabilisation and overshoot -----------------------------------------------------


def test_stabilisation_time_and_overshoot_of_a_sampled_arrival() -> None:
    # approach along +x, passing through the 0.2 mm band between t = 0.1 and 0.2 s
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    x = np.array([-5.0, -1.0, 0.5, 0.3, -0.15, 0.05, 0.0]) * MM
    p = C + np.column_stack([x, np.zeros(7), np.zeros(7)])
    s = stabilisation(t, p, C, 0.1, band=0.2 * MM)
    assert s.settled_at == pytest.approx(0.4)  # 0.3 mm at 0.3 s is the last sample outside
    assert s.time == pytest.approx(0.3)
    assert s.overshoot == pytest.approx(0.5 * MM, rel=1e-12)
    assert s.entered_at == pytest.approx(0.2)
    assert s.excursion == pytest.approx(0.5 * MM, rel=1e-12)
    # an arrival that does not go past: no overshoot; settling before the signal: time 0
    mono = C + np.column_stack([np.array([-5.0, -1.0, -0.1, -0.05]) * MM, np.zeros(4), np.zeros(4)])
    s2 = stabilisation(t[:4], mono, C, 0.25, band=0.2 * MM)
    assert s2.overshoot == 0.0 and s2.time == 0.0
    # a lateral wobble is an excursion, not an overshoot
    lat = p.copy()
    lat[:, 1] = C[1] + np.array([0.0, 0.0, 0.0, 0.4, 0.0, 0.0, 0.0]) * MM
    lat[:, 0] = C[0] + np.array([-5.0, -1.0, -0.1, 0.0, 0.0, 0.0, 0.0]) * MM
    s3 = stabilisation(t, lat, C, 0.1, band=0.2 * MM)
    assert s3.overshoot == pytest.approx(0.0, abs=1e-15)
    assert s3.excursion == pytest.approx(0.4 * MM, rel=1e-12)
    assert s3.time == pytest.approx(0.3)  # 0.4 mm aside at 0.3 s is the last sample outside
    summary = stabilisation_over_cycles([s, s2, s3])
    assert summary["overshoot_max_m"] == pytest.approx(0.5 * MM)
    assert summary["time_mean_s"] == pytest.approx((0.3 + 0.0 + 0.3) / 3)


def test_stabilisation_refuses_an_arrival_that_never_settles() -> None:
    t = np.array([0.0, 0.1, 0.2])
    p = C + np.array([[-5, 0, 0], [-1, 0, 0], [0.5, 0, 0]]) * MM
    with pytest.raises(Iso9283Error, match=r"still 0.5 mm .* last sample"):
        stabilisation(t, p, C, 0.1, band=0.2 * MM)
    with pytest.raises(Iso9283Error, match="already within the band"):
        stabilisation(t, p[::-1] * 0 + C, C, 0.1, band=0.2 * MM)
    with pytest.raises(Iso9283Error, match="do not increase"):
        stabilisation(t[::-1], p, C, 0.1, band=0.2 * MM)


# --- 8.2 path, 8.4 velocity ---------------------------------------------------------------------


def _line_cycles() -> tuple[np.ndarray, list[np.ndarray]]:
    commanded = np.column_stack([np.linspace(0.1, 0.9, 9), np.zeros(9), np.zeros(9)]) + C
    x = np.arange(-0.05, 1.05, 0.013)  # samples not on the commanded points
    cycles = []
    for y in (1.0, 2.0, 3.0):
        # each cycle a straight line 0.5 mm above, y_j + 10 µm per m of x to the side
        p = np.column_stack([x, (y + 0.01e3 * 1e-3 * x) * MM * 1.0, np.full_like(x, 0.5 * MM)])
        cycles.append(p + C)
    return commanded, cycles


def test_path_accuracy_and_repeatability_of_offset_straight_lines() -> None:
    commanded, cycles = _line_cycles()
    pc = path_accuracy(cycles, commanded)
    # barycentre at x_i: y = (2 + 0.01 x_i) mm, z = 0.5 mm; largest at x = 0.9
    y_bar = (2.0 + 0.01 * (commanded[:, 0] - C[0])) * MM
    np.testing.assert_allclose(pc.deviation, np.hypot(y_bar, 0.5 * MM), rtol=1e-10)
    assert pc.AT_P == pytest.approx(math.hypot(2.009 * MM, 0.5 * MM), rel=1e-10)
    # l_ij = 1, 0, 1 mm at every point: l̄ = 2/3 mm, S_l = √(1/3) mm, RT = 2/3 + √3 mm
    assert pc.RT_P == pytest.approx((2 / 3 + math.sqrt(3)) * MM, rel=1e-10)
    np.testing.assert_allclose(pc.crossings[:, :, 0], np.tile(commanded[:, :1], (1, 3)), atol=1e-12)
    doc = pc.document()
    assert doc["AT_at_point"] == 8 and len(doc["deviation_m"]) == 9


def test_path_orientation_accuracy_and_repeatability() -> None:
    commanded, cycles = _line_cycles()
    R0 = Rz(0.8) @ Ry(-0.4) @ Rx(2.2)
    # cycle j turns about the base's x by alpha_j + 1e-4 rad per m of x along the path: the
    # turn between samples is about one axis, so the interpolation at a crossing is exact
    alpha = np.array([1.0, 2.0, 3.0]) * 1e-4
    R_paths = [
        np.array([Rx(a + 1e-4 * (x - C[0])) @ R0 for x in c[:, 0]])
        for a, c in zip(alpha, cycles, strict=True)
    ]
    R_cmd = np.tile(R0, (len(commanded), 1, 1))
    pc = path_accuracy(cycles, commanded, R_paths=R_paths, R_commanded=R_cmd)
    assert pc.AT_abc is not None and pc.RT_abc is not None and pc.deviation_abc is not None
    # ā_i − a_ci = 2e-4 + 1e-4 x_i, largest at x = 0.9 m; 3 S_a = 3 · std(1, 2, 3)e-4 = 3e-4
    np.testing.assert_allclose(
        pc.deviation_abc[:, 0], 2e-4 + 1e-4 * (commanded[:, 0] - C[0]), atol=1e-12
    )
    np.testing.assert_allclose(pc.AT_abc, [2.9e-4, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pc.RT_abc, [3e-4, 0.0, 0.0], atol=1e-12)
    assert pc.document()["AT_abc_rad"] == pytest.approx([2.9e-4, 0.0, 0.0], abs=1e-12)
    with pytest.raises(Iso9283Error, match="without commanded ones"):
        path_accuracy(cycles, commanded, R_paths=R_paths)


def test_path_accuracy_takes_the_crossing_nearest_the_commanded_point() -> None:
    commanded, cycles = _line_cycles()
    # a cycle that comes back across the planes 5 cm away: the far crossing is ignored
    back = cycles[0][::-1] + np.array([0.0, 0.05, 0.0])
    looped = [np.vstack([c, back]) for c in cycles]
    assert path_accuracy(looped, commanded).AT_P == pytest.approx(
        path_accuracy(cycles, commanded).AT_P, rel=1e-12
    )


def test_path_accuracy_on_a_circle_with_the_default_tangents() -> None:
    # command: 36 points on a 100 mm circle; cycles: concentric circles 0.1, 0.2, 0.6 mm larger,
    # sampled every 0.1°: the chords lie inside the arcs by r (1 − cos 0.05°) < 0.04 µm
    th = np.radians(np.arange(0.0, 360.0, 0.1))
    cmd_th = np.radians(np.arange(5.0, 355.0, 10.0))
    r = 0.1
    commanded = C + r * np.column_stack([np.cos(cmd_th), np.sin(cmd_th), np.zeros_like(cmd_th)])
    offsets = np.array([0.1, 0.2, 0.6]) * MM
    cycles = [C + (r + o) * np.column_stack([np.cos(th), np.sin(th), 0 * th]) for o in offsets]
    pc = path_accuracy(cycles, commanded)
    # barycentre 0.3 mm outside everywhere; l = 0.2, 0.1, 0.3 mm: l̄ = 0.2, S_l = 0.1 mm. At the
    # ends the tangent is a second-order one-sided difference (a first-order one, 5° off the
    # tangent, put the end points 1.1 µm out)
    np.testing.assert_allclose(pc.deviation, 0.3 * MM, atol=1e-7)
    assert pc.RT_P == pytest.approx(0.5 * MM, abs=1e-7)


def test_path_refusals() -> None:
    commanded, cycles = _line_cycles()
    with pytest.raises(Iso9283Error, match="at least 2 cycles"):
        path_accuracy(cycles[:1], commanded)
    short = [c[c[:, 0] < C[0] + 0.5] for c in cycles]
    with pytest.raises(Iso9283Error, match=r"cycle 1 never crosses .* point 5 of 9"):
        path_accuracy(short, commanded)
    with pytest.raises(Iso9283Error, match="coincide"):
        path_accuracy(cycles, np.vstack([commanded[:1], commanded]))


def test_path_velocity() -> None:
    speeds = [np.array([1.0, 1.1, 0.9]), np.array([1.2, 1.2]), np.array([0.8, 1.0])]
    pv = path_velocity(speeds, 1.0)
    # v̄_j = 1.0, 1.2, 0.9; v̄ = 31/30; AV = 1/30; S_v = std(1.0, 1.2, 0.9); FV = 0.2
    assert pv.AV == pytest.approx(1 / 30, rel=1e-12)
    assert pv.RV == pytest.approx(3 * float(np.std([1.0, 1.2, 0.9], ddof=1)), rel=1e-12)
    assert pv.FV == pytest.approx(0.2, rel=1e-12)
    assert pv.document()["AV_percent"] == pytest.approx(100 / 30)
    t = np.array([0.0, 0.5, 1.5])
    p = np.array([[0, 0, 0], [0.3, 0.4, 0.0], [0.3, 0.4, 1.0]])
    np.testing.assert_allclose(speeds_from_positions(t, p), [1.0, 1.0])


# --- refusals ----------------------------------------------------------------------------------


def test_one_cycle_is_refused_naming_what_is_missing() -> None:
    with pytest.raises(Iso9283Error, match=r"pose repeatability.*1 cycles given, at least 2"):
        pose_repeatability(C[None, :])
    with pytest.raises(Iso9283Error, match="at least 2"):
        distance_accuracy(C[None, :], C[None, :], C, C)
    with pytest.raises(Iso9283Error, match="drift: 1 group"):
        drift([np.tile(C, (3, 1))], C)
    with pytest.raises(Iso9283Error, match="approach directions"):
        multi_directional(C[None, :])
    with pytest.raises(Iso9283Error, match="path velocity: 1 cycle"):
        path_velocity([np.ones(3)], 1.0)


def test_non_finite_and_malformed_input_is_refused() -> None:
    bad = np.tile(C, (5, 1))
    bad[2, 1] = np.nan
    with pytest.raises(NonFiniteError, match="1 non-finite"):
        pose_repeatability(bad)
    with pytest.raises(NonFiniteError):
        pose_accuracy(np.tile(C, (5, 1)), [0.0, np.inf, 0.0])
    with pytest.raises(ShapeError, match=r"\(n, 3\)"):
        pose_accuracy(np.zeros((5, 2)), C)
    with pytest.raises(ShapeError, match="proper rotation"):
        pose_repeatability(np.tile(C, (2, 1)), np.array([np.eye(3), 2 * np.eye(3)]))
    with pytest.raises(Iso9283Error, match="without a commanded one"):
        pose_accuracy(np.tile(C, (2, 1)), C, np.array([np.eye(3)] * 2))
    # every refusal is a DhlogError: one line, no traceback at the command line
    assert issubclass(Iso9283Error, DhlogError) and issubclass(NonFiniteError, DhlogError)
