"""``dhlog plan`` (issue 19, part 1): what a protocol will give, before the session."""

from __future__ import annotations

import math

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli import app
from dhlog.errors import InputError
from dhlog.plan import plan_session
from dhlog.robots import load_robot
from dhlog.simulate import SimulationConfig

runner = CliRunner()


def test_a_plan_predicts_sigma_that_shrinks_with_more_poses() -> None:
    """40 random poses (σ 10 µm): every free parameter has a σ, the FK σ over the workspace is
    a few µm; 160 poses give about half of it (σ ∝ 1/√N: 0.5, allowed 0.4–0.65)."""
    robot = load_robot("kr5")
    few = plan_session(robot, SimulationConfig(protocol="random-poses", poses=40, noise=1e-5))
    many = plan_session(robot, SimulationConfig(protocol="random-poses", poses=160, noise=1e-5))
    free = np.isfinite(few.rows_std)
    assert free.sum() >= 15 and np.all(few.rows_std[free] > 0)
    rms_few = math.sqrt(float(np.mean(few.fk_sd**2)))
    rms_many = math.sqrt(float(np.mean(many.fk_sd**2)))
    assert 1e-7 < rms_few < 1e-5
    assert 0.4 < rms_many / rms_few < 0.65, rms_many / rms_few
    assert few.poses == 40 and any("nominal" in line for line in few.fixed)


def test_a_plan_that_never_moves_a_joint_says_so() -> None:
    cfg = SimulationConfig(motion="step", skip_joints=(4,), noise=1e-5)
    with pytest.raises(InputError, match="joint 4"):
        plan_session(load_robot("kr5"), cfg)


def test_the_plan_command() -> None:
    done = runner.invoke(app, ["plan", "kr5", "--poses", "30"])
    assert done.exit_code == 0, done.output
    assert "Predicted σ of kr5's parameters" in done.output and "Predicted FK σ" in done.output
    bad = runner.invoke(app, ["plan", "kr5", "--protocol", "dance"])
    assert bad.exit_code == 1 and "protocol" in bad.output
