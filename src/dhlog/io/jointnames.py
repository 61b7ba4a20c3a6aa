"""A joint-state stream's joints matched to a model's joints by name.

A ``sensor_msgs/msg/JointState`` (or ``foxglove.JointStates``, or a JSON stream with names)
names its joints, in whatever order its publisher keeps: Universal Robots' ROS 2 driver
publishes ``elbow_joint`` first, in the alphabetical order of ros2_control's interfaces.
:func:`chain_order` decides which of the stream's names are the model's joints 1 … n:

- a pipeline's ``[joints] names`` are the chain, in its order (the user's mapping);
- else, the model's names (a DH file's ``joints[].name``, a library robot's driver names)
  found in the stream, exactly, or each once behind a prefix (``left_shoulder_pan_joint``: a
  driver's ``tf_prefix``); the stream's other joints (a gripper's) are left out, named once;
- else, names that only number the joints (``joint_1``, ``J2``, ``A3``, ``axis4``, ``q5``) in
  the order of their numbers — but for a ``dhlog import`` log, which wrote its joints in chain
  order already (by their numbers, or as ``--joint-columns`` gave them: a rail's A7 first);
- else, the stream's order (first seen): nothing names the chain, so a permutation is left to
  the data to reveal (:mod:`dhlog.identify.check.permutation`).

Where the model and the stream both name their joints and the names do not match,
:class:`JointNamesMismatchError` names both lists and the fix.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from dhlog.errors import InputError

#: A name that only numbers a joint (``joint_1``, ``J2``, ``A3``, ``axis 4``, ``q5``, ``theta6``).
NUMBERED = re.compile(r"(?i)^(?:joint|jnt|j|axis|ax|a|q|theta)[ _\-]?0*(\d{1,2})$")

#: How the chain was found in the stream.
How = Literal["pipeline", "name", "prefix", "number", "order"]


class JointNamesMismatchError(InputError):
    """The stream's joint names and the model's are both given and do not match."""

    def __init__(
        self, path: str, topic: str, found: Sequence[str], model: Sequence[str], source: str
    ) -> None:
        missing = [m for m in model if _matches(m, found) != 1]
        super().__init__(
            f"{path}: {topic} names its joints {_listed(found)}, but the nominal {source} names "
            f"them {_listed(model)} ({_listed(missing)} not found once in the stream); map them: "
            "list the stream's names in chain order in a pipeline file ([joints] names = [...], "
            "--pipeline), or name the nominal's joints as the stream does (joints[].name in "
            "the DH file)."
        )


def _listed(names: Sequence[str]) -> str:
    shown = ", ".join(names[:12]) + (f", … ({len(names)} in all)" if len(names) > 12 else "")
    return f"[{shown}]"


def numbers(names: Sequence[str]) -> list[int] | None:
    """The joint numbers of ``names`` when every name only numbers a joint and they number
    1 … len(names) once each; else None."""
    found = [NUMBERED.match(n.strip()) for n in names]
    if not names or any(m is None for m in found):
        return None
    out = [int(m.group(1)) for m in found if m is not None]
    return out if sorted(out) == list(range(1, len(names) + 1)) else None


def named(names: Sequence[str] | None) -> bool:
    """Whether ``names`` (a model's) name the joints rather than number them: a DH file
    without ``joints[].name`` numbers them ``joint_1`` … (no names to match); a name given
    twice names no joint (the DH file's reader refuses it)."""
    listed = list(names or [])
    return bool(listed) and numbers(listed) is None and len(set(listed)) == len(listed)


def _behind_prefix(stream: str, model: str) -> bool:
    """``stream`` is ``model`` behind a prefix ending in a separator (``left_``, ``ur/``)."""
    return (
        len(stream) > len(model)
        and stream.endswith(model)
        and not stream[-len(model) - 1].isalnum()
    )


def _matches(model: str, found: Sequence[str]) -> int:
    """How many of the stream's names ``found`` are the model's name ``model``."""
    if model in found:
        return 1
    return sum(1 for s in found if _behind_prefix(s, model))


@dataclass(frozen=True)
class ChainOrder:
    """The stream's names of the model's joints 1 … n (``names``), how they were found, the
    stream's names left out (not in the chain) and a note for the reader (None: nothing to
    say)."""

    names: tuple[str, ...]
    how: How
    left_out: tuple[str, ...] = ()
    note: str | None = None

    @property
    def by_name(self) -> bool:
        """Whether names decided the chain (the model's, or the pipeline's mapping)."""
        return self.how in ("pipeline", "name", "prefix")


def chain_order(
    found: Sequence[str],
    model: Sequence[str] | None,
    *,
    path: str,
    topic: str,
    source: str = "model",
    pipeline: Sequence[str] | None = None,
    in_chain_order: bool = False,
) -> ChainOrder:
    """The stream's joints (``found``, first seen first) in the chain order of a model named
    ``model`` (None or numbered names: no names to match), by the rules of the module
    docstring. ``pipeline``: the pipeline's ``[joints] names`` (the chain as the user gave it).
    ``in_chain_order``: the stream's writer put its joints in chain order (``dhlog import``'s
    record says ``joint_order = chain``), so numbered names do not reorder them. Raises
    :class:`JointNamesMismatchError` when the model and the stream name their joints
    differently."""
    found = list(found)
    if pipeline:
        return ChainOrder(tuple(pipeline), "pipeline", tuple(n for n in found if n not in pipeline))
    numbered = numbers(found)
    if model is not None and named(model):
        chain = list(model)
        if all(m in found for m in chain):
            left = tuple(n for n in found if n not in chain)
            return ChainOrder(tuple(chain), "name", left, _left_out_note(topic, left))
        if all(_matches(m, found) == 1 for m in chain):
            picked = [
                m if m in found else next(s for s in found if _behind_prefix(s, m)) for m in chain
            ]
            left = tuple(n for n in found if n not in picked)
            pairs = zip(picked, chain, strict=True)
            prefixes = sorted({p[: len(p) - len(m)] for p, m in pairs if p != m})
            note = (
                f"{topic}'s joints matched to the nominal's by name behind the prefix "
                f"{', '.join(repr(p) for p in prefixes)}."
            )
            extra = _left_out_note(topic, left)
            return ChainOrder(tuple(picked), "prefix", left, note + (f" {extra}" if extra else ""))
        if numbered is None:
            raise JointNamesMismatchError(path, topic, found, chain, source)
    if numbered is not None and not in_chain_order:
        chain = [n for _, n in sorted(zip(numbered, found, strict=True))]
        said = f"{topic}'s joints taken in the order of their numbers ({', '.join(chain)})."
        return ChainOrder(tuple(chain), "number", (), None if chain == found else said)
    return ChainOrder(tuple(found), "order")


def _left_out_note(topic: str, left: Sequence[str]) -> str | None:
    if not left:
        return None
    return (
        f"{topic} also carries {len(left)} joint(s) the nominal does not have "
        f"({', '.join(left)}: a gripper's, another arm's?); they were left out."
    )
