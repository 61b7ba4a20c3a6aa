"""``dhlog import``: tracker-software exports (generic CSV, SpatialAnalyzer points + joints CSV,
Leica CSV with U95) of a step-and-measure session of a KR5 off its nominal, converted to MCAP
with the command, processed like any log: FK against the simulator's truth within the reported
uncertainty, and bad rows named by their line."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.check.validate import fk_prediction_std
from dhlog.identify.run import ProcessOptions, process_log
from dhlog.io.reader import read_log
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

runner = CliRunner()
NOISE = 1e-5


@pytest.fixture(scope="module")
def stops() -> tuple[Session, np.ndarray, np.ndarray]:
    """The tracker's points (one or two per stop, 6 stops per joint) and the joint values there
    (rad), as the tracker software lists them."""
    cfg = SimulationConfig(
        seed=5,
        motion="step",
        steps=6,
        noise=NOISE,
        tracker_rate=1 / 0.3,
        perturb_length=2e-4,
        perturb_angle=math.radians(0.02),
    )
    session = simulate_session(load_robot("kr5"), cfg)
    t = session.point_t_ns.astype(float)
    q = np.column_stack(
        [np.interp(t, session.joint_t_ns.astype(float), c) for c in session.joint_q.T]
    )
    return session, session.point_xyz, q


def fk_check(path: Path, session: Session) -> None:
    result = process_log(path)
    assert result.complete and result.whole is not None, [j.reason for j in result.joints]
    rob = load_robot("kr5")
    Q = np.random.default_rng(1).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    ex = result.extraction
    assert ex is not None
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    err = np.linalg.norm(got - want, axis=1)
    assert np.all(err <= 4.0 * fk_prediction_std(result, Q)), err.max()


def imported(*args: str) -> str:
    result = runner.invoke(app, ["import", *args])
    assert result.exit_code == 0, result.output
    return result.output


def test_a_generic_csv_of_stops_in_mm_and_degrees(stops, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    session, xyz, q = stops
    src = tmp_path / "stops.csv"
    lines = ["X,Y,Z,A1,A2,A3,A4,A5,A6"]
    lines += [
        ",".join(f"{v:.6f}" for v in [*(p * 1e3), *np.degrees(r)])
        for p, r in zip(xyz, q, strict=True)
    ]
    src.write_text("\n".join(lines) + "\n")
    out = imported(str(src), "--joint-names", ",".join(session.joint_names))
    assert "step and measure" in out
    log = tmp_path / "stops.mcap"
    data = read_log(log)
    assert data.pipeline.name == "ros2_tracker" and data.joint_names == session.joint_names
    np.testing.assert_allclose(data.points.select(["x", "y", "z"]).to_numpy(), xyz, atol=1e-9)
    with log.open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["dhlog.import"]["format"] == "csv"
    assert meta["dhlog.import"]["source"] == str(src.resolve())
    fk_check(log, session)


def test_a_timed_csv_keeps_its_times(tmp_path: Path) -> None:
    src = tmp_path / "timed.csv"
    src.write_text("t,x,y,z,q1,q2\n0.0,1,2,3,0,0\n0.01,1,2,4,1,0\n0.025,1,2,5,2,0\n")
    imported(str(src), "--time", "t", "--length-unit", "m", "--angle-unit", "rad")
    data = read_log(tmp_path / "timed.mcap")
    t = data.points["t_ns"].to_numpy()
    np.testing.assert_array_equal(t - t[0], [0, 10_000_000, 25_000_000])
    assert data.joints is not None
    np.testing.assert_allclose(data.joints["q_1"].to_numpy(), [0, 1, 2])


def test_spatialanalyzer_points_matched_by_name_to_a_joints_csv(stops, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    session, xyz, q = stops
    order = np.random.default_rng(2).permutation(len(xyz))  # SA lists points in its own order
    pts = tmp_path / "points.txt"
    pts.write_text(
        "// SpatialAnalyzer ASCII export\nCollection Group Point X Y Z\n"
        + "".join(
            f"A::stops::P{k:03d} {p[0] * 1e3:.5f} {p[1] * 1e3:.5f} {p[2] * 1e3:.5f}\n"
            for k, p in ((k, xyz[k]) for k in order)
        )
    )
    joints = tmp_path / "joints.csv"
    joints.write_text(
        "point,q1,q2,q3,q4,q5,q6\n"
        + "".join(
            f"P{k:03d}," + ",".join(f"{v:.7f}" for v in np.degrees(r)) + "\n"
            for k, r in enumerate(q)
        )
        + "P999,0,0,0,0,0,0\n"  # a row without its point: left out, with a warning
    )
    out = imported(str(pts), "--format", "spatialanalyzer", "--joints-file", str(joints))
    assert "1 row(s) name a point" in out and "P999" in out
    fk_check(tmp_path / "points.mcap", session)


def test_a_leica_csv_keeps_its_u95_as_each_samples_covariance(stops, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    session, xyz, q = stops
    src = tmp_path / "leica.csv"
    u95 = 1.96 * NOISE * 1e3  # mm, per coordinate
    rows = ["Point ID;X [mm];Y [mm];Z [mm];U95 X [mm];U95 Y [mm];U95 Z [mm];J1;J2;J3;J4;J5;J6"]
    for k, (p, r) in enumerate(zip(xyz, q, strict=True)):
        vals = [*(p * 1e3), u95, u95, u95, *np.degrees(r)]
        rows.append(f"P{k};" + ";".join(f"{v:.7f}".replace(".", ",") for v in vals))
    src.write_text("\n".join(rows) + "\n", encoding="cp1252")
    out = imported(str(src), "--format", "leica", "-o", str(tmp_path / "l.mcap"))
    assert "U95" in out
    data = read_log(tmp_path / "l.mcap")
    np.testing.assert_allclose(
        data.points["cxx"].to_numpy(), NOISE**2, rtol=1e-4
    )  # 1.96 vs 1.95996
    np.testing.assert_allclose(data.points["cxy"].to_numpy(), 0.0)
    result = process_log(tmp_path / "l.mcap")
    assert "per-sample" in result.noise.described
    fk_check(tmp_path / "l.mcap", session)


@pytest.mark.parametrize(
    ("text", "args", "message"),
    [
        ("x,y,z,q1\n1,2,3,0\n1,2,oops,1\n", [], "line 3: z 'oops' is not a number"),
        ("x,y,z,q1\n1,2,3,0\n1,2\n", [], "line 3: has 2 field(s), the header 4"),
        (
            "a,b,c,q1\n1,2,3,0\n",
            [],
            "no column 'x' for the target's x; its columns are a, b, c, q1",
        ),
        ("x,y,z,speed\n1,2,3,0\n", [], "has no joint columns"),
        ("t,x,y,z,q1\n1,1,2,3,0\n0.5,1,2,3,1\n", ["--time", "t"], "line 3: time does not"),
        ("x,y,z,q1\n1,2,3,0\n", ["--length-unit", "ft"], "--length-unit must be one of"),
        ("t,x,y,z,q1\n0,1,2,3,0\n1e300,1,2,3,1\n", ["--time", "t"], "check --time-unit"),
        ("", [], "holds no rows"),
    ],
)
def test_bad_sources_are_one_line_naming_the_line(
    tmp_path: Path, text: str, args: list[str], message: str
) -> None:
    src = tmp_path / "bad.csv"
    src.write_text(text)
    result = runner.invoke(app, ["import", str(src), *args])
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "bad.mcap").exists()


def test_the_readme_walkthrough_from_the_bundled_csv(tmp_path: Path) -> None:
    """docs/own-data.md: sample_logs/kr5_stops.csv (a KR5 off its nominal, 8 stops per
    joint, one tracker point per stop) imported, processed with --nominal kr5, exported as a
    URDF: the result's FK within 4σ of the truth beside the CSV at 200 joint vectors."""
    from dhlog.io.dhfile import dh_model_from, load_dh

    samples = Path(__file__).parents[1] / "sample_logs"
    imported(str(samples / "kr5_stops.csv"), "-o", str(tmp_path / "run.mcap"))
    done = runner.invoke(
        app,
        [
            "process",
            str(tmp_path / "run.mcap"),
            "--out",
            str(tmp_path / "results"),
            "--nominal",
            "kr5",
            "--no-rrd",
        ],
    )
    assert done.exit_code == 0, done.output
    made = runner.invoke(
        app,
        [
            "export",
            str(tmp_path / "results" / "run.dh.json"),
            "--format",
            "urdf",
            "-o",
            str(tmp_path / "robot.urdf"),
            "--limits-from",
            "kr5",
        ],
    )
    assert made.exit_code == 0, made.output
    truth = load_dh(samples / "kr5_stops.truth.json")
    result = process_log(tmp_path / "run.mcap", ProcessOptions(nominal=dh_model_from("kr5")))
    rob = load_robot("kr5")
    Q = np.random.default_rng(2).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    ex = result.extraction
    assert ex is not None and result.complete
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(truth.table, Q, truth.tool_point, T_base=truth.T_base)
    err = np.linalg.norm(got - want, axis=1)
    assert np.all(err <= 4.0 * fk_prediction_std(result, Q)), (
        err / fk_prediction_std(result, Q)
    ).max()
