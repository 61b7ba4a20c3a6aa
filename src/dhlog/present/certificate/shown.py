"""What a certificate shows of a result: its rows of parameters, held-out checks, per-joint
residuals and 3-vectors, as :func:`~dhlog.present.certificate.read.read_result` reads them
(:class:`Result`), SI units throughout; :func:`nominal_deltas` adds measured − nominal."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from dhlog.errors import DhlogError

if TYPE_CHECKING:
    from dhlog.model.dh import StandardDH
    from dhlog.present.certificate.camera import CameraShown


def mm(value: float) -> str:
    """A length (m) as the certificate writes it in its text."""
    return f"{value * 1e3:.4f} mm"


@dataclass(frozen=True)
class Parameter:
    """One shown parameter: ``name`` (``theta``, ``d``, ``beta``, ``a``, ``alpha`` or ``scale``
    for a fitted encoder scale), its value and σ in SI units (σ None where unknown or fixed),
    why it is held when it is (``fixed``), and measured − nominal (SI) when a nominal is given
    and the parameter is measured."""

    name: str
    value: float
    std: float | None
    fixed: str | None
    delta: float | None = None

    @property
    def angular(self) -> bool:
        return self.name in ("theta", "alpha", "beta")


@dataclass(frozen=True)
class ShownRow:
    """A row of the table as the result shows it: ``form`` ``dh`` (θ, d, a, α) or ``hayati``
    (θ, β, a, α: ``Rz(θ) Tx(a) Rx(α) Ry(β)``)."""

    joint: int
    name: str
    type: str
    form: str
    parameters: list[Parameter]


@dataclass(frozen=True)
class Stats:
    """Error statistics of one model at held-out poses (m)."""

    mean: float
    rms: float
    p95: float
    max: float
    n_poses: int


@dataclass(frozen=True)
class Check:
    """One held-out check of ``validation.holdout``, with its per-pose error lengths (m) from
    ``<stem>.holdout.csv`` when that file is beside the result."""

    label: str
    n_poses: int
    nominal: Stats | None
    calibrated: Stats
    notes: list[str]
    nominal_errors: list[float] | None = None
    calibrated_errors: list[float] | None = None


@dataclass(frozen=True)
class JointResidual:
    """A joint's residual summary (m): its own fit (``joints[].fit``) and the FK of the table
    at its samples (``joints[].validation``); ``error`` when it was not identified."""

    joint: int
    name: str
    fit_rms: float | None
    fit_points: int | None
    fk_rms: float | None
    fk_max: float | None
    fk_points: int | None
    error: str | None


@dataclass(frozen=True)
class Triple:
    """A shown 3-vector (tool point, frame 1's origin or rotation) in SI units with its σ
    (None: unknown or fixed) and its fixed coordinates (``x``, ``y``, ``z``) and why."""

    label: str
    values: list[float]
    stds: list[float | None]
    fixed: list[str] = field(default_factory=list)
    reason: str = ""


@dataclass(frozen=True)
class Result:
    """What the certificate shows of a result document, every field checked."""

    version: str
    log_name: str
    log_sha256: str
    pipeline: str
    method: str | None
    n_joints: int
    joint_names: list[str]
    joint_types: list[str | None]
    reference_pose: list[float]
    rows: list[ShownRow]
    checks: list[Check]
    fk_rms: float | None
    fk_max: float | None
    fk_points: int
    residuals: list[JointResidual]
    warnings: list[str]
    notes: list[str]
    measurement: list[tuple[str, str]]
    tool: list[Triple]
    nongeometric: dict[str, Any] | None
    #: a camera calibration's ``camera`` block (None: a tracker's result)
    camera: CameraShown | None = None
    #: why dhlog judges the result implausible (``plausible: false``); empty: plausible
    implausible: list[str] = field(default_factory=list)


def nominal_deltas(
    rows: list[ShownRow], nominal: StandardDH, reference_pose: Sequence[float]
) -> list[ShownRow]:
    """``rows`` with measured − nominal on every measured parameter (SI, angles wrapped); the
    nominal is put in the rows' form first (its rows of nearly parallel pairs in the
    Hayati–Mirmirani form, as ``dhlog process`` does); rows whose nominal has no such form get
    none."""
    from dhlog.geometry._checks import wrap_angle
    from dhlog.identify.read.hayati import table_in_hayati_form

    hayati = frozenset(r.joint - 1 for r in rows if r.form == "hayati")
    table = nominal
    skip: set[int] = set()
    if hayati:
        try:
            table = table_in_hayati_form(
                nominal, np.asarray(reference_pose, dtype=np.float64), hayati
            )
        except DhlogError:
            table = nominal
            skip = set(hayati) | {i + 1 for i in hayati}
    flags = getattr(table, "hayati", (False,) * table.n)
    beta = getattr(table, "beta", np.zeros(table.n))
    out = []
    for i, row in enumerate(rows):
        if row.type != table.joint_types[i].value or (row.form == "hayati") != bool(flags[i]):
            skip.add(i)
        nom = {
            "theta": float(table.theta_offset[i]),
            "d": float(table.d_offset[i]),
            "beta": float(beta[i]),
            "a": float(table.a[i]),
            "alpha": float(table.alpha[i]),
        }
        params = []
        for p in row.parameters:
            delta = None
            if p.fixed is None and p.name in nom and i not in skip:
                delta = p.value - nom[p.name]
                if p.angular:
                    delta = wrap_angle(delta)
            params.append(Parameter(p.name, p.value, p.std, p.fixed, delta))
        out.append(ShownRow(row.joint, row.name, row.type, row.form, params))
    return out
