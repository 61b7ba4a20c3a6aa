"""The result contract (``dhlog.result/1``): the JSON document, the CSV and the display rows."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog._version import __version__
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.identify.check.validate import shown_stride
from dhlog.identify.joints.sweeps import JointReport
from dhlog.identify.model.parked import PARKED_REASON
from dhlog.identify.read.hayati import NEAR_PARALLEL
from dhlog.identify.read.propagate import state_difference, state_names, state_vector
from dhlog.identify.run import Identification
from dhlog.model.dh import JointType
from dhlog.result.contract import RESULT_FORMAT, dh_documents, relation_documents


def _fit_doc(j: JointReport, t_ns: NDArray[np.int64]) -> dict[str, Any] | None:
    f = j.fit
    if f is None:
        return None
    return {
        "method": f.method,
        "n_points": int(j.rows.size),
        **({"start_fit_points": int(f.n_points)} if f.n_points != j.rows.size else {}),
        "n_outliers": j.n_outliers,
        "rms": float(f.rms),
        "sweep": float(f.sweep),
        "radius": float(f.radius),
        "sigma": float(f.sigma),
        "segments": j.segments,
        "outliers_t_ns": [int(t) for t in t_ns[j.rows[~j.inliers]]],
        "axis_std": {"direction": f.direction_std, "position": f.position_std},
        **({"encoder_scale": f.encoder_scale} if f.encoder_scale is not None else {}),
    }


def result_document(result: Identification) -> dict[str, Any]:
    """The ``<stem>.dh.json`` document (the result contract, ``dhlog.result/1``)."""
    ex = result.extraction
    n_rows = 0 if ex is None else (ex.standard.n if result.complete else ex.standard.n - 1)
    std = result.std
    rows: list[dict[str, Any]] = []
    mod_rows: list[dict[str, Any]] = []
    relations: list[dict[str, Any]] = []
    if ex is not None:
        rows, mod_rows = dh_documents(ex.standard, ex.reference_pose, std, n_rows)
        relations = relation_documents(ex.relations)
    val = result.validation
    per_joint = {} if val is None else val.per_joint
    t_ns = result.segmentation.t_ns
    held = set(result.parked) if result.nominal is not None else set()  # parked joints held
    doc: dict[str, Any] = {
        "format": RESULT_FORMAT,
        "dhlog_version": __version__,
        "source": {
            "path": Path(result.path).name,
            "sha256": result.sha256,
            "pipeline": result.log.pipeline.name,
        },
        "units": {"length": "m", "angle": "rad"},
        "reference_pose": [float(v) for v in result.reference_pose],
        "joints": [
            {
                "index": j.index,
                "name": j.name,
                "type": j.type.value if j.type else None,
                "axis": None
                if j.axis is None
                else {"point": j.axis.point.tolist(), "direction": j.axis.direction.tolist()},
                "fit": _fit_doc(j, t_ns),
                **(
                    {
                        "validation": {
                            "fk_rms": per_joint[j.index][0],
                            "fk_max": per_joint[j.index][1],
                            "n_points": per_joint[j.index][2],
                        }
                    }
                    if j.index in per_joint
                    else {}
                ),
                **({"error": j.reason} if j.reason else {}),
                **({"parked": PARKED_REASON} if j.index - 1 in held else {}),
            }
            for j in result.joints
        ],
        "standard_dh": rows,
        "modified_dh": mod_rows,
        "relations": relations,
        "base": {"T_measurement_base": None if ex is None else ex.T_measurement_base.tolist()},
        "tool": {"point": None if (ex is None or not result.complete) else ex.tool_point.tolist()},
        "validation": {
            "fk_rms": None if val is None else val.rms,
            "fk_max": None if val is None else val.max,
            "n_points": 0 if val is None else val.n_points,
            **({"holdout": [h.document() for h in result.holdout]} if result.holdout else {}),
            **(
                {"not_scored": [u.document() for u in result.not_scored]}
                if result.not_scored
                else {}
            ),
        },
        "warnings": list(result.warnings),
        "notes": list(result.info),
        # what makes dhlog judge the result implausible (dhlog process exits 4); empty: none
        "plausible": not result.implausible,
        "implausible": list(result.implausible),
    }
    if result.selection is not None:
        doc["nongeometric"] = nongeometric_document(result)
    if result.camera is not None:  # a camera calibration: the hand-eye product
        doc["camera"] = result.camera.document()
        if len(result.camera_results) > 1:  # several cameras: each one's block, the first's too
            doc["cameras"] = [c.document() for c in result.camera_results]
    if ex is not None and result.complete:
        doc["modified_dh_tool"] = {"T_n_tool": ex.T_modified_tool.tolist()}
        if std is not None:
            n = ex.standard.n
            doc["tool"]["std"] = [_num_or_none(v) for v in std[4 * n : 4 * n + 3]]
            doc["base"]["std"] = {
                "translation": [_num_or_none(v) for v in std[4 * n + 3 : 4 * n + 6]],
                "rotation": [_num_or_none(v) for v in std[4 * n + 6 : 4 * n + 9]],
            }
        _mark_fixed(doc, result)
        _encoder_scales(doc, result)
        if result.tool_orientation is not None and result.tool_orientation_std is not None:
            doc["tool"]["orientation"] = {
                "matrix": result.tool_orientation.tolist(),
                "std": [float(v) for v in result.tool_orientation_std],
                "description": "the target frame in the last frame; std: rotation vector (rad)",
            }
        if len(result.extra_tool_points):
            topics = result.log.pipeline.streams["point"].extra_topics
            doc["tool"]["further_targets"] = [
                {
                    "target": k + 2,
                    "topic": topics[k] if k < len(topics) else None,
                    "point": [float(v) for v in p],
                    "std": [float(v) for v in sd],
                }
                for k, (p, sd) in enumerate(
                    zip(result.extra_tool_points, result.extra_tool_std, strict=True)
                )
            ]
        doc["method"] = result.method
        if result.covariance is not None:
            doc["covariance"] = _covariance_document(result)
        if result.analytic is not None and result.std is not None:
            doc["analytic"] = _analytic_document(result)
        doc["noise"] = _noise_document(result)
        if result.whole is not None:
            doc["whole_fit"] = _whole_fit_document(result)
    if result.hayati:
        q = result.reference_pose
        doc["hayati"] = []
        for k, h in enumerate(result.hayati):
            i = h.joints[0] - 1
            offset = h.theta - (float(q[i]) if result.joints[i].type is JointType.REVOLUTE else 0.0)
            if result.nominal is not None:  # within π of the nominal's, as the table
                near = float(result.nominal.table.theta_offset[i])
                offset = near + wrap_angle(offset - near)
            row: dict[str, Any] = {
                "joints": list(h.joints),
                "theta": h.theta,
                "theta_offset": offset,
                "a": h.a,
                "alpha": h.alpha,
                "beta": h.beta,
            }
            if k < len(result.hayati_std):
                sd = result.hayati_std[k]
                row["std"] = dict(zip(("theta", "a", "alpha", "beta"), map(float, sd), strict=True))
            doc["hayati"].append(row)
    if result.conditioned is not None and ex is not None:
        doc["hayati_dh"] = _conditioned_document(result, n_rows)
    if ex is not None:
        doc["base"]["frame_1_origin"] = frame_1_origin(result)
    if result.timing is not None:
        doc["timing"] = result.timing.document()
    if result.base is not None:
        doc["base"]["plane"] = {
            "point": result.base.plane.point.tolist(),
            "normal": result.base.plane.normal.tolist(),
            "rms": result.base.rms,
            "n_points": int(result.base.residuals.size),
        }
    height = result.segmentation.height
    every = shown_stride(height)
    doc["segmentation"] = {
        "segments": result.segmentation.segments.height,
        "set_aside": dict(result.segmentation.set_aside),
        "samples": height,
        # the recording draws every `recording_every`-th sample: the viewer shows no more
        "recording_samples": -(-height // every),
        "recording_every": every,
    }
    return doc


HAYATI_DESCRIPTION = (
    "standard_dh with the rows of nearly parallel pairs in the Hayati-Mirmirani form, same "
    "forward kinematics: row i is Rz(theta) Tz(d) Tx(a) Rx(alpha) (form dh) or "
    "Rz(theta) Tx(a) Rx(alpha) Ry(beta) (form hayati: beta in place of the ill-conditioned d)"
)


def _conditioned_document(result: Identification, n_rows: int) -> dict[str, Any]:
    """``hayati_dh``: the table of :class:`~dhlog.identify.read.conditioning.Conditioned`, row
    by row."""
    c = result.conditioned
    assert c is not None
    t = c.table
    hayati = getattr(t, "hayati", (False,) * t.n)
    beta = getattr(t, "beta", np.zeros(t.n))
    scales = None
    if result.whole is not None and result.whole.layout.scale_at is not None:
        scales = result.whole.model.scales
    out = []
    for i in range(n_rows):
        second = "beta" if hayati[i] else "d_offset"
        names = ("theta_offset", second, "a", "alpha")
        values = [t.theta_offset[i], beta[i] if hayati[i] else t.d_offset[i], t.a[i], t.alpha[i]]
        if scales is not None:  # offsets at encoder zero under the fitted encoder scale
            k = 0 if t.joint_types[i] is JointType.REVOLUTE else 1
            values[k] += float((1.0 - scales[i]) * result.reference_pose[i])
        row: dict[str, Any] = {
            "form": "hayati" if hayati[i] else "dh",
            "type": t.joint_types[i].value,
            **{name: float(v) for name, v in zip(names, values, strict=True)},
            "std": {
                name.removesuffix("_offset"): _num_or_none(float(c.std[4 * i + p]))
                for p, name in enumerate(names)
            },
        }
        held = [p for p in range(4) if 4 * i + p in c.fixed]
        if held:
            row["fixed"] = [names[p].removesuffix("_offset") for p in held]
            row["fixed_reason"] = "; ".join(
                dict.fromkeys(
                    f"{names[p].removesuffix('_offset')}: {c.fixed[4 * i + p]}" for p in held
                )
            )
        out.append(row)
    return {"description": HAYATI_DESCRIPTION, "rows": out}


def frame_1_origin(result: Identification) -> str:
    """How frame 1's origin (on axis 1) was placed: by the base plane when the log has base
    points, else by a convention, which the sentence names."""
    if result.base is not None:
        n = int(result.base.residuals.size)
        return f"axis 1 ∩ the base plane fitted to {n} probed points"
    ex = result.extraction
    parallel = False
    if ex is not None and ex.relations:
        rel = ex.relations[0].relation
        parallel = min(rel.angle, math.pi - rel.angle) < NEAR_PARALLEL
    if result.nominal is not None and not parallel:
        where = "the nominal's d₁ from the foot of the common normal to axis 2"
    elif parallel:
        where = "the point of axis 1 nearest the measurement origin (axes 1 and 2 parallel)"
    else:
        where = "foot of the common normal to axis 2"
    return f"{where} — no base points in the log, so d₁ is a convention"


def _num_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _encoder_scales(doc: dict[str, Any], result: Identification) -> None:
    """With fitted encoder scales, each row's ``encoder_scale`` (and σ) and its offset at
    encoder zero such that ``θ_i = θ_offset_i + encoder_scale_i · q_i`` (prismatic: ``d``)."""
    w = result.whole
    if w is None or w.layout.scale_at is None:
        return
    ref, scales = w.model.reference_pose, w.model.scales
    k = w.layout.scale_at
    for i, row in enumerate(doc["standard_dh"]):
        shift = float((1.0 - scales[i]) * ref[i])
        key = "theta_offset" if row["type"] == "revolute" else "d_offset"
        row[key] += shift
        row["encoder_scale"] = float(scales[i])
        row["encoder_scale_std"] = float(math.sqrt(max(w.covariance[k + i, k + i], 0.0)))


def _mark_fixed(doc: dict[str, Any], result: Identification) -> None:
    """``fixed`` / ``fixed_reason`` on each DH row, on the tool and on the base."""
    names = ("theta", "d", "a", "alpha")
    n = len(doc["standard_dh"])
    for i, row in enumerate(doc["standard_dh"]):
        held = [(names[p], result.fixed[4 * i + p]) for p in range(4) if 4 * i + p in result.fixed]
        if held:
            row["fixed"] = [name for name, _ in held]
            row["fixed_reason"] = "; ".join(dict.fromkeys(f"{name}: {why}" for name, why in held))
    tool = [("xyz"[p], result.fixed[4 * n + p]) for p in range(3) if 4 * n + p in result.fixed]
    if tool:
        doc["tool"]["fixed"] = [c for c, _ in tool]
        doc["tool"]["fixed_reason"] = tool[0][1]


def _covariance_document(result: Identification) -> dict[str, Any]:
    """The covariance of every free parameter (names as :func:`state_names`, SI units)."""
    cov = result.covariance
    assert cov is not None
    n = len(result.joints)
    free = [k for k in range(4 * n + 9) if k not in result.fixed]
    names = state_names(n)
    return {
        "parameters": [names[k] for k in free],
        "matrix": [[float(cov[a, b]) for b in free] for a in free],
    }


def _analytic_document(result: Identification) -> dict[str, Any]:
    """The seed method's table (the start of the whole-model fit) and its distance from the
    result in the result's σ."""
    an, ex, std = result.analytic, result.extraction, result.std
    assert an is not None and ex is not None and std is not None
    rows, _ = dh_documents(an.standard, an.reference_pose)
    for row in rows:
        del row["std"]
    R0 = ex.T_measurement_base[:3, :3]
    n = ex.standard.n
    diff = state_difference(state_vector(an, R0), state_vector(ex, R0), n)
    ratio = np.where(np.isfinite(std) & (std > 0), np.abs(diff) / np.where(std > 0, std, 1), 0)
    worst = int(np.argmax(ratio))
    return {
        "standard_dh": rows,
        "max_deviation_sigma": float(ratio[worst]),
        "max_deviation_parameter": state_names(n)[worst],
    }


def _noise_document(result: Identification) -> dict[str, Any]:
    doc: dict[str, Any] = {"model": result.noise.model, **result.noise.document()}
    if result.whole is not None:
        doc["chi2_dof"] = result.whole.chi2_dof
        if result.noise.model == "isotropic":
            doc["sigma"] = result.sigma
            doc["sigma_source"] = "estimated from the residuals"
        elif result.noise.model == "per-sample":
            doc["source"] = "the position covariance each sample carries in the log"
    else:
        fits = [j.fit.sigma for j in result.joints if j.fit is not None]
        doc["sigma"] = float(math.sqrt(np.mean(np.square(fits)))) if fits else None
        doc["sigma_source"] = "the per-joint fits' residuals"
    return doc


def _whole_fit_document(result: Identification) -> dict[str, Any]:
    w = result.whole
    assert w is not None
    doc: dict[str, Any] = {
        "n_points": w.n_points,
        "n_outliers": int(np.count_nonzero(~w.inliers)),
        "outliers": list(result.outlier_names),
        "iterations": w.iterations,
        "rms": None if result.validation is None else result.validation.rms,
    }
    if w.sigma_rotation is not None:
        doc["sigma_rotation"] = w.sigma_rotation
    if w.determined is not None:
        doc["identifiability"] = w.determined.document(w.layout.names)
    if w.layout.scale_at is not None:
        k = w.layout.scale_at
        n = w.model.n
        doc["encoder_scales"] = {
            "value": [float(v) for v in w.model.scales],
            "std": [float(math.sqrt(max(w.covariance[k + i, k + i], 0.0))) for i in range(n)],
        }
    return doc


def display_scales(units: str) -> tuple[float, float, str, str]:
    """Factors and unit names for display: ``mm`` → (1e3, 180/π, "mm", "deg"), ``m`` → SI."""
    if units == "m":
        return 1.0, 1.0, "m", "rad"
    return 1e3, 180.0 / math.pi, "mm", "deg"


@dataclass(frozen=True)
class DisplayRow:
    """A table row as shown: joint type, form (``dh`` or ``hayati``), ``θ_offset``, ``d_offset``
    (``β`` on a Hayati row), ``a``, ``α`` in display units (``display_scales``), their σ (None
    when fixed or unknown) and which of the four are held fixed."""

    type: str
    form: str
    values: list[float]
    stds: list[float | None]
    held: list[bool]


def display_rows(result: Identification, units: str = "mm") -> list[DisplayRow]:
    """The rows to show: the standard DH table, or, when nearly parallel pairs make a DH ``d``
    ill-conditioned, the same table with those rows in the Hayati–Mirmirani form."""
    length, angle, _, _ = display_scales(units)
    doc = result_document(result)
    if "hayati_dh" in doc:
        rows = doc["hayati_dh"]["rows"]
    else:
        rows = [dict(r, form="dh") for r in doc["standard_dh"]]
    out = []
    for row in rows:
        hayati = row["form"] == "hayati"
        second = "beta" if hayati else "d"
        factors = [angle, angle if hayati else length, length, angle]
        s = row["std"]
        values = [row["theta_offset"], row["beta" if hayati else "d_offset"], row["a"]]
        values.append(row["alpha"])
        stds = [s["theta"], s[second], s["a"], s["alpha"]]
        held = row.get("fixed", [])
        out.append(
            DisplayRow(
                row["type"],
                row["form"],
                [v * f for v, f in zip(values, factors, strict=True)],
                [None if v is None else v * f for v, f in zip(stds, factors, strict=True)],
                [name in held for name in ("theta", second, "a", "alpha")],
            )
        )
    return out


def result_csv(result: Identification, *, units: str = "mm") -> str:
    """The DH table as CSV, in mm and degrees (or m and rad), with ±1σ columns; a parameter
    held by a convention has ``fixed`` in its σ column. The last three columns give each row's
    form: ``dh``, or ``hayati`` for a row of a nearly parallel pair, whose ``d`` is then empty
    and whose ``β`` (``Rz(θ) Tx(a) Rx(α) Ry(β)``) stands in its place."""
    _, _, lu, au = display_scales(units)
    lines = [
        f"joint,name,type,theta_offset_{au},d_{lu},a_{lu},alpha_{au},"
        f"std_theta_{au},std_d_{lu},std_a_{lu},std_alpha_{au},form,beta_{au},std_beta_{au}"
    ]
    for i, row in enumerate(display_rows(result, units)):
        hayati = row.form == "hayati"

        def sd(k: int, row: DisplayRow = row) -> str:
            v = row.stds[k]
            return "fixed" if row.held[k] else ("" if v is None else f"{v:.3g}")

        values = [f"{v:.9g}" for v in row.values]
        stds = [sd(k) for k in range(4)]
        beta, std_beta = (values[1], stds[1]) if hayati else ("", "")
        if hayati:
            values[1], stds[1] = "", ""
        cells = [str(i + 1), _csv_cell(result.joints[i].name), row.type, *values, *stds]
        cells += [row.form, beta, std_beta]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def nongeometric_document(result: Identification) -> dict[str, Any]:
    """The ``nongeometric`` block: the model asked and chosen with every candidate tried (BIC,
    held-out RMS), and the chosen terms in the table's frames with σ, as the forward kinematics
    applies them (``Δq`` added to the table's joint values)."""
    assert result.selection is not None
    doc: dict[str, Any] = {
        "selection": result.selection.document(),
        "description": (
            "joint-value terms: q_table += Σ value · b(q); compliance b = z_i · ((p − o_i) × g) "
            "(m: the lever arm about joint i's axis, frame i−1's z through its origin, of a unit "
            "mass at the lump p under gravity g, taken at the undeflected pose); harmonic_sin/cos "
            "b = sin/cos of the encoder value; lump points in the frame whose z is that axis "
            "(standard DH frames of fk_frames), the target's in the last frame; gravity in the "
            "base frame"
        ),
        "gravity": None,
        "lumps": [],
        "terms": [],
    }
    if result.terms is not None:
        doc.update(result.terms.document(result.terms_std))
        for t in doc["terms"]:
            t["std"] = _num_or_none(t["std"])
        doc["max_deflection"] = [float(v) for v in result.deflection_max]
        doc["max_target_displacement"] = result.deflection_target
        doc["max_deflection_std"] = [_num_or_none(float(v)) for v in result.deflection_max_std]
        doc["max_target_displacement_std"] = _num_or_none(result.deflection_target_std)
    return doc


def terms_csv(result: Identification) -> str:
    """The chosen terms beyond the geometry, one a row (SI: rad/m or rad), with σ; only the
    header when the geometric model was chosen."""
    lines = ["name,kind,joint,lump,value,std,unit"]
    terms = result.terms
    if terms is not None:
        doc = terms.document(result.terms_std)
        for t in doc["terms"]:
            lump = doc["lumps"][t["lump"]]["on"] if "lump" in t else ""
            sd = "" if t["std"] is None or not math.isfinite(t["std"]) else f"{t['std']:.9g}"
            lines.append(
                f"{t['name']},{t['kind']},{t['joint']},{_csv_cell(lump)},{t['value']:.9g},{sd},"
                f"{t['unit']}"
            )
    return "\n".join(lines) + "\n"


def holdout_csv(result: Identification, *, units: str = "mm") -> str:
    """Every held-out pose as CSV: the check (``cross-validation`` or the log's name), the
    pose's measured position in M, the error vector (measured − predicted) and its length for
    the nominal (empty without one) and the calibrated model; ``point_id`` last, the export's
    id of the pose's point where the log carries ids (``dhlog import``), else empty."""
    _, _, lu, _ = display_scales(units)
    f = 1e3 if units == "mm" else 1.0
    axes = ("x", "y", "z")
    lines = [
        ",".join(
            ["check", "pose", *(f"{a}_{lu}" for a in axes)]
            + [f"nominal_d{a}_{lu}" for a in axes]
            + [f"nominal_error_{lu}"]
            + [f"calibrated_d{a}_{lu}" for a in axes]
            + [f"calibrated_error_{lu}", "point_id"]
        )
    ]
    for h in result.holdout:
        check = "cross-validation" if h.kind == "cross-validation" else Path(h.path or "").name
        for k, pos in enumerate(h.positions):
            nom = (
                ["", "", "", ""]
                if h.nominal_vectors is None
                else [f"{v * f:.9g}" for v in h.nominal_vectors[k]]
                + [f"{np.linalg.norm(h.nominal_vectors[k]) * f:.9g}"]
            )
            cal = [f"{v * f:.9g}" for v in h.calibrated_vectors[k]]
            cal.append(f"{np.linalg.norm(h.calibrated_vectors[k]) * f:.9g}")
            named = "" if h.pose_names is None else _csv_cell(h.pose_names[k])
            cells = [_csv_cell(check), str(k + 1), *(f"{v * f:.9g}" for v in pos), *nom, *cal]
            cells.append(named)
            lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _csv_cell(text: str) -> str:
    if any(c in text for c in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


def nominal_difference(result: Identification, *, shown: bool = False) -> FloatArray | None:
    """measured − nominal per row (n, 4) in SI units, angles wrapped; None without nominal.
    ``shown``: in the form :func:`display_rows` shows (β in place of d on Hayati rows; NaN on
    the rows whose nominal has no such form)."""
    if result.nominal is None or result.extraction is None:
        return None
    t, nom = result.extraction.standard, result.nominal.table
    c = result.conditioned
    if shown and c is not None:
        if c.nominal is None:
            plain = nominal_difference(result)
            assert plain is not None
            affected = {i for i, h in enumerate(getattr(c.table, "hayati", ())) if h}
            for i in affected | {i + 1 for i in affected}:
                if i < plain.shape[0]:
                    plain[i] = np.nan
            return plain
        t, nom = c.table, c.nominal
        hay = getattr(t, "hayati", (False,) * t.n)
        bt, bn = getattr(t, "beta", np.zeros(t.n)), getattr(nom, "beta", np.zeros(t.n))
        n = t.n if result.complete else t.n - 1
        return np.array(
            [
                [
                    wrap_angle(t.theta_offset[i] - nom.theta_offset[i]),
                    wrap_angle(bt[i] - bn[i]) if hay[i] else t.d_offset[i] - nom.d_offset[i],
                    t.a[i] - nom.a[i],
                    wrap_angle(t.alpha[i] - nom.alpha[i]),
                ]
                for i in range(n)
            ]
        ).reshape(n, 4)
    n = t.n if result.complete else t.n - 1
    diff = np.zeros((n, 4))
    for i in range(n):
        diff[i] = [
            wrap_angle(t.theta_offset[i] - nom.theta_offset[i]),
            t.d_offset[i] - nom.d_offset[i],
            t.a[i] - nom.a[i],
            wrap_angle(t.alpha[i] - nom.alpha[i]),
        ]
    return diff
