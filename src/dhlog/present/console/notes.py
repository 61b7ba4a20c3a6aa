"""The labelled lines under the console tables and in the Markdown: how the table was found
(:func:`method_line`), the clock offset (:func:`clock_line`), what is held by convention or
gauge (:func:`held_lines`), and their printing with notes and warnings (:func:`prose`)."""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from dhlog.identify.run import Identification
from dhlog.identify.segment.clocks import COARSE_STEP
from dhlog.identify.segment.timing import STOPS, pace, set_by
from dhlog.present.console.layout import literal
from dhlog.result.document import DisplayRow


def held_lines(result: Identification, rows: list[DisplayRow]) -> list[str]:
    """One line per reason: the parameters held by it (the names of the shown ``rows``)."""
    fixed = result.conditioned.fixed if result.conditioned is not None else result.fixed
    if not fixed or result.extraction is None:
        return []
    n = result.extraction.standard.n
    by_reason: dict[str, list[str]] = {}
    for idx in sorted(fixed):
        if idx < 4 * n:
            row, p = divmod(idx, 4)
            hayati = row < len(rows) and rows[row].form == "hayati"
            name = ("θ", "β" if hayati else "d", "a", "α")[p] + str(row + 1)
        else:
            name = (
                "tool " + "xyz"[idx - 4 * n]
                if idx < 4 * n + 3
                else "base " + ("x", "y", "z", "rx", "ry", "rz")[min(idx - 4 * n - 3, 5)]
            )
        by_reason.setdefault(fixed[idx], []).append(name)
    return [f"{', '.join(names)}: {why}" for why, names in by_reason.items()]


def clock_line(result: Identification) -> str:
    """The clock offset of the joint states against the tracker, and where it comes from."""
    t = result.timing
    if t is None:
        return ""
    ms = f"{t.offset * 1e3:+.4f} ms"
    if t.source == "estimated" and t.std is not None:
        drift = (
            f" at the sweeps' mean time, their clock running {pace(t.drift)} (mapped)"
            if t.drift
            else ""
        )
        if t.step:
            drift += (
                f", their clock {set_by(t.step)} mid-session (the stamps after it moved by that)"
            )
        return (
            f"joint-state stamps {ms} ± {t.std * 1e3:.4f} ms onto the tracker's clock{drift} "
            f"(estimated from the data; the pipeline's clock_offset: {t.pipeline * 1e3:+.4f} ms)"
        )
    if t.reason == STOPS:  # found at the stops' edges, no σ
        drift = f" at the stops' mean time, their clock running {pace(t.drift)} (mapped)"
        return (
            f"joint-state stamps {ms} onto the tracker's clock{drift if t.drift else ''} "
            "(step-and-measure: found where the first fit misses the samples at the stops' "
            f"edges least; the pipeline's clock_offset: {t.pipeline * 1e3:+.4f} ms)"
        )
    why = {
        "fixed": "clock_offset_fixed in the pipeline",
        "step-and-measure": "not estimated: samples taken while still (step-and-measure)",
    }.get(t.reason, t.reason)
    if t.coarse:  # matched where each stream moves, then no finer estimate
        return (
            f"joint-state stamps {ms} onto the tracker's clock (matched where each stream "
            f"moves, to about a step of {COARSE_STEP * 1e3:g} ms or the tracker's interval; "
            "the pipeline's clock_offset: "
            f"{t.pipeline * 1e3:+.4f} ms; {why.replace('not estimated', 'not estimated finer')})"
        )
    return f"joint-state stamps {ms} (the pipeline's clock_offset; {why})"


def method_line(result: Identification, length: float, lu: str) -> str:
    """How the table was found: the whole-model fit (samples, noise model, χ²/dof) or the seed
    method."""
    w = result.whole
    if w is None:
        return "the seed method (per-joint fits + line geometry)"
    noise = result.noise.described
    if result.noise.model == "isotropic" and result.sigma is not None:
        noise = f"isotropic, σ {result.sigma * length:.4f} {lu} per coordinate"
    return (
        f"whole-model maximum likelihood over {w.n_points} samples; noise {noise}, "
        f"χ²/dof {w.chi2_dof:.2f}"
    )


def prose(console: Console, lines: list[tuple[str, str]], *, markup: bool = False) -> None:
    """Labelled lines of text; long ones wrap under their text, not under the label."""
    if not lines:
        return
    grid = Table.grid(padding=(0, 1))
    grid.add_column(no_wrap=True)
    grid.add_column(overflow="fold")
    for label, text in lines:
        grid.add_row((label if markup else escape(label)) + ":", literal(text))
    console.print(grid)
