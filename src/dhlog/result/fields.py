"""The typed reader of an untrusted JSON document: :class:`FieldReader` reads each field a
caller uses and checks its presence, type and range, so that a fault is one line naming the file
and the field. Shared by the result's checks (:mod:`dhlog.result.check`: ``compare``, ``export``,
``batch``) and ``dhlog report`` (:mod:`dhlog.present.certificate.read`), each in its own wording
(:data:`WORDING_IS`, :data:`WORDING_MUST`) and error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NoReturn

from dhlog.io.dhfile import DHFileError

#: The largest length (m) and angle (rad) a result's field may hold: a kilometre, 16 turns.
MAX_LENGTH_M = 1e3
MAX_ANGLE_RAD = 100.0
#: The largest standard-DH ``d`` of the rows of a nearly parallel pair (the row the result also
#: gives in the Hayati-Mirmirani form, and the next): their common normal lies far away (0.5 km
#: in a real KR5, 13.5 km in a simulated one; ~ the offset over the angle between the axes).
MAX_FAR_LENGTH_M = 1e9

_FIX = "repair that field, or give the <stem>.dh.json that dhlog process wrote"


class ResultFieldError(DHFileError):
    """A field of a result JSON is missing, null, of the wrong type or out of range."""

    def __init__(self, path: str, field: str, problem: str) -> None:
        self.field = field
        super().__init__(path, f"{field} {problem}; {_FIX}.")


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
