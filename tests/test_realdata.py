"""Real measurements: the SScanSS-2 four-axis positioner (shared/realdata/positioner_table.tsv),
converted to a ROS 2 MCAP as a tracker and the axis controller would have logged it (mm, step and
measure), then processed like any log. Not tuned to: the checks are the ones the data's README
states for a correct processing."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer

from dhlog.geometry.lines import Line
from dhlog.identify.run import process_data
from dhlog.io import ros2
from dhlog.io.pipeline import parse_pipeline
from dhlog.io.reader import read_log

DATA = Path(__file__).parents[2] / "shared" / "realdata" / "positioner_table.tsv"
S = 1_000_000_000

PIPELINE = """
name = "positioner"
encoding = "cdr"
length_unit = "mm"
[streams.point]
topic = "/tracker/point"
[streams.joints]
topic = "/joint_states"
required = true
[joints]
names = ["y_stage", "rotation", "x_stage", "z_stage"]
types = ["prismatic", "revolute", "prismatic", "prismatic"]
[segmentation]
min_samples = 5
"""


def write_positioner_log(path: Path) -> None:
    """One measurement per row after a dwell; the controller's joint states at 20 Hz (commanded
    values, mm or rad), stepping from row to row; other axes at home."""
    rows = np.loadtxt(DATA, dtype=str)
    axis = rows[:, 0].astype(int)
    xyz = rows[:, 1:4].astype(float)
    value = rows[:, 4].astype(float)
    home = rows[:, 6].astype(float)
    revolute = rows[:, 5] == "revolute"
    q_rows = np.tile(home[:4], (len(rows), 1))
    q_rows[np.arange(len(rows)), axis - 1] = np.where(revolute, np.radians(value), value)
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros2", library="dhlog test")
        pid = writer.register_schema(
            ros2.POINT_STAMPED, "ros2msg", ros2.MSGDEFS[ros2.POINT_STAMPED].encode()
        )
        jid = writer.register_schema(
            ros2.JOINT_STATE, "ros2msg", ros2.MSGDEFS[ros2.JOINT_STATE].encode()
        )
        pc = writer.register_channel("/tracker/point", "cdr", pid)
        jc = writer.register_channel("/joint_states", "cdr", jid)
        names = ["y_stage", "rotation", "x_stage", "z_stage"]
        events: list[tuple[int, int, bytes]] = []
        for i, q in enumerate(q_rows):
            start = 10 + 2 * i  # s: 2 s per row (1 s dwell before and after the measurement)
            t_js = ((start + np.arange(0.0, 2.0, 0.05)) * S).astype(np.int64)
            for t, payload in zip(
                t_js, ros2.encode_joint_state(t_js, names, np.tile(q, (t_js.size, 1))), strict=True
            ):
                events.append((int(t), jc, payload))
            t_pt = np.array([(start + 1) * S], dtype=np.int64)
            events.append(
                (int(t_pt[0]), pc, ros2.encode_point_stamped(t_pt, xyz[i : i + 1], "tracker")[0])
            )
        for t, channel, payload in sorted(events, key=lambda e: e[0]):
            writer.add_message(channel, t, payload, t)
        writer.finish()  # type: ignore[no-untyped-call]


@pytest.fixture(scope="module")
def positioner(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    if not DATA.exists():
        pytest.skip("shared/realdata is not beside the checkout")
    path = tmp_path_factory.mktemp("real") / "positioner.mcap"
    write_positioner_log(path)
    return process_data(read_log(path, parse_pipeline(PIPELINE, "positioner.toml")))


def angle_between(a: Line, b: Line) -> float:
    return math.degrees(math.acos(min(1.0, abs(float(a.direction @ b.direction)))))


def test_every_axis_fits_within_a_few_hundredths_of_a_millimetre(positioner) -> None:  # type: ignore[no-untyped-def]
    """Across the motion (distance from the fitted line or circle: straightness, roundness) the
    residuals are 11-21 µm RMS. Along the motion the encoder-aided residual also holds the
    stages' positioning error against their commanded values (up to 81 µm RMS on x)."""
    from dhlog.geometry.fitting import orthogonal_distances

    assert all(j.ok for j in positioner.joints), [j.reason for j in positioner.joints]
    points = positioner.segmentation.table.select(["x", "y", "z"]).to_numpy()
    for j in positioner.joints:
        assert j.fit is not None and j.fit.n_points == 11 and j.n_outliers == 0
        across = orthogonal_distances(j.fit, points[j.rows])
        assert np.sqrt(np.mean(across**2)) < 0.05e-3, j.name
        assert j.fit.rms < 0.1e-3, j.name


def test_the_translations_are_near_perpendicular_and_axis_2_near_parallel_to_axis_1(
    positioner,
) -> None:  # type: ignore[no-untyped-def]
    y, rot, x, z = (j.axis for j in positioner.joints)
    for a, b in ((y, x), (y, z), (x, z)):
        assert abs(angle_between(a, b) - 90.0) < 1.0
    assert angle_between(y, rot) < 1.0


def test_the_fitted_travel_agrees_with_the_commanded_values(positioner) -> None:  # type: ignore[no-untyped-def]
    for j in positioner.joints:
        assert j.fit is not None
        if j.fit.kind == "line":
            assert j.fit.encoder_scale is not None
            assert abs(j.fit.encoder_scale - 1.0) < 1e-3, (j.name, j.fit.encoder_scale)


def test_its_holdout_is_the_error_at_its_poses_not_the_rotary_tables_compliance() -> None:
    """``--holdout 5`` on the positioner: the rotary table's axis is vertical behind a linear
    stage, so gravity exerts no torque about it and the compliance family adds no term. When it
    did (only the chain's first axis was exempt), its columns were numerical noise: the
    selection fitted coefficients of 2e11, two folds chose them, their fits did not converge
    (χ²/dof 44 and 36 against 1.9), and the held-out RMS was 72.6 mm against 0.068 mm in
    sample, exit 0. Now 0.074 mm; the in-sample FK RMS bounds it to within 2x here (43 poses,
    each a fifth of a session held out). With the old terms forced back (every revolute axis
    compliant), the broken folds are fitted again from the session's fit and said."""
    if not DATA.exists():
        pytest.skip("shared/realdata is not beside the checkout")
    import dhlog.model.terms as terms
    from dhlog.identify.run import ProcessOptions

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "positioner.mcap"
        write_positioner_log(path)
        pipeline = parse_pipeline(PIPELINE, "positioner.toml")
        log = read_log(path, pipeline)
    options = ProcessOptions(pipeline=pipeline, holdout=5)
    result = process_data(log, options)
    (check,) = result.checks.holdout
    fk = result.checks.validation.rms
    assert check.calibrated.rms < 2 * fk, (check.calibrated.rms, fk)
    assert result.selection is not None
    compliance = [c for c in result.selection.candidates if c.families == ("compliance",)]
    assert compliance and compliance[0].terms == 0
    old = terms.VERTICAL
    try:
        terms.VERTICAL = 0.0  # no axis counts as along gravity: the rotary table's terms back
        forced = process_data(log, options)
    finally:
        terms.VERTICAL = old
    (check,) = forced.checks.holdout
    assert check.calibrated.rms < 2 * fk, (check.calibrated.rms, fk)
    assert any("did not converge" in note for note in check.notes), check.notes
