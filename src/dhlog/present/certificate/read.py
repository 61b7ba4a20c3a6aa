"""A result JSON read for the certificate, every byte untrusted: :func:`read_result` checks
it field by field through the shared :class:`~dhlog.result.check.FieldReader` (worded "must
be …, not …"), a fault a :class:`ResultFileError` naming the file and the field."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.errors import InputError
from dhlog.geometry._checks import roll_pitch_yaw
from dhlog.identify.segment.timing import set_by
from dhlog.io.pointids import MAX_ID, listed
from dhlog.present.certificate.camera import read_camera
from dhlog.present.certificate.shown import (
    Check,
    JointResidual,
    Parameter,
    Result,
    ShownRow,
    Stats,
    Triple,
    mm,
)
from dhlog.result.contract import RESULT_FORMAT
from dhlog.result.fields import WORDING_MUST, FieldReader

#: What to do about a damaged result JSON.
REMEDY = "the file is damaged or not a dhlog result: write it again with dhlog process"


class ResultFileError(InputError):
    """A result JSON, or a CSV written beside it, cannot be used: ``field`` is the key (or
    column) at fault."""

    def __init__(self, path: str, field: str, problem: str, remedy: str = REMEDY) -> None:
        self.field = field
        super().__init__(f"{path}: {field} {problem}; {remedy}.")


def _reader(path: str) -> FieldReader:
    """The reader of ``path``: refusals as :class:`ResultFileError`, worded "must be …, not …"."""
    return FieldReader(path, error=ResultFileError, wording=WORDING_MUST)


def _reasons(fixed: list[str], reason: str) -> dict[str, str]:
    """``fixed_reason`` (``"theta: why; d: why"``) split per parameter; a reason in another
    form is every fixed parameter's."""
    parts = re.split(r"(?:^|; )(theta|d|beta|a|alpha|scale): ", reason)
    found: dict[str, str] = {}
    if len(parts) > 1 and not parts[0]:
        for name, why in zip(parts[1::2], parts[2::2], strict=True):
            found[name] = why.strip()
    return {name: found.get(name) or reason or "held by a convention" for name in fixed}


def _rows(f: FieldReader, doc: dict[str, Any], names: list[str]) -> list[ShownRow]:
    """The table as shown: ``hayati_dh.rows`` when present, else ``standard_dh``."""
    standard = f.array(f.get(doc, "standard_dh", "", null=True), "standard_dh")
    if len(standard) > len(names):
        f.fail("standard_dh", f"has {len(standard)} rows for {len(names)} joints")
    block = f.get_obj(doc, "hayati_dh", required=False)
    at = "hayati_dh.rows" if block is not None else "standard_dh"
    shown = standard
    if block is not None:
        shown = f.array(f.get(block, "rows", "hayati_dh", null=True), at)
        if len(shown) != len(standard):
            f.fail(at, f"has {len(shown)} rows, standard_dh {len(standard)}")
    out = []
    for i, item in enumerate(shown):
        where = f"{at}[{i}]"
        row = f.obj(item, where)
        plain = f.obj(standard[i], f"standard_dh[{i}]")
        form = "dh"
        if block is not None:
            form = f.get_text(row, "form", where) or "dh"
            if form not in ("dh", "hayati"):
                f.fail(f"{where}.form", f"must be dh or hayati, not {form[:40]!r}")
        kind = f.get_text(row, "type", where, required=False) or "revolute"
        if kind not in ("revolute", "prismatic"):
            f.fail(f"{where}.type", f"must be revolute or prismatic, not {kind[:40]!r}")
        second = "beta" if form == "hayati" else "d"
        keys = ("theta_offset", "beta" if form == "hayati" else "d_offset", "a", "alpha")
        names4 = ("theta", second, "a", "alpha")
        std = f.get_obj(row, "std", where)
        assert std is not None
        fixed_list = []
        if "fixed" in row and row["fixed"] is not None:
            fixed_list = f.texts(row["fixed"], f"{where}.fixed")
            for k, name in enumerate(fixed_list):
                if name not in names4:
                    f.fail(f"{where}.fixed[{k}]", f"names {name[:40]!r}, not one of {names4}")
        reason = f.get_text(row, "fixed_reason", where, required=False) or ""
        held = _reasons(fixed_list, reason)
        params = []
        for key, name in zip(keys, names4, strict=True):
            value = f.get_number(row, key, where)
            assert value is not None
            sd = f.get_number(std, name, f"{where}.std", null=True, minimum=0.0)
            params.append(Parameter(name, value, None if name in held else sd, held.get(name)))
        if "encoder_scale" in plain:
            scale = f.get_number(plain, "encoder_scale", f"standard_dh[{i}]")
            sd = f.get_number(
                plain, "encoder_scale_std", f"standard_dh[{i}]", required=False, minimum=0.0
            )
            assert scale is not None
            params.append(Parameter("scale", scale, sd, None))
        out.append(ShownRow(i + 1, names[i], kind, form, params))
    return out


def _stats(f: FieldReader, parent: dict[str, Any], key: str, at: str) -> Stats | None:
    block = f.get_obj(parent, key, at, required=key == "calibrated")
    if block is None:
        return None
    where = f"{at}.{key}"
    values = [f.get_number(block, k, where, minimum=0.0) for k in ("mean", "rms", "p95", "max")]
    n = f.integer(f.get(block, "n_poses", where, null=True), f"{where}.n_poses", minimum=1)
    mean, rms, p95, top = (float(v or 0.0) for v in values)
    return Stats(mean, rms, p95, top, n)


def _calibrated(f: FieldReader, entry: dict[str, Any], at: str) -> Stats:
    stats = _stats(f, entry, "calibrated", at)
    assert stats is not None  # required
    return stats


def _checks(f: FieldReader, validation: dict[str, Any]) -> list[Check]:
    raw = validation.get("holdout")
    if raw is None:
        return []
    out = []
    for k, item in enumerate(f.array(raw, "validation.holdout")):
        at = f"validation.holdout[{k}]"
        entry = f.obj(item, at)
        kind = f.get_text(entry, "kind", at)
        n = f.integer(f.get(entry, "n_poses", at, null=True), f"{at}.n_poses", minimum=1)
        if kind == "cross-validation":
            folds = f.get(entry, "folds", at, required=False)
            label = "cross-validation"
            if folds is not None:
                label = f"{f.integer(folds, f'{at}.folds', minimum=2)}-fold cross-validation"
        elif kind == "log":
            path = f.get_text(entry, "path", at, required=False) or "another log"
            label = f"log {Path(path).name}"
            if entry.get("registered") is True:
                label += " (tracker moved: base placed again)"
        else:
            f.fail(f"{at}.kind", f"must be cross-validation or log, not {str(kind)[:40]!r}")
        notes = entry.get("notes")
        out.append(
            Check(
                label,
                n,
                _stats(f, entry, "nominal", at),
                _calibrated(f, entry, at),
                [] if notes is None else f.texts(notes, f"{at}.notes"),
            )
        )
    return out


def _residuals(f: FieldReader, joints: list[dict[str, Any]]) -> list[JointResidual]:
    out = []
    for i, j in enumerate(joints):
        at = f"joints[{i}]"
        fit = f.get_obj(j, "fit", at, required=False)
        fit_rms = fit_points = None
        if fit is not None:
            fit_rms = f.get_number(fit, "rms", f"{at}.fit", null=True, minimum=0.0)
            points = f.get(fit, "n_points", f"{at}.fit", required=False)
            if points is not None:
                fit_points = f.integer(points, f"{at}.fit.n_points", minimum=0)
        val = f.get_obj(j, "validation", at, required=False)
        fk_rms = fk_max = fk_points = None
        if val is not None:
            fk_rms = f.get_number(val, "fk_rms", f"{at}.validation", null=True, minimum=0.0)
            fk_max = f.get_number(val, "fk_max", f"{at}.validation", null=True, minimum=0.0)
            points = f.get(val, "n_points", f"{at}.validation", required=False)
            if points is not None:
                fk_points = f.integer(points, f"{at}.validation.n_points", minimum=0)
        error = f.get_text(j, "error", at, required=False)
        name = f.get_text(j, "name", at) or f"joint_{i + 1}"
        out.append(
            JointResidual(i + 1, name, fit_rms, fit_points, fk_rms, fk_max, fk_points, error)
        )
    return out


def _measurement(f: FieldReader, doc: dict[str, Any]) -> list[tuple[str, str]]:
    """The tracker, noise model, clock and fit facts the result records, as (label, text)."""
    lines: list[tuple[str, str]] = []
    noise = f.get_obj(doc, "noise", required=False)
    if noise is not None:
        model = f.get_text(noise, "model", "noise")
        assert model is not None
        if model == "tracker":
            radial = f.get_number(noise, "radial", "noise", required=False, minimum=0.0)
            transverse = f.get_number(noise, "transverse", "noise", required=False, minimum=0.0)
            per_m = f.get_number(noise, "transverse_per_m", "noise", required=False, minimum=0.0)
            parts = ["laser tracker specification"]
            if radial is not None:
                parts.append(f"radial σ {radial * 1e6:.3g} µm")
            if transverse is not None:
                grow = f" + {per_m * 1e6:.3g} µm/m" if per_m is not None else ""
                parts.append(f"transverse σ {transverse * 1e6:.3g} µm{grow}")
            station = noise.get("station")
            if station is not None:
                s = f.vector(station, "noise.station", 3)
                parts.append("station at (" + ", ".join(f"{v or 0.0:.4f}" for v in s) + ") m")
            lines.append(("Noise model", ", ".join(parts)))
        elif model == "per-sample":
            lines.append(
                ("Noise model", "per-sample covariance carried by the log (e.g. the export's U95)")
            )
        elif model == "isotropic":
            sigma = f.get_number(noise, "sigma", "noise", required=False, null=True, minimum=0.0)
            shown = "" if sigma is None else f", σ {mm(sigma)} per coordinate"
            source = f.get_text(noise, "sigma_source", "noise", required=False)
            lines.append(("Noise model", f"isotropic{shown}" + (f" ({source})" if source else "")))
        else:
            f.fail("noise.model", f"must be isotropic, tracker or per-sample, not {model[:40]!r}")
        err = f.get_number(noise, "model_error_sigma", "noise", required=False, minimum=0.0)
        if err is not None:
            lines.append(
                (
                    "Model-error σ",
                    f"{mm(err)} per coordinate, estimated and added to every sample's "
                    "declared uncertainty (what the model leaves beyond the tracker)",
                )
            )
        chi2 = f.get_number(noise, "chi2_dof", "noise", required=False, minimum=0.0)
        if chi2 is not None:
            lines.append(("χ²/dof", f"{chi2:.3f}"))
    whole = f.get_obj(doc, "whole_fit", required=False)
    if whole is not None:
        n = f.get(whole, "n_points", "whole_fit", required=False)
        out_ = f.get(whole, "n_outliers", "whole_fit", required=False)
        if n is not None:
            text = f"{f.integer(n, 'whole_fit.n_points', minimum=0)} samples"
            if out_ is not None:
                text += (
                    f", {f.integer(out_, 'whole_fit.n_outliers', minimum=0)} held out as outliers"
                )
            named = f.get(whole, "outliers", "whole_fit", required=False)
            if named is not None and f.texts(named, "whole_fit.outliers"):
                ids = [t[:MAX_ID] for t in f.texts(named, "whole_fit.outliers")]
                text += f": {listed(ids)}"
            lines.append(("Samples fitted", text))
        rot = f.get_number(whole, "sigma_rotation", "whole_fit", required=False, minimum=0.0)
        if rot is not None:
            lines.append(("Orientation σ", f"{math.degrees(rot):.5f}° (6-DoF target)"))
        ident = f.get_obj(whole, "identifiability", "whole_fit", required=False)
        if ident is not None:
            cond = f.get_number(
                ident, "condition_number", "whole_fit.identifiability", required=False, null=True
            )
            if cond is not None:
                lines.append(("Condition number", f"{cond:.4g} (scaled Jacobian of the fit)"))
    timing = f.get_obj(doc, "timing", required=False)
    if timing is not None:
        offset = f.get_number(timing, "clock_offset", "timing")
        sd = f.get_number(timing, "std", "timing", null=True, required=False, minimum=0.0)
        source = f.get_text(timing, "source", "timing", required=False) or "?"
        reason = f.get_text(timing, "reason", "timing", required=False)
        text = f"joint-state stamps {float(offset or 0.0) * 1e3:+.4f} ms"
        if sd is not None:
            text += f" ± {sd * 1e3:.4f} ms"
        text += f" onto the tracker's clock ({source}" + (f": {reason})" if reason else ")")
        coarse = f.get_number(timing, "coarse_offset", "timing", required=False)
        if coarse:
            text += (
                f"; {coarse:+.2f} s of it matched by when each stream moves (the joint states' "
                "clock was seconds off the tracker's)"
            )
        drift = f.get_number(timing, "clock_drift", "timing", required=False)
        if drift:
            text += (
                f"; the offset at the sweeps' mean time, the joint states' clock running "
                f"{abs(drift) * 1e6:.1f} ppm {'fast' if drift < 0 else 'slow'} against the "
                "tracker's (their stamps mapped by it)"
            )
        step = f.get_number(timing, "clock_step", "timing", required=False)
        if step:
            text += (
                f"; the joint states' clock {set_by(step)} mid-session (their stamps after it "
                "moved by that)"
            )
        lines.append(("Clock offset", text))
    base = f.get_obj(doc, "base", required=False)
    if base is not None:
        origin = f.get_text(base, "frame_1_origin", "base", required=False)
        if origin:
            lines.append(("Frame 1 origin", origin))
    seg = f.get_obj(doc, "segmentation", required=False)
    if seg is not None:
        aside = f.get_obj(seg, "set_aside", "segmentation", required=False)
        if aside:
            counts = [
                f"{str(k)[:40]} {f.integer(v, f'segmentation.set_aside.{str(k)[:40]}', minimum=0)}"
                for k, v in aside.items()
            ]
            lines.append(("Set aside", ", ".join(counts)))
    return lines


def _unknown() -> list[float | None]:
    return [None, None, None]


def _tool(f: FieldReader, doc: dict[str, Any], n_rows: int) -> list[Triple]:
    """(label, x y z in SI, σ, fixed coordinates) for the tool point(s) and frame 1 in M."""
    out: list[Triple] = []
    tool = f.get_obj(doc, "tool", required=False)
    if tool is not None and tool.get("point") is not None:
        point = [v or 0.0 for v in f.vector(tool["point"], "tool.point", 3)]
        std = f.vector(tool["std"], "tool.std", 3, null=True) if "std" in tool else _unknown()
        fixed = f.texts(tool["fixed"], "tool.fixed") if tool.get("fixed") is not None else []
        why = f.get_text(tool, "fixed_reason", "tool", required=False) or ""
        out.append(Triple(f"tool point in frame {n_rows + 1} [mm]", point, std, fixed, why))
        extra = tool.get("further_targets")
        for k, item in enumerate([] if extra is None else f.array(extra, "tool.further_targets")):
            at = f"tool.further_targets[{k}]"
            t = f.obj(item, at)
            p = [v or 0.0 for v in f.vector(f.get(t, "point", at, null=True), f"{at}.point", 3)]
            sd = f.vector(f.get(t, "std", at, null=True), f"{at}.std", 3, null=True)
            out.append(Triple(f"target {k + 2} in frame {n_rows + 1} [mm]", p, sd))
    base = f.get_obj(doc, "base", required=False)
    if base is not None and base.get("T_measurement_base") is not None:
        rows = f.array(base["T_measurement_base"], "base.T_measurement_base")
        if len(rows) != 4:
            f.fail("base.T_measurement_base", "must be a 4×4 matrix")
        T = [
            [v or 0.0 for v in f.vector(r, f"base.T_measurement_base[{k}]", 4)]
            for k, r in enumerate(rows)
        ]
        base_std = f.get_obj(base, "std", "base", required=False) or {}
        tr = base_std.get("translation")
        rot = base_std.get("rotation")
        t_std = _unknown() if tr is None else f.vector(tr, "base.std.translation", 3, null=True)
        r_std = _unknown() if rot is None else f.vector(rot, "base.std.rotation", 3, null=True)
        out.append(Triple("frame 1 origin in M [mm]", [T[0][3], T[1][3], T[2][3]], t_std))
        rpy = list(roll_pitch_yaw(np.array([r[:3] for r in T[:3]])))
        out.append(Triple("frame 1 rotation in M [°] (roll, pitch, yaw)", rpy, r_std))
    return out


def _nongeometric(f: FieldReader, doc: dict[str, Any]) -> dict[str, Any] | None:
    """The ``nongeometric`` block's selection and terms, checked (SI as in the JSON)."""
    block = f.get_obj(doc, "nongeometric", required=False)
    if block is None:
        return None
    at = "nongeometric"
    out: dict[str, Any] = {"mode": None, "chosen": None, "candidates": [], "terms": []}
    sel = f.get_obj(block, "selection", at, required=False)
    if sel is not None:
        out["mode"] = f.get_text(sel, "mode", f"{at}.selection", required=False)
        out["chosen"] = f.get_text(sel, "chosen", f"{at}.selection", required=False)
        cands = sel.get("candidates")
        for k, item in enumerate(
            [] if cands is None else f.array(cands, f"{at}.selection.candidates")
        ):
            w = f"{at}.selection.candidates[{k}]"
            c = f.obj(item, w)
            out["candidates"].append(
                {
                    "model": f.get_text(c, "model", w),
                    "parameters": f.integer(
                        f.get(c, "parameters", w, null=True), f"{w}.parameters", minimum=0
                    ),
                    "bic": f.get_number(c, "bic", w, required=False, null=True),
                    "holdout_rms": f.get_number(
                        c, "holdout_rms", w, required=False, null=True, minimum=0.0
                    ),
                    "range_sd": f.get_number(
                        c, "range_sd", w, required=False, null=True, minimum=0.0
                    ),
                    "chosen": c.get("chosen") is True,
                    "why": f.get_text(c, "why", w, required=False) or "",
                }
            )
    lumps = block.get("lumps")
    lump_names = []
    for k, item in enumerate([] if lumps is None else f.array(lumps, f"{at}.lumps")):
        lump = f.obj(item, f"{at}.lumps[{k}]")
        lump_names.append(f.get_text(lump, "on", f"{at}.lumps[{k}]") or "")
    terms = block.get("terms")
    for k, item in enumerate([] if terms is None else f.array(terms, f"{at}.terms")):
        w = f"{at}.terms[{k}]"
        t = f.obj(item, w)
        lump_at = t.get("lump")
        lump_name = ""
        if lump_at is not None:
            index = f.integer(lump_at, f"{w}.lump", minimum=0)
            if index >= len(lump_names):
                f.fail(f"{w}.lump", f"is {index}; there are {len(lump_names)} lumps")
            lump_name = lump_names[index]
        out["terms"].append(
            {
                "name": f.get_text(t, "name", w),
                "kind": f.get_text(t, "kind", w),
                "joint": f.integer(f.get(t, "joint", w, null=True), f"{w}.joint", minimum=1),
                "lump": lump_name,
                "value": f.get_number(t, "value", w),
                "std": f.get_number(t, "std", w, null=True, minimum=0.0),
                "unit": f.get_text(t, "unit", w),
            }
        )
    deflection = block.get("max_deflection")
    out["max_deflection"] = (
        None
        if deflection is None
        else [
            f.number(v, f"{at}.max_deflection[{k}]")
            for k, v in enumerate(f.array(deflection, f"{at}.max_deflection"))
        ]
    )
    out["max_target_displacement"] = f.get_number(
        block, "max_target_displacement", at, required=False, null=True, minimum=0.0
    )
    return out


def read_result(document: Any, path: str) -> Result:
    """The result document checked field by field (a :class:`ResultFileError` names the first
    one at fault)."""
    f = _reader(path)
    doc = f.obj(document, "the document")
    fmt = f.get_text(doc, "format")
    if fmt != RESULT_FORMAT:
        f.fail("format", f"is {str(fmt)[:40]!r}, not {RESULT_FORMAT!r}")
    version = f.get_text(doc, "dhlog_version") or "?"
    source = f.get_obj(doc, "source")
    assert source is not None
    log_name = f.get_text(source, "path", "source") or ""
    sha = f.get_text(source, "sha256", "source") or ""
    if sha and not re.fullmatch(r"[0-9a-f]{64}", sha):
        f.fail("source.sha256", "must be 64 lowercase hexadecimal digits or empty")
    pipeline = f.get_text(source, "pipeline", "source") or ""
    units = f.get_obj(doc, "units")
    assert units is not None
    if units.get("length") != "m" or units.get("angle") != "rad":
        f.fail("units", 'must be {"length": "m", "angle": "rad"} (the result contract)')
    joints = [
        f.obj(j, f"joints[{i}]")
        for i, j in enumerate(f.array(f.get(doc, "joints", "", null=True), "joints"))
    ]
    if not joints:
        f.fail("joints", "is empty")
    names = [f.get_text(j, "name", f"joints[{i}]") or "" for i, j in enumerate(joints)]
    types: list[str | None] = []
    for i, j in enumerate(joints):
        kind = f.get_text(j, "type", f"joints[{i}]", required=False)
        if kind not in (None, "revolute", "prismatic"):
            f.fail(f"joints[{i}].type", f"must be revolute, prismatic or null, not {kind[:40]!r}")
        types.append(kind)
    ref = f.array(f.get(doc, "reference_pose", "", null=True), "reference_pose")
    if len(ref) != len(joints):
        f.fail("reference_pose", f"has {len(ref)} values for {len(joints)} joints")
    reference = [f.number(v, f"reference_pose[{k}]") for k, v in enumerate(ref)]
    rows = _rows(f, doc, names)
    validation = f.get_obj(doc, "validation")
    assert validation is not None
    fk_rms = f.get_number(validation, "fk_rms", "validation", null=True, minimum=0.0)
    fk_max = f.get_number(validation, "fk_max", "validation", null=True, minimum=0.0)
    fk_points = f.integer(
        f.get(validation, "n_points", "validation", null=True),
        "validation.n_points",
        minimum=0,
    )
    warnings = f.texts(f.get(doc, "warnings", "", null=True), "warnings")
    notes_raw = doc.get("notes")
    notes = [] if notes_raw is None else f.texts(notes_raw, "notes")
    method = f.get_text(doc, "method", required=False)
    flag = doc.get("plausible")
    if flag is not None and not isinstance(flag, bool):
        f.mismatch(flag, "plausible", "true or false")
    reasons_raw = doc.get("implausible")
    reasons = [] if reasons_raw is None else f.texts(reasons_raw, "implausible")
    if flag is False and not reasons:
        reasons = ["the result is marked implausible (plausible: false) without a reason"]
    return Result(
        version,
        log_name,
        sha,
        pipeline,
        method,
        len(joints),
        names,
        types,
        reference,
        rows,
        _checks(f, validation),
        fk_rms,
        fk_max,
        fk_points,
        _residuals(f, joints),
        warnings,
        notes,
        _measurement(f, doc),
        _tool(f, doc, len(rows)),
        _nongeometric(f, doc),
        read_camera(f, doc),
        reasons,
    )
