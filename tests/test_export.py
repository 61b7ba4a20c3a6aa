"""Exports checked by real consumers: the URDF through yourdfpy's loader and its forward
kinematics against dhlog's at random joint vectors (to 1e-9 m)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from typer.testing import CliRunner

from dhlog.cli import app
from dhlog.dhfile import load_dh
from dhlog.kinematics import fk_point
from dhlog.robots import load_robot

SAMPLES = Path(__file__).parents[1] / "sample_logs"
runner = CliRunner()


@pytest.mark.parametrize(
    ("log", "robot"),
    [("kr5_0.01mm", "kr5"), ("kr5_real", "kr5"), ("scara", "scara")],
    ids=["parallel pair held", "Hayati row", "prismatic joint"],
)
def test_the_urdf_reproduces_the_result_exactly(log: str, robot: str, tmp_path: Path) -> None:
    """``dhlog process`` then ``dhlog export --format urdf``: yourdfpy loads the URDF, and the
    target's position (``tool0`` in ``measurement``) equals the result's FK to 1e-9 m at 200
    random joint vectors within the robot's limits; the joint limits are the robot's."""
    out = tmp_path / "out"
    done = runner.invoke(
        app, ["process", str(SAMPLES / f"{log}.mcap"), "--no-rrd", "--out", str(out)]
    )
    assert done.exit_code == 0, done.output
    result = out / f"{log}.dh.json"
    urdf = tmp_path / "robot.urdf"
    made = runner.invoke(
        app, ["export", str(result), "-o", str(urdf), "--format", "urdf", "--limits-from", robot]
    )
    assert made.exit_code == 0, made.output
    model = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True)
    names = [j["name"] for j in json.loads(result.read_text())["joints"]]
    assert list(model.actuated_joint_names) == names
    rob = load_robot(robot)
    for k, name in enumerate(names):
        limit = model.joint_map[name].limit
        assert (limit.lower, limit.upper) == pytest.approx(tuple(rob.limits[k]))
    dh = load_dh(result)
    Q = np.random.default_rng(0).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, rob.n))
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        model.update_cfg(q)
        T = model.get_transform("tool0", "measurement")
        assert np.abs(T[:3, 3] - p).max() < 1e-9


def test_a_result_with_encoder_scales_is_not_exported(tmp_path: Path) -> None:
    """An encoder scale has no place in a URDF: one line, exit 2."""
    data = json.loads((SAMPLES / "kr5_0.01mm.truth.json").read_text())
    data["standard_dh"][1]["encoder_scale"] = 1.001
    path = tmp_path / "scaled.dh.json"
    path.write_text(json.dumps(data))
    made = runner.invoke(app, ["export", str(path), "-o", str(tmp_path / "x.urdf")])
    assert made.exit_code == 2 and "encoder scales" in made.output


def test_compare_finds_the_changed_parameter_and_nothing_else(tmp_path: Path) -> None:
    """Two sessions of one robot (a KR5 off its nominal, its truth as a DH file) differ by
    noise only: no parameter beyond 4 combined σ, FK within 50 µm RMS. A third session of the
    same robot with a2 0.5 mm longer: a2 changed by 0.5 mm far beyond its σ, the FK difference
    of that size."""
    base = tmp_path / "robot.mcap"
    assert (
        runner.invoke(
            app,
            ["simulate", "kr5", "-o", str(base), "--perturb-mm", "0.3", "--perturb-deg", "0.02"],
        ).exit_code
        == 0
    )
    robot = tmp_path / "robot.truth.json"
    longer = json.loads(robot.read_text())
    longer["standard_dh"][1]["a"] += 5e-4
    changed = tmp_path / "longer.json"
    changed.write_text(json.dumps(longer))
    results = []
    for k, source in enumerate((robot, robot, changed)):
        log = tmp_path / f"s{k}.mcap"
        made = runner.invoke(app, ["simulate", str(source), "-o", str(log), "--seed", str(k + 1)])
        assert made.exit_code == 0, made.output
        done = runner.invoke(app, ["process", str(log), "--no-rrd", "--out", str(tmp_path)])
        assert done.exit_code == 0, done.output
        results.append(tmp_path / f"s{k}.dh.json")
    from dhlog.compare import compare

    same = compare(results[0], results[1])
    z = [c.significance for c in same.changes if c.significance is not None]
    assert max(z) < 4.0 and same.fk_rms < 50e-6
    moved = compare(results[0], results[2])
    a2 = next(c for c in moved.changes if c.name == "a_2")
    assert a2.diff == pytest.approx(5e-4, abs=4 * (a2.sigma or 0)) and (a2.significance or 0) > 10
    others = [c for c in moved.changes if c.name != "a_2" and c.significance is not None]
    assert 2e-4 < moved.fk_rms < 1e-3 and moved.fk_max < 1.5e-3
    shown = runner.invoke(app, ["compare", str(results[0]), str(results[2])])
    assert shown.exit_code == 0 and "a_2" in shown.output and "changed beyond 3σ" in shown.output
    assert len(others) > 10 and max(c.significance or 0 for c in others) < 4.0
