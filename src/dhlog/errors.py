"""The one error hierarchy of dhlog.

Every error dhlog raises on purpose derives from :class:`DhlogError`. Each class writes its own
message from the facts it is given, as whole sentences that name the joint, file or topic at fault
and say what to do. Only the command line catches ``DhlogError`` and turns it into a one-line
message and an exit code. What a run says without stopping (a warning, a note) is a
:class:`Note`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Literal


class DhlogError(Exception):
    """Base of every error dhlog raises on purpose."""


class GeometryError(DhlogError):
    """A geometric construction or fit cannot be carried out on the data given."""


class NonFiniteError(GeometryError):
    """Input holds NaN or infinite values."""

    def __init__(self, what: str, count: int) -> None:
        self.what = what
        self.count = count
        super().__init__(
            f"{what}: {count} non-finite value(s) (NaN or inf) in the input; "
            "drop or repair those samples before fitting."
        )


class TooFewPointsError(GeometryError):
    """Fewer distinct points than the model needs."""

    def __init__(self, what: str, n_distinct: int, needed: int) -> None:
        self.what = what
        self.n_distinct = n_distinct
        self.needed = needed
        super().__init__(
            f"{what}: only {n_distinct} distinct point(s), at least {needed} are needed; "
            "record more samples over the sweep."
        )


class CollinearPointsError(GeometryError):
    """Points given to a circle fit lie on a line."""

    def __init__(self, what: str) -> None:
        self.what = what
        super().__init__(
            f"{what}: the points are collinear, so no circle passes through them; "
            "if this joint is prismatic, declare it so (or fit a line)."
        )


class SweepTooSmallError(GeometryError):
    """The measured motion is too short to identify an axis."""

    def __init__(self, what: str, sweep: float, minimum: float, unit: str) -> None:
        self.what = what
        self.sweep = sweep
        self.minimum = minimum
        if unit == "rad":
            shown = f"{math.degrees(sweep):.3g}° (minimum {math.degrees(minimum):.3g}°)"
        else:
            shown = f"{sweep * 1e3:.4g} mm (minimum {minimum * 1e3:.4g} mm)"
        super().__init__(
            f"{what}: the sweep covers only {shown}; move the joint further while it is measured."
        )


class EncoderScaleError(GeometryError):
    """The encoder values do not agree with the measured travel."""

    def __init__(self, what: str, scale: float) -> None:
        self.what = what
        self.scale = scale
        super().__init__(
            f"{what}: the measured travel is {scale:.6g} times the encoder travel; "
            "check the encoder and length units (m vs mm) in the pipeline."
        )


class DegenerateGeometryError(GeometryError):
    """A construction is undefined for the configuration given (parallel line and plane, …)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)


class ShapeError(DhlogError, ValueError):
    """An array argument has the wrong shape or holds non-finite values."""

    def __init__(self, name: str, expected: str, got: object) -> None:
        self.name = name
        super().__init__(f"{name} must be {expected}, got {got}.")


class InputError(DhlogError):
    """A log, pipeline or DH file cannot be used as given."""


class NotMcapError(InputError):
    """The file does not start with the MCAP magic."""

    def __init__(self, path: str) -> None:
        super().__init__(
            f"{path}: not an MCAP file (no MCAP magic bytes at the start); give the .mcap file "
            "the recorder wrote, or the rosbag2 bag folder (a tracker program's export, CSV or "
            "text: convert it with dhlog import first)."
        )


class UnknownSchemaError(InputError):
    """A configured topic carries a message type dhlog cannot decode for that stream."""

    def __init__(self, path: str, topic: str, schema: str, encoding: str, accepted: str) -> None:
        super().__init__(
            f"{path}: topic {topic} carries '{schema}' ({encoding}), which the pipeline cannot "
            f"read as this stream; accepted: {accepted}. Point the pipeline at another topic "
            "or give its field paths."
        )


class MissingTopicError(InputError):
    """A required topic is not in the log."""

    def __init__(self, path: str, stream: str, topic: str, present: list[str]) -> None:
        listed = ", ".join(present) if present else "none"
        super().__init__(
            f"{path}: no topic {topic} for the '{stream}' stream; topics present: {listed}. "
            "Set the topic in a pipeline file (--pipeline)."
        )


class JointNamesError(InputError):
    """The joint names in the log do not match the pipeline."""

    def __init__(self, path: str, topic: str, expected: list[str], found: list[str]) -> None:
        super().__init__(
            f"{path}: topic {topic} names joints {found}, but the pipeline expects {expected}; "
            "fix [joints] names in the pipeline file."
        )


class TooFewSamplesError(InputError):
    """A stream or joint has too few usable samples."""

    def __init__(self, what: str, n: int, needed: int) -> None:
        super().__init__(
            f"{what}: only {n} usable sample(s), at least {needed} are needed; "
            "record a longer sweep or check the topic."
        )


class PipelineError(InputError):
    """A pipeline file is malformed or matches nothing."""

    def __init__(self, where: str, problem: str) -> None:
        super().__init__(f"{where}: {problem}")


class OutputError(DhlogError):
    """The results cannot be written (a full disk, a read-only or unwritable folder)."""

    def __init__(self, folder: object, exc: OSError) -> None:
        why = exc.strerror or str(exc)
        super().__init__(
            f"cannot write the results in {folder} ({why}); nothing was written there — free "
            "space or choose another folder with --out."
        )


class FieldError(InputError):
    """One field of an untrusted description (a camera's intrinsics, a target board) that
    cannot be right: the message names where, the field, the problem and what to do."""

    def __init__(self, where: str, field_name: str, problem: str, todo: str) -> None:
        self.where = where
        self.field_name = field_name
        super().__init__(f"{where}: {field_name} {problem}; {todo}.")


class DhlogWarning(UserWarning):
    """What may need the user's action, as the console's warnings say it (a joint swept too
    little, samples set aside, a nominal far from the data, a target not compensated …):
    :func:`dhlog.process`, :func:`dhlog.load`, :func:`dhlog.simulate`, :func:`dhlog.plan`,
    :func:`dhlog.acceptance_test` (its notes) and :meth:`dhlog.Calibration.compensate` /
    ``compensate_poses`` (each target not corrected) give each of theirs through
    :func:`warnings.warn` with this category and through the ``dhlog`` logger
    (``logging.getLogger("dhlog")``, level WARNING). The text is the one
    ``Calibration.warnings`` holds."""


#: The logger every warning goes through too (a :class:`logging.NullHandler` by default, as a
#: library's; the user's logging configuration decides where it goes).
LOGGER_NAME = "dhlog"


#: True while the caller prints dhlog's warnings itself (the command line): not given twice
_PRINTED_BY_CALLER: ContextVar[bool] = ContextVar("dhlog_warnings_printed", default=False)


@contextmanager
def warnings_printed_by_caller() -> Iterator[None]:
    """Within: :func:`give_warning` gives nothing — the caller (the command line) prints the
    warnings in its own words, once."""
    token = _PRINTED_BY_CALLER.set(True)
    try:
        yield
    finally:
        _PRINTED_BY_CALLER.reset(token)


def give_warning(
    message: str, category: type[DhlogWarning] = DhlogWarning, stacklevel: int = 2
) -> None:
    """Give ``message`` as dhlog gives a warning: :func:`warnings.warn` with ``category``
    (``stacklevel`` counted from the caller) and the ``dhlog`` logger at WARNING — unless
    within :func:`warnings_printed_by_caller`."""
    import logging
    import warnings

    if _PRINTED_BY_CALLER.get():
        return

    warnings.warn(category(message), stacklevel=stacklevel + 1)
    logging.getLogger(LOGGER_NAME).warning(message, extra={"dhlog_category": category.__name__})


#: A note's level: ``"warning"``, what may need the user's action (the console's "Warning:",
#: the JSON's ``warnings``, :class:`DhlogWarning`); ``"info"``, what a reader should know but
#: need not act on (the console's "Note:", the JSON's ``notes``).
NoteLevel = Literal["warning", "info"]


@dataclass(frozen=True)
class Note:
    """One thing a run says without stopping: its ``level``, its ``text`` (a whole sentence, as
    the console and the JSON show it) and its ``code``, a short stable identifier tests and
    scripts match on (``"fit-noise"``, ``"parked"``, ``"clock-offset"``) while the text's
    wording may change. Each stage of the identification returns its notes in order; the
    result keeps them in the order the run said them."""

    level: NoteLevel
    text: str
    code: str

    def __post_init__(self) -> None:
        if self.level not in ("warning", "info"):
            raise ValueError(f"Note: level {self.level!r}, not 'warning' or 'info'")

    @classmethod
    def warning(cls, text: str, code: str) -> Note:
        """A note of what may need the user's action."""
        return cls("warning", text, code)

    @classmethod
    def info(cls, text: str, code: str) -> Note:
        """A note of what a reader should know but need not act on."""
        return cls("info", text, code)


def texts(notes: Iterable[Note], level: NoteLevel) -> tuple[str, ...]:
    """The texts of ``notes`` at ``level``, in their order."""
    return tuple(n.text for n in notes if n.level == level)


class ImplausibleWarning(DhlogWarning):
    """A calibration dhlog judges implausible was made or read (``Calibration.plausible`` is
    False; ``Calibration.implausible`` gives the reasons, each naming the evidence and the
    fix): :func:`dhlog.process` and :func:`dhlog.load` warn with it, as ``dhlog process``
    exits 4. ``warnings.simplefilter("error", dhlog.ImplausibleWarning)`` makes it an error."""


class UsageError(DhlogError, ValueError):
    """An argument that cannot be used — of the Python API (``dhlog.process(holdout=1)``) or of
    a command; the message names it and what to give."""


class Iso9283Error(InputError):
    """An ISO 9283 characteristic cannot be computed from the data given (too few cycles, a
    path never crossing a plane, an arrival that never settles): the message names the
    characteristic, what is missing and what to do."""

    def __init__(self, what: str, problem: str, todo: str) -> None:
        self.what = what
        super().__init__(f"{what}: {problem}; {todo}.")
