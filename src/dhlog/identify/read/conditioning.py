"""How well the samples condition the DH model, for the reader: the table with the rows of
nearly parallel pairs in the Hayati–Mirmirani form (:class:`Conditioned`, with σ and the nominal
in the same form), the parameter pairs correlated beyond :data:`CORRELATION_WARNING`, and what
the poses leave undetermined or weakly determined (the scaled Jacobian's condition number)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.read.extract import Extraction, hayati_table
from dhlog.identify.read.hayati import NEAR_PARALLEL, table_in_hayati_form
from dhlog.identify.read.propagate import NOT_DETERMINED, state_names
from dhlog.model.dh import StandardDH

#: Correlations beyond this between free parameters are reported.
CORRELATION_WARNING = 0.95


@dataclass(frozen=True, eq=False)
class Conditioned:
    """The result's table with the rows of nearly parallel pairs in the Hayati–Mirmirani form
    (a :class:`HayatiDH`: β in place of the ill-conditioned d, same forward kinematics), each
    entry's σ (NaN where fixed, per row θ, d or β, a, α), why fixed entries are held, and the
    nominal in the same form (None without a nominal, or when it has no such form)."""

    table: StandardDH
    std: FloatArray
    fixed: dict[int, str]
    nominal: StandardDH | None


#: A condition number of the scaled Jacobian above this is worth a note naming the weakest
#: direction.
CONDITION_NOTE = 1e3


def nominal_rows(
    nominal: StandardDH | None, ref: FloatArray, rows: frozenset[int]
) -> StandardDH | None:
    """The nominal with ``rows`` in the Hayati–Mirmirani form (None without rows or nominal, or
    where the nominal's own axes have no such form: perpendicular there)."""
    if nominal is None or not rows:
        return None
    try:
        return table_in_hayati_form(nominal, ref, rows)
    except DhlogError:
        return None


def conditioned(
    ex: Extraction,
    rows: frozenset[int],
    nominal_rows: StandardDH | None,
    std: FloatArray,
    fixed: NDArray[np.bool_],
    reasons: dict[int, str],
    undetermined: NDArray[np.bool_] | None = None,
) -> Conditioned:
    """The table in the Hayati form with its σ; fixed entries keep the standard table's reason
    (``reasons``) where the row is the standard one, are not determined by the poses where
    ``undetermined`` says so, and are held by a convention elsewhere."""
    table = hayati_table(ex, rows, nominal_rows)
    held = {
        int(k): NOT_DETERMINED
        if undetermined is not None and undetermined[k]
        else reasons.get(int(k), "held by a convention of the extraction")
        for k in np.flatnonzero(fixed)
    }
    return Conditioned(table, np.where(fixed, np.nan, std), held, nominal_rows)


def near_parallel_pairs(ex: Extraction) -> list[tuple[int, int]]:
    out = []
    for rel in ex.relations:
        angle = min(rel.relation.angle, math.pi - rel.relation.angle)
        if angle < NEAR_PARALLEL:
            out.append(rel.joints)
    return out


def correlation_notes(cov: FloatArray, fixed: NDArray[np.bool_], n: int) -> tuple[Note, ...]:
    """One note (``correlated``) naming the free parameter pairs correlated beyond
    ``CORRELATION_WARNING``."""
    free = np.flatnonzero(~fixed)
    sd = np.sqrt(np.diag(cov)[free])
    ok = sd > 0
    free, sd = free[ok], sd[ok]
    corr = cov[np.ix_(free, free)] / np.outer(sd, sd)
    names = state_names(n)
    iu = np.triu_indices(free.size, 1)
    strong = np.abs(corr[iu]) > CORRELATION_WARNING
    if not np.any(strong):
        return ()
    order = np.argsort(-np.abs(corr[iu][strong]))
    pairs = [
        f"{names[free[iu[0][strong][k]]]}–{names[free[iu[1][strong][k]]]} "
        f"{corr[iu][strong][k]:+.3f}"
        for k in order[:4]
    ]
    more = int(np.count_nonzero(strong)) - len(pairs)
    said = (
        f"{int(np.count_nonzero(strong))} parameter pair(s) correlated beyond "
        f"{CORRELATION_WARNING}: {', '.join(pairs)}"
        + (f" and {more} more" if more > 0 else "")
        + " (full covariance in the JSON)."
    )
    return (Note.info(said, "correlated"),)


def identifiability_notes(whole: WholeFit, nominal: bool) -> tuple[Note, ...]:
    """What the poses determine: undetermined directions (a warning, ``undetermined``: held
    at the start, the parameters they move fixed, held at the nominal when ``nominal``), and
    the condition number with the weakest direction (a note, ``identifiability``)."""
    d = whole.determined
    if d is None:
        return ()
    notes: list[Note] = []
    names = whole.layout.names
    weakest = ", ".join(f"{c:+.2f} {k}" for k, c in d.weakest_terms(names))
    k = d.null.shape[1]
    if k:
        held = "the nominal" if nominal else "the start"
        said = (
            f"these poses do not determine {k} direction(s) of the model's {d.scale.size} "
            f"parameters: held at {held}, and the parameters they move are fixed (reason "
            f"'{NOT_DETERMINED}'); move every joint over more of its range, or alone."
        )
        notes.append(Note.warning(said, "undetermined"))
    if k or d.condition > CONDITION_NOTE:
        said = (
            f"identifiability: the scaled Jacobian's condition number is {d.condition:.3g}; "
            f"its weakest determined direction is {weakest}."
        )
        notes.append(Note.info(said, "identifiability"))
    return tuple(notes)
