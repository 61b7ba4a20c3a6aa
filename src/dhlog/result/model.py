"""A run's model as forward kinematics reads it (:func:`model_of`): the one result's table, base,
tool, names, terms and parked joints, taken from the result itself — what ``dhlog.load`` reads
back from the written JSON, without writing and parsing it."""

from __future__ import annotations

import numpy as np

from dhlog.identify.stages import Identification
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import StandardDH


def model_of(result: Identification) -> DHModel | None:
    """The model of ``result``: its standard table (offsets at encoder zero), frame 1 in M, the
    tool point, the joints' names, the terms beyond the geometry in the table's frames and the
    joints held at the nominal because they never moved. None when no joint was identified; a
    partial result's model has its identified rows and the tool point at the last frame's
    origin (the result names the joints that failed)."""
    ex = result.extraction
    if ex is None:
        return None
    s = ex.standard
    table = StandardDH(s.joint_types, s.theta_offset, s.d_offset, s.a, s.alpha)
    names = tuple(j.name for j in result.joints)
    if not result.complete:
        return DHModel(table, ex.T_measurement_base, np.zeros(3), names, str(result.path))
    terms = result.terms if result.selection is not None else None
    parked = tuple(result.parked) if result.nominal is not None else ()
    return DHModel(
        table=table,
        T_base=np.array(ex.T_measurement_base, dtype=np.float64),
        tool_point=np.array(ex.tool_point, dtype=np.float64),
        joint_names=names,
        source=str(result.path),
        terms=terms if terms is not None and terms.size else None,
        parked=parked,
    )
