"""A pipeline file's values checked as they are read: strings of at most :data:`MAX_TEXT`
characters, flags, lists of strings, numbers in a range, tables, and every table's keys against
the known ones (the nearest suggested); each error names the pipeline and the key.
"""

from __future__ import annotations

import datetime
import math
from typing import Any

from dhlog.errors import PipelineError

#: The most characters a string value may have, and the most joints.
MAX_TEXT, MAX_JOINTS = 1000, 64


def _shown(value: object) -> str:
    """A value as the file spells it, cut short (``true``, ``"abc"``, ``[1, 2]``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and abs(value) > 10**30:
        return "an integer of more than 30 digits"
    if isinstance(value, datetime.date | datetime.time):  # a TOML date or time
        return f"the date/time {value.isoformat()}"
    text = f'"{value}"' if isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "…"


def _text(source: str, where: str, value: object) -> str:
    """A string value (the key named in ``where``)."""
    if not isinstance(value, str):
        raise PipelineError(source, f"{where} must be a string, not {_shown(value)}.")
    if len(value) > MAX_TEXT:
        raise PipelineError(
            source, f"{where} is a string of {len(value)} characters (at most {MAX_TEXT})."
        )
    return value


def _flag(source: str, where: str, value: object) -> bool:
    if not isinstance(value, bool):
        raise PipelineError(source, f"{where} must be true or false, not {_shown(value)}.")
    return value


def _texts(source: str, where: str, value: object) -> list[str]:
    if not isinstance(value, list):
        raise PipelineError(source, f"{where} must be a list of strings, not {_shown(value)}.")
    if len(value) > MAX_JOINTS:
        raise PipelineError(source, f"{where} has {len(value)} entries (at most {MAX_JOINTS}).")
    return [_text(source, f"{where}[{k}]", v) for k, v in enumerate(value)]


def _number(
    source: str, where: str, value: object, lo: float, hi: float, unit: str, *, whole: bool = False
) -> float:
    """A finite number (not a boolean; a whole one when ``whole``) within ``[lo, hi]``."""
    span = f"{int(lo)} to {int(hi)}" if whole else f"{lo:g} to {hi:g} {unit}"
    whole_one = ", a whole one" if whole else ""
    refused = PipelineError(
        source,
        f"{where} must be a finite number from {span}{whole_one}, not {_shown(value)}; correct "
        "it in the pipeline.",
    )
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise refused
    try:
        x = float(value)
    except OverflowError:
        raise refused from None
    if not math.isfinite(x) or not lo <= x <= hi or (whole and not x.is_integer()):
        raise refused
    return x


def _check_keys(source: str, where: str, given: dict[str, Any], known: tuple[str, ...]) -> None:
    """A one-line error for the first key of ``given`` not in ``known``, with the nearest."""
    import difflib

    for key in given:
        if key not in known:
            near = difflib.get_close_matches(key, known, n=1, cutoff=0.5)
            hint = f"did you mean '{near[0]}'? " if near else ""
            raise PipelineError(
                source, f"{where}: unknown key '{key}'; {hint}known keys: {', '.join(known)}."
            )


def _table(where: str, data: dict[str, Any], key: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise PipelineError(where, f"[{key}] must be a table.")
    return value
