"""Result JSONs and batch summaries read as untrusted input.

Every byte of a file handed to ``compare``, ``export`` or ``batch`` may be damaged or hostile:
its size is checked before it is read (:func:`read_limited`), a JSON document's nesting is
bounded by the parser, and each field those commands use is checked for presence, type and
range (:func:`check_result`) before any of them touches it, so that a fault is one line naming
the file and the field. The reads go through :class:`~dhlog.result.fields.FieldReader`, shared
with ``dhlog report``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from dhlog.io.dhfile import DHFileError
from dhlog.result.fields import WORDING_IS, FieldReader

#: The largest result (or DH) JSON read, and the largest batch summary (a result is ~40 kB).
MAX_RESULT_BYTES = 100 * 2**20
MAX_SUMMARY_BYTES = 100 * 2**20
#: The most joints a result may have.
MAX_JOINTS = 100
#: The longest joint name.
MAX_NAME = 256
#: Integers with more digits than this are read as floats (Python refuses over 4 300 digits).
_INT_DIGITS = 18

# ---------------------------------------------------------------------------- reading


def read_limited(path: str | Path, limit: int, what: str) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (its size checked before it is
    read; a folder, a device or a pipe refused: :func:`dhlog.io.textfile.read_capped`);
    ``what`` names it in the messages."""
    from dhlog.io.textfile import read_capped

    name = str(path)
    return read_capped(
        path,
        limit,
        lambda message: DHFileError(name, message),
        what=what,
        hint=f"give the {what} itself (is this the right file?).",
        check=f"give the {what}.",
    )


def _parse_int(text: str) -> int | float:
    """JSON integers: beyond ``_INT_DIGITS`` digits, a float (``inf`` when beyond float's
    range), which the range checks then refuse by field."""
    return int(text) if len(text) <= _INT_DIGITS else float(text)


def load_result(path: str | Path) -> dict[str, Any]:
    """A result (or DH) JSON read and checked (:func:`check_result`): every field ``compare``,
    ``export`` and ``batch`` use is present, of its type and in range."""
    name = str(path)
    raw = read_limited(path, MAX_RESULT_BYTES, "result JSON")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DHFileError(
            name, f"is not UTF-8 text (byte {exc.start}); give the result JSON, saved as UTF-8."
        ) from None
    try:
        data = json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as exc:
        raise DHFileError(
            name,
            f"is not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno}); give the "
            "result JSON dhlog process wrote.",
        ) from None
    except RecursionError:
        raise DHFileError(
            name,
            "is nested too deeply to be a result (arrays or objects inside each other thousands "
            "of levels deep); give the result JSON dhlog process wrote.",
        ) from None
    except ValueError as exc:  # a number the parser cannot hold
        raise DHFileError(name, f"holds a value JSON cannot carry ({exc}).") from None
    return check_result(data, name)


# ---------------------------------------------------------------------------- checks


def name_problem(name: str) -> str | None:
    """What is wrong with a name that lands in outputs (XML, YAML, CSV), or None."""
    if not name.strip():
        return "is empty"
    if len(name) > MAX_NAME:
        return f"is {len(name)} characters long (at most {MAX_NAME})"
    for ch in name:
        code = ord(ch)
        control = code < 0x20 or 0x7F <= code <= 0x9F
        if control or 0xD800 <= code <= 0xDFFF or code in (0xFFFE, 0xFFFF):
            return f"holds the character U+{code:04X} (a control character or a non-character)"
    return None


def _numbers(f: FieldReader, value: Any, field: str, unit: str, size: int) -> list[float]:
    items = f.array_or_null(value, field, most=size)
    if items is None:
        f.fail(field, f"is null, not a list of {size} numbers")
    if len(items) != size:
        f.fail(field, f"has {len(items)} entries, not {size}")
    return [f.number(v, f"{field}[{k}]", unit) for k, v in enumerate(items)]


def _joint_type(f: FieldReader, value: Any, field: str) -> None:
    if value is not None:
        f.text(value, field, ("revolute", "prismatic", "r", "p"))


def _std(f: FieldReader, row: dict[str, Any], field: str, d_unit: str = "length") -> None:
    block = f.obj_or_null(row.get("std"), f"{field}.std")
    if block is None:
        return
    for key, unit in (("theta", "angle"), ("d", d_unit), ("a", "length")):
        if block.get(key) is not None:
            f.number(block[key], f"{field}.std.{key}", unit, sigma=True)
    for key in ("alpha", "beta"):
        if block.get(key) is not None:
            f.number(block[key], f"{field}.std.{key}", "angle", sigma=True)


def _held(f: FieldReader, row: dict[str, Any], field: str) -> None:
    fixed = f.array_or_null(row.get("fixed"), f"{field}.fixed", most=16)
    for k, item in enumerate(fixed or []):
        f.text(item, f"{field}.fixed[{k}]")


def _scales(data: dict[str, Any], f: FieldReader) -> tuple[float, float]:
    units = f.obj_or_null(data.get("units"), "units")
    if units is None:
        return 1.0, 1.0
    length, angle = units.get("length", "m"), units.get("angle", "rad")
    if length not in ("m", "mm"):
        f.fail("units.length", "must be m or mm")
    if angle not in ("rad", "deg"):
        f.fail("units.angle", "must be rad or deg")
    return (1.0 if length == "m" else 1e-3), (1.0 if angle == "rad" else math.pi / 180)


def check_result(data: Any, source: str) -> dict[str, Any]:
    """``data`` (a parsed result or DH JSON) when every field ``compare``, ``export`` and
    ``batch`` use is present, of its type and in range; else
    :class:`~dhlog.result.fields.ResultFieldError` naming the first that is not."""
    if not isinstance(data, dict):
        raise DHFileError(
            source,
            f"holds {WORDING_IS.kind(data)}, not an object with a 'standard_dh' array; give the "
            "result JSON dhlog process wrote.",
        )
    f = FieldReader(source)
    f.length, f.angle = _scales(data, f)
    given = f.get(data, "standard_dh")
    rows = f.array_or_null(given, "standard_dh", most=MAX_JOINTS)
    if not rows:
        f.fail("standard_dh", "is empty (one row per joint is needed)")
    n = len(rows)
    far = _hayati_rows(data)
    types: list[str | None] = []
    for i, value in enumerate(rows):
        at = f"standard_dh[{i}]"
        row = f.obj_or_null(value, at)
        if row is None:
            f.fail(at, "is null, not a row")
        _joint_type(f, row.get("type"), f"{at}.type")
        types.append(str(row["type"]).strip().lower()[:1] if row.get("type") else None)
        d_unit = "far" if i in far else "length"
        for keys, unit in ((("theta_offset", "theta"), "angle"), (("d_offset", "d"), d_unit)):
            key = keys[0] if keys[0] in row else keys[1]
            if key in row:
                f.number(row[key], f"{at}.{key}", unit)
        f.number(f.get(row, "a", at), f"{at}.a", "length")
        f.number(f.get(row, "alpha", at), f"{at}.alpha", "angle")
        if "encoder_scale" in row:
            scale = f.number(row["encoder_scale"], f"{at}.encoder_scale", "plain")
            if scale <= 0:
                f.fail(f"{at}.encoder_scale", "must be positive")
        _std(f, row, at, d_unit)
        _held(f, row, at)
    _check_hayati(data, f, n, types)
    joints = f.array_or_null(data.get("joints"), "joints", most=n) or []
    for i, value in enumerate(joints):
        at = f"joints[{i}]"
        joint = f.obj_or_null(value, at)
        if joint is None:
            f.fail(at, "is null, not an object")
        if joint.get("name") is not None:
            problem = name_problem(f.text(joint["name"], f"{at}.name"))
            if problem:
                f.fail(f"{at}.name", problem)
        _joint_type(f, joint.get("type"), f"{at}.type")
    base = f.obj_or_null(data.get("base"), "base")
    if base is not None and base.get("T_measurement_base") is not None:
        _check_transform(base["T_measurement_base"], "base.T_measurement_base", f)
    tool = f.obj_or_null(data.get("tool"), "tool")
    if tool is not None:
        if tool.get("point") is not None:
            _numbers(f, tool["point"], "tool.point", "length", 3)
        std = f.array_or_null(tool.get("std"), "tool.std", most=3)
        if std is not None:
            if len(std) != 3:
                f.fail("tool.std", f"has {len(std)} entries, not 3")
            for k, v in enumerate(std):
                if v is not None:
                    f.number(v, f"tool.std[{k}]", "length", sigma=True)
    _check_nongeometric(data, f, n)
    _check_plausible(data, f)
    return data


#: The reason a result marked ``plausible: false`` without reasons is given.
UNSAID = "the result is marked implausible (plausible: false) without a reason"


def _check_plausible(data: dict[str, Any], f: FieldReader) -> None:
    """``plausible`` true or false and ``implausible`` a list of sentences, where present; a
    result marked plausible cannot list reasons against it."""
    flag = data.get("plausible")
    if flag is not None and not isinstance(flag, bool):
        f.mismatch(flag, "plausible", "true or false")
    reasons = data.get("implausible")
    if reasons is not None:
        said = f.texts(reasons, "implausible")
        if flag is True and said:
            f.fail("implausible", "lists reasons while plausible is true")


def implausible_reasons(data: dict[str, Any]) -> list[str]:
    """Why the result ``data`` (read by :func:`check_result`) is judged implausible: its
    ``implausible`` sentences (:data:`UNSAID` when it is marked ``plausible: false`` without
    any); empty for a plausible result, a DH file, or a result written before results were
    judged."""
    reasons = [str(r) for r in data.get("implausible") or []]
    if data.get("plausible") is False and not reasons:
        return [UNSAID]
    return reasons


def _hayati_rows(data: dict[str, Any]) -> set[int]:
    """The standard rows of the pairs the result gives in the Hayati-Mirmirani form (the Hayati
    row and the next: their ``d`` may be far off, and opposite); the block itself is checked by
    :func:`_check_hayati`."""
    block = data.get("hayati_dh")
    rows = block.get("rows") if isinstance(block, dict) else None
    if not isinstance(rows, list):
        return set()
    pairs = [i for i, r in enumerate(rows) if isinstance(r, dict) and r.get("form") == "hayati"]
    return {*pairs, *(i + 1 for i in pairs)}


def _check_hayati(data: dict[str, Any], f: FieldReader, n: int, types: list[str | None]) -> None:
    block = data.get("hayati_dh")
    if not block:
        return
    block = f.obj_or_null(block, "hayati_dh") or {}
    given = f.get(block, "rows", "hayati_dh")
    rows = f.array_or_null(given, "hayati_dh.rows", most=MAX_JOINTS) or []
    if len(rows) != n:
        f.fail("hayati_dh.rows", f"has {len(rows)} rows, standard_dh {n}")
    for i, value in enumerate(rows):
        at = f"hayati_dh.rows[{i}]"
        row = f.obj_or_null(value, at)
        if row is None:
            f.fail(at, "is null, not a row")
        form = f.text(f.get(row, "form", at), f"{at}.form")
        if form not in ("dh", "hayati"):
            f.fail(f"{at}.form", "must be dh or hayati")
        given = f.get(row, "type", at)
        kind = f.text(given, f"{at}.type", ("revolute", "prismatic", "r", "p"))
        if types[i] is not None and kind.strip().lower()[:1] != types[i]:
            f.fail(f"{at}.type", f"is {kind}, not the type of standard_dh[{i}]")
        required = [("theta_offset", "angle"), ("a", "length"), ("alpha", "angle")]
        required.append(("beta", "angle") if form == "hayati" else ("d_offset", "length"))
        for key, unit in required:
            f.number(f.get(row, key, at), f"{at}.{key}", unit)
        if form == "hayati" and "d_offset" in row:
            f.number(row["d_offset"], f"{at}.d_offset", "length")
        _std(f, row, at)
        _held(f, row, at)


def _check_transform(value: Any, field: str, f: FieldReader) -> None:
    """A rigid 4×4 transform (its translation a length, its rotation orthonormal)."""
    rows = f.array_or_null(value, field, most=4)
    if rows is None or len(rows) != 4:
        f.fail(field, "must be a 4×4 list of numbers")
    M = [
        _numbers(f, row, f"{field}[{r}]", "length" if r < 3 else "plain", 4)
        for r, row in enumerate(rows)
    ]
    if M[3] != [0.0, 0.0, 0.0, 1.0]:
        f.fail(f"{field}[3]", "must be 0, 0, 0, 1 (a rigid transform)")
    for i in range(3):
        for j in range(3):
            dot = sum(M[k][i] * M[k][j] for k in range(3))
            if abs(dot - (1.0 if i == j else 0.0)) > 1e-6:
                f.fail(field, "is not a rigid transform (its 3×3 part is not a rotation)")


def _check_nongeometric(data: dict[str, Any], f: FieldReader, n: int) -> None:
    """The shape of the ``nongeometric`` block (its meaning is checked where it is read)."""
    block = data.get("nongeometric")
    if not isinstance(block, dict) or not block.get("terms"):
        return  # as the DH reader: no terms, nothing read
    _numbers(f, block.get("gravity"), "nongeometric.gravity", "plain", 3)
    lumps = f.array_or_null(block.get("lumps"), "nongeometric.lumps", most=4 * MAX_JOINTS) or []
    for k, value in enumerate(lumps):
        at = f"nongeometric.lumps[{k}]"
        lump = f.obj_or_null(value, at)
        if lump is None:
            f.fail(at, "is null, not an object")
        f.text(f.get(lump, "on", at), f"{at}.on")
        # in the DH frame of its axis, whose origin may lie far off (nearly parallel axes)
        _numbers(f, lump.get("point"), f"{at}.point", "far", 3)
        if "mass" in lump:
            f.number(lump["mass"], f"{at}.mass", "mass", sigma=True)
    terms = f.array_or_null(block.get("terms"), "nongeometric.terms", most=64 * MAX_JOINTS) or []
    for k, value in enumerate(terms):
        at = f"nongeometric.terms[{k}]"
        term = f.obj_or_null(value, at)
        if term is None:
            f.fail(at, "is null, not an object")
        f.text(f.get(term, "kind", at), f"{at}.kind")
        joint = f.number(f.get(term, "joint", at), f"{at}.joint", "plain")
        if joint != int(joint) or not 1 <= joint <= n:
            f.fail(f"{at}.joint", f"must be a joint number 1-{n}")
        f.number(f.get(term, "value", at), f"{at}.value", "plain")
        if term.get("lump") is not None:
            lump_at = f.number(term["lump"], f"{at}.lump", "plain")
            if lump_at != int(lump_at) or lump_at < 0:
                f.fail(f"{at}.lump", "must be a lump's index (0, 1, …)")
