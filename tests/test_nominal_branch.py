"""The result's table follows the nominal's branch of every ambiguous choice (DESIGN.md,
Conventions), so measured − nominal is the table minus the nominal.

A UR5 as Universal Robots publish it (a2 = −425 mm, a3 = −392.25 mm, every θ offset 0), 0.5 mm
and 0.05° off its nominal, processed with its nominal: axes 2, 3, 4 are nearly parallel, so rows
2 and 3 are shown in the Hayati–Mirmirani form, whose x axis (toward where the next axis crosses
the plane) has two directions — a ≥ 0 with θ2 = 180° is the same line as a < 0 with θ2 = 0. The
table shown, the JSON, the CSV and measured − nominal take the nominal's; the forward kinematics
is the one the other branch gives (to 1e-9 m), and the σ are those of the other branch. A KR5
(positive a) is left as it was. A previous result as the nominal (a sub-millimetre a1 beside
α1 = 90°) keeps its branch too, and a nominal whose a and α are zero keeps its θ.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from dhlog.geometry._checks import wrap_angle
from dhlog.geometry.lines import Line
from dhlog.identify.read import analytic, extract, hayati, propagate
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import dh_model_from
from dhlog.io.memory import log_data_from_session
from dhlog.model.dh import HayatiDH, StandardDH
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.result.document import nominal_difference, result_csv, result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

OFF = {"perturb_length": 5e-4, "perturb_angle": math.radians(0.05), "seed": 3}


def _config(protocol: str, seed: int = 3) -> SimulationConfig:
    off = {**OFF, "seed": seed}
    return SimulationConfig(protocol=protocol, poses=60, **off)  # type: ignore[arg-type]


def _session(robot: str, protocol: str) -> Session:
    return simulate_session(load_robot(robot), _config(protocol))


def _by_signs(
    x_next: np.ndarray,
    x_i: np.ndarray | None,
    z_i: np.ndarray,
    z_next: np.ndarray,
    offset: np.ndarray,
    nominal: StandardDH,
    i: int,
    theta: np.ndarray,
) -> np.ndarray:
    """x_{i+1} as the sign of the nominal's a_i (beyond 1 µm) or else of its α_i gives it."""
    a, sin_alpha = float(offset @ x_next), float(np.cross(z_i, z_next) @ x_next)
    if abs(nominal.a[i]) > 1e-6:
        return x_next if a * nominal.a[i] >= 0.0 else -x_next
    if abs(math.sin(nominal.alpha[i])) > 1e-6:
        return x_next if sin_alpha * math.sin(nominal.alpha[i]) >= 0.0 else -x_next
    return x_next


#: a reference pose far from home (the axes read off there; θ = offset + joint value)
TURNED = np.array([0.3, -1.2, 2.8, 2.9, -2.5, 1.0])


def _run(session: Session, robot: str, reference: np.ndarray | None = None) -> Identification:
    log = log_data_from_session(session)
    return process_data(log, ProcessOptions(nominal=dh_model_from(robot), reference_pose=reference))


def _unbranched(
    session: Session, robot: str, reference: np.ndarray | None = None
) -> Identification:
    """The same run with the Hayati rows on their own branch (a ≥ 0): no reference row."""
    with pytest.MonkeyPatch.context() as mp:
        for module in (hayati, analytic, propagate):
            mp.setattr(module, "row_reference", lambda *args: None)
        return _run(session, robot, reference)


def _shown(doc: dict[str, object]) -> StandardDH:
    """The table the result shows (its ``hayati_dh`` rows), as the exports read it."""
    rows = doc["hayati_dh"]["rows"]  # type: ignore[index]
    return HayatiDH(
        [r["type"] for r in rows],
        [r["theta_offset"] for r in rows],
        [r.get("d_offset", 0.0) for r in rows],
        [r["a"] for r in rows],
        [r["alpha"] for r in rows],
        [r.get("beta", 0.0) for r in rows],
        [r["form"] == "hayati" for r in rows],
    )


def _fk(table: StandardDH, result: Identification, Q: np.ndarray) -> np.ndarray:
    ex = result.extraction
    assert ex is not None
    return fk_point(table, Q, ex.tool_point, T_base=ex.T_measurement_base)


@pytest.fixture(scope="module", params=["sweeps", "random-poses", "sweeps, turned"])
def ur5(request: pytest.FixtureRequest) -> tuple[Identification, Identification]:
    protocol, _, turned = str(request.param).partition(", ")
    session = _session("ur5", protocol)
    reference = TURNED if turned else None
    return _run(session, "ur5", reference), _unbranched(session, "ur5", reference)


def test_ur5_table_has_the_nominal_signs_and_offsets(
    ur5: tuple[Identification, Identification],
) -> None:
    result, _ = ur5
    doc = result_document(result)
    table = _shown(doc)
    assert table.hayati[1] and table.hayati[2]  # type: ignore[attr-defined]
    nominal = load_robot("ur5").table
    # a2, a3 < 0 as published; θ offsets within a few mrad of 0 (0.05° σ perturbation)
    assert table.a[1] < -0.42 and table.a[2] < -0.39
    for i in range(6):
        assert abs(wrap_angle(table.theta_offset[i] - nominal.theta_offset[i])) < 5e-3, i
        assert abs(wrap_angle(table.alpha[i] - nominal.alpha[i])) < 5e-3, i
        assert abs(table.a[i] - nominal.a[i]) < 3e-3, i
    # the pairs' Hayati rows (each from the standard frame before it: θ within its σ of 0,
    # which is the standard row's ill-conditioned one after a nearly parallel pair) and the CSV
    for row in doc["hayati"]:
        near = 5e-3 + 4 * row["std"]["theta"]
        assert row["a"] < 0 and abs(row["theta_offset"]) < near, row
    lines = list(csv.DictReader(io.StringIO(result_csv(result))))
    assert float(lines[1]["a_mm"]) < -420 and abs(float(lines[1]["theta_offset_deg"])) < 0.3
    assert float(lines[2]["a_mm"]) < -390 and abs(float(lines[3]["theta_offset_deg"])) < 0.3


def test_ur5_branch_keeps_the_forward_kinematics_and_the_sigma(
    ur5: tuple[Identification, Identification],
) -> None:
    result, before = ur5
    table, other = _shown(result_document(result)), _shown(result_document(before))
    assert other.a[1] > 0.42  # the other branch of the same lines
    assert abs(abs(wrap_angle(other.theta_offset[1])) - math.pi) < 5e-3
    Q = np.random.default_rng(5).uniform(-math.pi, math.pi, (200, 6))
    assert np.max(np.linalg.norm(_fk(table, result, Q) - _fk(other, before, Q), axis=1)) < 1e-9
    ex = result.extraction
    assert ex is not None  # and the standard table's FK
    assert (
        np.max(np.linalg.norm(_fk(table, result, Q) - _fk(ex.standard, result, Q), axis=1)) < 1e-9
    )
    c, c0 = result.conditioned, before.conditioned
    assert c is not None and c0 is not None
    np.testing.assert_allclose(c.std, c0.std, rtol=1e-4, atol=1e-12)
    assert np.array_equal(np.isnan(c.std), np.isnan(c0.std))
    s, s0 = np.asarray(result.hayati_std), np.asarray(before.hayati_std)
    np.testing.assert_allclose(s, s0, rtol=1e-4, atol=1e-12)


def test_ur5_measured_minus_nominal_is_the_table_minus_the_nominal(
    ur5: tuple[Identification, Identification],
) -> None:
    result, _ = ur5
    table = _shown(result_document(result))
    nominal = load_robot("ur5").table
    diff = nominal_difference(result, shown=True)
    assert diff is not None
    beta = np.asarray(table.beta)  # type: ignore[attr-defined]
    for i in range(6):
        second = beta[i] if table.hayati[i] else table.d_offset[i] - nominal.d_offset[i]  # type: ignore[attr-defined]
        want = [
            wrap_angle(table.theta_offset[i] - nominal.theta_offset[i]),
            second,  # the nominal's axes 2, 3, 4 are parallel: its β is 0
            table.a[i] - nominal.a[i],
            wrap_angle(table.alpha[i] - nominal.alpha[i]),
        ]
        np.testing.assert_allclose(diff[i], want, atol=1e-12)
    assert abs(diff[1, 2]) < 3e-3 and abs(diff[1, 0]) < 5e-3  # small: not 850 mm, not 180°


@pytest.mark.parametrize("robot", ["kr5", "puma560"])
def test_a_nominal_on_the_default_branch_changes_nothing(robot: str) -> None:
    """Positive a (KR5: 600 mm, PUMA: 431.8 mm): the branch the nominal takes is the one taken
    without it; the shown table is the one without the branch choice, to the bit."""
    session = _session(robot, "sweeps")
    result, before = _run(session, robot), _unbranched(session, robot)
    doc, doc0 = result_document(result), result_document(before)
    assert doc["hayati_dh"] == doc0["hayati_dh"] and doc["hayati"] == doc0["hayati"]
    nominal = load_robot(robot).table
    table = _shown(doc)
    for i in range(6):
        assert abs(table.a[i] - nominal.a[i]) < 3e-3, i
        assert abs(wrap_angle(table.theta_offset[i] - nominal.theta_offset[i])) < 5e-3, i


def test_hayati_branches_describe_the_same_line() -> None:
    """Both branches of a Hayati row put the next frame's origin and z axis at the same place,
    the frame turned by π about z; the reference picks by a's sign, or by θ where its a is 0."""
    F = np.eye(4)
    line = Line(np.array([-0.4, 0.01, 0.02]), np.array([0.001, -0.002, 1.0]))
    free = hayati.hayati_parameters(F, line, (2, 3))
    neg = hayati.hayati_parameters(F, line, (2, 3), (-0.425, 0.0))
    zero = hayati.hayati_parameters(F, line, (2, 3), (0.0, 0.0))
    assert free.a > 0 and neg.a < 0 and zero.a < 0 and abs(neg.theta) < 0.1
    A = hayati.hayati_transform(free.theta, free.a, free.alpha, free.beta)
    B = hayati.hayati_transform(neg.theta, neg.a, neg.alpha, neg.beta)
    np.testing.assert_allclose(A[:3, 3], B[:3, 3], atol=1e-15)
    np.testing.assert_allclose(A[:3, 2], B[:3, 2], atol=1e-15)
    np.testing.assert_allclose(A[:3, 0], -B[:3, 0], atol=1e-15)
    assert hayati.hayati_parameters(F, line, (2, 3), (0.0, math.pi)).a > 0


def test_a_nominal_without_a_sign_gives_its_theta() -> None:
    """A SCARA's prismatic axis 4 meets axis 3 (nominal a3 = 0, α3 = 0) at a tilt of the noise's
    size: x4 along their cross product has no sign the nominal's a or α could give; it takes the
    one that puts θ3 nearer the nominal's 0 (it was 178° off). The FK is the same."""
    session = _session("scara", "random-poses")
    result = _run(session, "scara")
    with pytest.MonkeyPatch.context() as mp:  # every x as Eq. 17-19 give it
        mp.setattr(extract, "_nearest_branch", lambda x_next, *args: x_next)
        before = _run(session, "scara")
    ex, ex0 = result.extraction, before.extraction
    assert ex is not None and ex0 is not None
    assert abs(wrap_angle(ex.standard.theta_offset[2])) < math.pi / 2
    assert abs(wrap_angle(ex0.standard.theta_offset[2])) > math.pi / 2
    Q = np.random.default_rng(5).uniform(-1.0, 1.0, (200, 4)) * [2.5, 2.5, 3.0, 0.04]
    got, want = _fk(ex.standard, result, Q), _fk(ex0.standard, before, Q)
    assert np.max(np.linalg.norm(got - want, axis=1)) < 1e-9


@pytest.mark.parametrize("robot", ["ur5", "puma560"])
def test_a_previous_result_as_the_nominal(robot: str, tmp_path: Path) -> None:
    """Recalibrating against the last result (``--nominal last.dh.json``): its a1 is a fraction
    of a mm (the robot's, not the library's 0), its α1 90°. Following the sign of so small an a1
    flipped x2 (α1 −90°, θ2 180° off: measured − nominal said ±180°); the row's nearest branch
    keeps every difference to what the two robots differ by (0.5 mm, 0.05° σ each), and the FK
    is the same as on the other branch."""
    first = _run(simulate_session(load_robot(robot), _config("sweeps", seed=11)), robot)
    path = tmp_path / "last.dh.json"
    path.write_text(json.dumps(result_document(first)))
    session = simulate_session(load_robot(robot), _config("sweeps", seed=12))
    log = log_data_from_session(session)
    result = process_data(log, ProcessOptions(nominal=dh_model_from(str(path))))
    with pytest.MonkeyPatch.context() as mp:  # every x_{i+1} by a's sign, else α's
        mp.setattr(extract, "_nearest_branch", _by_signs)
        before = process_data(log, ProcessOptions(nominal=dh_model_from(str(path))))
    diff, diff0 = nominal_difference(result, shown=True), nominal_difference(before, shown=True)
    assert diff is not None and diff0 is not None
    assert np.max(np.abs(diff0[:, [0, 3]])) > 3.0  # the flip this guards against
    assert np.max(np.abs(diff[:, [0, 3]])) < math.radians(1.0), np.degrees(diff[:, [0, 3]])
    assert np.max(np.abs(diff[:, 2])) < 5e-3, diff[:, 2]
    ex, ex0 = result.extraction, before.extraction
    assert ex is not None and ex0 is not None
    Q = np.random.default_rng(5).uniform(-math.pi, math.pi, (200, 6))
    got, want = _fk(ex.standard, result, Q), _fk(ex0.standard, before, Q)
    assert np.max(np.linalg.norm(got - want, axis=1)) < 1e-9
