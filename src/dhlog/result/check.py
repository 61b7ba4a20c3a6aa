"""Result JSONs, batch summaries and URDF templates read as untrusted input.

Every byte of a file handed to ``compare``, ``export`` or ``batch`` may be damaged or hostile:
its size is checked before it is read (:func:`read_limited`), a JSON document's nesting is
bounded by the parser, and each field those commands use is checked for presence, type and
range (:func:`check_result`) before any of them touches it, so that a fault is one line naming
the file and the field. :class:`FieldReader` does those reads for them and for ``dhlog report``
(:mod:`dhlog.present.certificate.read`), each in its own wording (:data:`WORDING_IS`,
:data:`WORDING_MUST`) and error. :func:`refuse_inputs_as_outputs` keeps a command from writing
over one of its own inputs. Text that lands in an output (file names in comments) is made safe
for it by :func:`printable` and :func:`xml_comment_text`.
"""

from __future__ import annotations

import json
import math
import unicodedata
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from dhlog.errors import InputError
from dhlog.io.dhfile import DHFileError
from dhlog.io.paths import SameFiles

#: The largest result (or DH) JSON read, and the largest batch summary (a result is ~40 kB).
MAX_RESULT_BYTES = 100 * 2**20
MAX_SUMMARY_BYTES = 100 * 2**20
#: The most joints a result may have.
MAX_JOINTS = 100
#: The largest length (m) and angle (rad) a result's field may hold: a kilometre, 16 turns.
MAX_LENGTH_M = 1e3
MAX_ANGLE_RAD = 100.0
#: The largest standard-DH ``d`` of the rows of a nearly parallel pair (the row the result also
#: gives in the Hayati-Mirmirani form, and the next): their common normal lies far away (0.5 km
#: in a real KR5, 13.5 km in a simulated one; ~ the offset over the angle between the axes).
MAX_FAR_LENGTH_M = 1e9
#: The longest joint name.
MAX_NAME = 256
#: Integers with more digits than this are read as floats (Python refuses over 4 300 digits).
_INT_DIGITS = 18

_FIX = "repair that field, or give the <stem>.dh.json that dhlog process wrote"


class ResultFieldError(DHFileError):
    """A field of a result JSON is missing, null, of the wrong type or out of range."""

    def __init__(self, path: str, field: str, problem: str) -> None:
        self.field = field
        super().__init__(path, f"{field} {problem}; {_FIX}.")


class InputIsOutputError(InputError):
    """An output path is one of the command's inputs."""

    def __init__(self, input_path: object, what: str, output_path: object) -> None:
        super().__init__(
            f"{input_path}: the {what} is also an output of this command ({output_path}) and "
            "would be overwritten; choose another output path (or folder). Nothing was written."
        )


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


# ---------------------------------------------------------------------------- fields


@dataclass(frozen=True)
class Wording:
    """How a :class:`FieldReader` words a refusal: ``mismatch`` (a value of the wrong type,
    with ``{kind}``, what it is, and ``{wanted}``), the nouns of a JSON string and array,
    ``not_finite`` (with ``{value}``) and ``overflow`` (an integer beyond a float's range;
    None: refused as not finite)."""

    mismatch: str
    text: str
    array: str
    not_finite: str
    overflow: str | None

    def kind(self, value: object) -> str:
        """A JSON value's type as a reader would name it."""
        if value is None:
            return "null"
        if isinstance(value, bool):
            return "true/false"
        if isinstance(value, int | float):
            return "a number"
        if isinstance(value, str):
            return self.text
        if isinstance(value, list):
            return self.array
        if isinstance(value, dict):
            return "an object"
        return type(value).__name__


#: ``compare``, ``export`` and ``batch``: "tool.point is text, not a list".
WORDING_IS = Wording("is {kind}, not {wanted}", "text", "a list", "is not a finite number", None)
#: ``report``: "tool.point must be an array, not a string".
WORDING_MUST = Wording(
    "must be {wanted}, not {kind}",
    "a string",
    "an array",
    "must be a finite number, not {value}",
    "is out of range",
)


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


def _at(at: str, key: str) -> str:
    return f"{at}.{key}" if at else key


class FieldReader:
    """Typed reads of an untrusted JSON document (the file ``path``), each refusal an
    ``error(path, field, problem)`` naming the field, worded by ``wording``. ``length`` and
    ``angle``: the document's units in m and rad, for the ranges of :meth:`number`'s units."""

    def __init__(
        self,
        path: str,
        *,
        error: Callable[[str, str, str], Exception] = ResultFieldError,
        wording: Wording = WORDING_IS,
        length: float = 1.0,
        angle: float = 1.0,
    ) -> None:
        self.path = path
        self.error = error
        self.wording = wording
        self.length = length
        self.angle = angle

    def fail(self, field: str, problem: str) -> NoReturn:
        raise self.error(self.path, field, problem)

    def mismatch(self, value: object, field: str, wanted: str) -> NoReturn:
        kind = self.wording.kind(value)
        self.fail(field, self.wording.mismatch.format(kind=kind, wanted=wanted))

    def get(
        self,
        holder: dict[str, Any],
        key: str,
        at: str = "",
        *,
        required: bool = True,
        null: bool = False,
    ) -> Any:
        """``holder[key]`` (field ``at.key``): None when it is missing and not ``required``; a
        null where one is ``required`` is refused unless ``null`` (then the reader that takes
        the value words the refusal)."""
        if key not in holder:
            if required:
                self.fail(_at(at, key), "is missing")
            return None
        value = holder[key]
        if value is None and required and not null:
            self.fail(_at(at, key), "is null")
        return value

    def obj(self, value: Any, field: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            self.mismatch(value, field, "an object")
        return value

    def obj_or_null(self, value: Any, field: str) -> dict[str, Any] | None:
        return None if value is None else self.obj(value, field)

    def array(self, value: Any, field: str, *, most: int | None = None) -> list[Any]:
        """A list (of at most ``most`` items)."""
        if not isinstance(value, list):
            self.mismatch(value, field, self.wording.array)
        if most is not None and len(value) > most:
            self.fail(field, f"has {len(value)} entries (at most {most})")
        return value

    def array_or_null(self, value: Any, field: str, *, most: int | None = None) -> list[Any] | None:
        return None if value is None else self.array(value, field, most=most)

    def number(
        self,
        value: Any,
        field: str,
        unit: str | None = None,
        *,
        sigma: bool = False,
        minimum: float | None = None,
    ) -> float:
        """A finite number; within the range of its ``unit`` when one is given (``length``,
        ``angle``, ``far``: a length of an ill-conditioned row, ``mass``; any other: plain);
        ``sigma``: not negative; at least ``minimum``."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.mismatch(value, field, "a number")
        try:
            v = float(value)
        except OverflowError:
            if self.wording.overflow is not None:
                self.fail(field, self.wording.overflow)
            v = math.inf
        if not math.isfinite(v):
            self.fail(field, self.wording.not_finite.format(value=v))
        if unit is not None:
            if unit == "length":
                bound, shown, scaled = MAX_LENGTH_M, "m", v * self.length
            elif unit == "far":
                bound, shown, scaled = MAX_FAR_LENGTH_M, "m", v * self.length
            elif unit == "angle":
                bound, shown, scaled = MAX_ANGLE_RAD, "rad", v * self.angle
            elif unit == "mass":
                bound, shown, scaled = 1e6, "kg", v
            else:
                bound, shown, scaled = 1e3, "", v
            if abs(scaled) > bound:
                self.fail(field, f"is {v:.6g}, beyond ±{bound:g} {shown}".rstrip())
        if sigma and v < 0:
            self.fail(field, f"is {v:.6g}; a standard deviation is not negative")
        if minimum is not None and v < minimum:
            self.fail(field, f"must be at least {minimum:g}, not {v:g}")
        return v

    def number_or_null(
        self, value: Any, field: str, *, minimum: float | None = None
    ) -> float | None:
        return None if value is None else self.number(value, field, minimum=minimum)

    def integer(self, value: Any, field: str, *, minimum: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.mismatch(value, field, "a whole number")
        if minimum is not None and value < minimum:
            self.fail(field, f"must be at least {minimum}, not {value}")
        return value

    def text(self, value: Any, field: str, choices: Sequence[str] | None = None) -> str:
        if not isinstance(value, str):
            self.mismatch(value, field, self.wording.text)
        if choices is not None and value.strip().lower() not in choices:
            self.fail(field, f"must be one of {', '.join(choices)}")
        return value

    def texts(self, value: Any, field: str) -> list[str]:
        return [self.text(v, f"{field}[{k}]") for k, v in enumerate(self.array(value, field))]

    def vector(
        self, value: Any, field: str, size: int, *, null: bool = False
    ) -> list[float | None]:
        """``size`` numbers (``null``: each may be null)."""
        items = self.array(value, field)
        if len(items) != size:
            self.fail(field, f"must hold {size} numbers, not {len(items)}")
        if null:
            return [self.number_or_null(v, f"{field}[{k}]") for k, v in enumerate(items)]
        return [self.number(v, f"{field}[{k}]") for k, v in enumerate(items)]

    # keyed forms: parent[key] at ``at`` (optional ones None when missing or null; a required
    # null refused by the typed reader)

    def get_obj(
        self, parent: dict[str, Any], key: str, at: str = "", *, required: bool = True
    ) -> dict[str, Any] | None:
        v = self.get(parent, key, at, required=required, null=True)
        if v is None and not required:
            return None
        return self.obj(v, _at(at, key))

    def get_number(
        self,
        parent: dict[str, Any],
        key: str,
        at: str = "",
        *,
        required: bool = True,
        null: bool = False,
        minimum: float | None = None,
    ) -> float | None:
        v = self.get(parent, key, at, required=required, null=True)
        if v is None and (null or not required):
            return None
        return self.number(v, _at(at, key), minimum=minimum)

    def get_text(
        self, parent: dict[str, Any], key: str, at: str = "", *, required: bool = True
    ) -> str | None:
        v = self.get(parent, key, at, required=required, null=True)
        if v is None and not required:
            return None
        return self.text(v, _at(at, key))


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
    ``batch`` use is present, of its type and in range; else :class:`ResultFieldError` naming
    the first that is not."""
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
    return data


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


# ---------------------------------------------------------------------------- outputs


def refuse_inputs_as_outputs(inputs: Iterable[tuple[Path, str]], outputs: Iterable[Path]) -> None:
    """:class:`InputIsOutputError` when an input (path, what it is) is one of ``outputs``: the
    same path once resolved (symbolic links followed), or the same file (hard links)."""
    written = SameFiles(outputs)
    for path, what in inputs:
        hit = written.find(path)
        if hit is not None:
            raise InputIsOutputError(path, what, hit)


# ---------------------------------------------------------------------------- text in outputs


def printable(text: str) -> str:
    """``text`` with every character that is not printable on one line (controls, line and
    paragraph separators, surrogates of undecodable file names, unassigned code points) as a
    ``\\xNN`` / ``\\uNNNN`` escape: safe in a comment of XML, YAML or Python."""
    out = []
    for ch in text:
        category = unicodedata.category(ch)
        if category[0] == "C" or category in ("Zl", "Zp"):
            code = ord(ch)
            out.append(f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")
        else:
            out.append(ch)
    return "".join(out)


def xml_comment_text(text: str) -> str:
    """``text`` fit for an XML comment: printable, no ``--``, not ending in ``-``."""
    safe = printable(text)
    while "--" in safe:
        safe = safe.replace("--", "- -")
    return safe + " " if safe.endswith("-") else safe
