"""A run's model is read off the one result (``result.model.model_of``), not written to JSON and
parsed back: it must equal, field for field and bit for bit, what ``dhlog.load`` reads from the
JSON the run writes (``parse_dh(result_document(result))``) — a whole-model fit with a nominal,
terms beyond the geometry, a parked joint, a free fit without nominal — and a partial result
keeps what was identified."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import Identification, ProcessOptions, process_data, process_log
from dhlog.io.dhfile import DHModel, dh_model_from, load_dh, parse_dh
from dhlog.io.memory import log_data_from_session
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.result.model import model_of
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

SAMPLES = Path(__file__).parents[1] / "sample_logs"


def _parked_run() -> Identification:
    robot = load_robot("kr5")
    cfg = SimulationConfig(
        seed=3,
        noise=1e-5,
        perturb_length=5e-4,
        perturb_angle=math.radians(0.05),
        base_points=0,
        protocol="random-poses",
        poses=60,
        parked=((1, 0.3),),  # joint 1 (1-based)
    )
    session = simulate_session(robot, cfg)
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
    return process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))


def _library(name: str) -> DHModel:
    return dh_model_from(name)


def _kr5_truth() -> DHModel:
    return load_dh(SAMPLES / "kr5_0.1mm.truth.json")


RUNS = {
    "nominal": lambda: process_log(
        SAMPLES / "kr5_0.1mm.mcap", ProcessOptions(nominal=_kr5_truth())
    ),
    "free": lambda: process_log(SAMPLES / "scara.mcap"),
    "parked": _parked_run,
}


def _same(got: DHModel, want: DHModel) -> None:
    assert got.table.joint_types == want.table.joint_types
    for name in ("theta_offset", "d_offset", "a", "alpha"):
        np.testing.assert_array_equal(getattr(got.table, name), getattr(want.table, name))
    np.testing.assert_array_equal(got.T_base, want.T_base)
    np.testing.assert_array_equal(got.tool_point, want.tool_point)
    assert got.joint_names == want.joint_names and got.source == want.source
    assert got.parked == want.parked
    assert (got.limits is None) == (want.limits is None)
    assert (got.terms is None) == (want.terms is None)
    if got.terms is not None and want.terms is not None:
        assert got.terms.names() == want.terms.names()
        np.testing.assert_array_equal(got.terms.coefficients, want.terms.coefficients)
        # the JSON's reader normalises the unit gravity vector again: an ulp apart
        np.testing.assert_allclose(got.terms.gravity, want.terms.gravity, rtol=0, atol=1e-15)


@pytest.mark.parametrize("kind", sorted(RUNS))
def test_the_model_is_the_one_the_json_gives(kind: str) -> None:
    result = RUNS[kind]()
    assert result.complete
    model = model_of(result)
    assert model is not None
    _same(model, parse_dh(result_document(result), str(result.path)))
    if kind == "parked":
        assert model.parked == (0,)


def test_terms_beyond_the_geometry_are_the_json_s() -> None:
    """kr5_real with --model compliance: the terms in the table's frames, as the JSON's."""
    result = process_log(
        SAMPLES / "kr5_real.mcap",
        ProcessOptions(nominal=_library("kr5"), model=ModelRequest("compliance")),
    )
    model = model_of(result)
    assert model is not None and model.terms is not None and model.terms.size
    _same(model, parse_dh(result_document(result), str(result.path)))


def test_a_partial_result_keeps_the_identified_rows() -> None:
    """A session in which one joint never moved alone and there is no nominal: the model has
    the table as far as identified and no tool point; the JSON has no complete table."""
    result = process_log(SAMPLES / "kr5_0.1mm.mcap")
    joints = (*result.joints[:-1], dataclasses.replace(result.joints[-1], reason="x"))
    partial = dataclasses.replace(
        result, session=dataclasses.replace(result.session, joints=joints)
    )
    model = model_of(partial)
    assert model is not None and not partial.complete
    np.testing.assert_array_equal(model.tool_point, np.zeros(3))
    assert model.table.n == result.joints.__len__()
