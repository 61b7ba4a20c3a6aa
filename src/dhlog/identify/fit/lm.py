"""The one Levenberg–Marquardt loop of the whole-model fits (:func:`levenberg_marquardt`).

Every fit of the kinematic model — the tracker's streamed normal equations
(:mod:`dhlog.identify.fit.whole`) and any :class:`~dhlog.identify.fit.measure.Measurement`'s
(:mod:`dhlog.identify.fit.measure`: a point, a camera's pixels) — runs this loop over a state
that carries its normal equations ``H = JᵀWJ``, ``g = JᵀWr`` and its (truncated) cost; what a
state is, how it is evaluated at a step and how the step is solved within the determined
directions are the caller's. Damping starts at 1e-6, is divided by 10 on a step that lowers the
cost (to 1e-12 at least) and multiplied by 10 on one that does not (the fit stops beyond 1e8).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, TypeVar

import numpy as np

from dhlog.geometry._checks import FloatArray

#: Damping at the start, its floor and the ceiling at which the fit gives up moving.
LAMBDA_START, LAMBDA_MIN, LAMBDA_MAX = 1e-6, 1e-12, 1e8
#: A step is taken when the cost does not rise by more than this fraction of it, and the fit
#: has converged when it falls by less.
RELATIVE = 1e-12


class State(Protocol):
    """A point of the fit with its normal equations and cost."""

    @property
    def H(self) -> FloatArray: ...

    @property
    def g(self) -> FloatArray: ...

    @property
    def cost(self) -> float: ...


S = TypeVar("S", bound=State)


def levenberg_marquardt(
    state: S,
    *,
    solve: Callable[[FloatArray, FloatArray, float], FloatArray],
    trial: Callable[[S, FloatArray], S],
    settle: Callable[[S, FloatArray], S],
    small: float,
    floor: float,
    max_iterations: int,
    progress: Callable[[int], None] | None = None,
) -> tuple[S, int]:
    """Levenberg–Marquardt from ``state``: ``solve(H, g, λ)`` the damped step, ``trial(state,
    δ)`` the state evaluated at the step, ``settle(state, δ)`` the state after a last step whose
    expected decrease ``−gᵀδ`` is below ``small`` (the fit has converged; a caller may keep its
    normal equations, equal to first order); ``floor`` the smallest cost the relative test
    scales by. ``progress(iteration)`` is told each iteration. Returns the final state and the
    iterations run."""
    lam = LAMBDA_START
    it = 0
    while it < max_iterations:
        it += 1
        if progress is not None:
            progress(it)
        try:
            delta = solve(state.H, state.g, lam)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        if float(-(state.g @ delta)) < small:
            return settle(state, delta), it
        moved = trial(state, delta)
        if moved.cost <= state.cost + RELATIVE * max(state.cost, floor):
            converged = state.cost - moved.cost < RELATIVE * state.cost
            state = moved
            lam = max(lam / 10.0, LAMBDA_MIN)
            if converged:
                break
        else:
            lam *= 10.0
            if lam > LAMBDA_MAX:
                break
    return state, it
