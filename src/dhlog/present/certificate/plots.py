"""The certificate's plots as inline SVG (text as paths, ids prefixed): the held-out errors'
histogram (:func:`histogram_svg`), the per-joint residuals (:func:`residual_bars_svg`) and the
ISO 9283 test's poses (:func:`iso9283_svg`).
matplotlib is imported here only, and only when a plot is drawn (``dhlog report``)."""

from __future__ import annotations

import html
import io
import re
from typing import TYPE_CHECKING, Any

import numpy as np

from dhlog.present.certificate.shown import Check, JointResidual

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from dhlog.present.certificate.iso9283 import IsoPose

#: Colours of the nominal and the calibrated model in every plot.
NOMINAL_COLOUR, CALIBRATED_COLOUR, FIT_COLOUR = "#c8553d", "#2a6f97", "#6c757d"


def _figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    return fig


def _style(ax: Any) -> None:
    ax.spines[["top", "right"]].set_visible(False)
    ax.tick_params(labelsize=8)
    ax.grid(axis="y", color="#e4e7eb", linewidth=0.6)
    ax.set_axisbelow(True)


def _svg(fig: Figure, prefix: str, label: str) -> str:
    """``fig`` as inline SVG: text as paths (no fonts needed), no XML prolog, comments or
    metadata, every id prefixed (several plots share one page), scaled to its container."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "path", "svg.hashsalt": "dhlog"}):
        fig.savefig(
            buf,
            format="svg",
            metadata={"Date": None, "Creator": None, "Format": None, "Type": None},
        )
    text = buf.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(r"<!--.*?-->", "", text, flags=re.DOTALL)
    text = re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.DOTALL)
    text = re.sub(r'\bid="([^"]+)"', rf'id="{prefix}-\1"', text)
    text = re.sub(r"url\(#([^)]+)\)", rf"url(#{prefix}-\1)", text)
    text = re.sub(r'href="#([^"]+)"', rf'href="#{prefix}-\1"', text)
    text = re.sub(
        r'<svg ([^>]*?)width="[^"]*" height="[^"]*"',
        rf'<svg \1class="plot" role="img" aria-label="{html.escape(label, quote=True)}"',
        text,
        count=1,
    )
    return re.sub(r"\n\s*", "\n", text).strip()


def histogram_svg(check: Check, in_sample_rms: float | None, prefix: str) -> str | None:
    """Per-pose held-out errors of the nominal and the calibrated model (log-spaced bins), the
    in-sample FK RMS as a dashed line; None without per-pose errors."""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    if check.calibrated_errors is None:
        return None
    cal = np.asarray(check.calibrated_errors) * 1e3
    nom = None if check.nominal_errors is None else np.asarray(check.nominal_errors) * 1e3
    values = np.concatenate([cal, nom]) if nom is not None else cal
    positive = values[values > 0]
    if positive.size == 0:
        return None
    lo, hi = float(positive.min()) / 1.3, float(positive.max()) * 1.3
    bins = np.geomspace(lo, hi, 36).tolist()
    fig = _figure(10.6, 3.0)
    ax = fig.add_subplot()
    if nom is not None:
        ax.hist(np.maximum(nom, lo), bins, color=NOMINAL_COLOUR, alpha=0.8, label="nominal")
    ax.hist(np.maximum(cal, lo), bins, color=CALIBRATED_COLOUR, alpha=0.85, label="calibrated")
    if in_sample_rms is not None and in_sample_rms * 1e3 > lo:
        ax.axvline(
            in_sample_rms * 1e3,
            color=FIT_COLOUR,
            linestyle="--",
            linewidth=1.2,
            label="in-sample FK RMS",
        )
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("3-D error at a held-out pose [mm]", fontsize=9)
    ax.set_ylabel("poses", fontsize=9)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    _style(ax)
    ax.legend(frameon=False, fontsize=8, loc="upper center", ncols=3)
    ax.set_ylim(top=ax.get_ylim()[1] * 1.25)
    return _svg(fig, prefix, f"histogram of the held-out errors, {check.label}")


def residual_bars_svg(residuals: list[JointResidual], prefix: str) -> str | None:
    """Per joint: its own fit's RMS, and the RMS and max of the table's FK at its samples (µm);
    None when the result has none."""
    series = [
        ("fit RMS", [r.fit_rms for r in residuals], "#8fb8de"),
        ("FK RMS", [r.fk_rms for r in residuals], CALIBRATED_COLOUR),
        ("FK max", [r.fk_max for r in residuals], "#1b3a57"),
    ]
    series = [s for s in series if any(v is not None for v in s[1])]
    if not series:
        return None
    x = np.arange(len(residuals), dtype=np.float64)
    width = 0.8 / len(series)
    fig = _figure(10.6, 2.8)
    ax = fig.add_subplot()
    for k, (label, values, colour) in enumerate(series):
        heights = np.array([np.nan if v is None else v * 1e6 for v in values])
        ax.bar(x + (k - (len(series) - 1) / 2) * width, heights, width, color=colour, label=label)
    ax.set_xticks(x, [str(r.joint) for r in residuals])
    ax.set_xlabel("joint", fontsize=9)
    ax.set_ylabel("residual [µm]", fontsize=9)
    _style(ax)
    ax.legend(frameon=False, fontsize=8, loc="upper center", ncols=len(series))
    ax.set_ylim(top=ax.get_ylim()[1] * 1.2)
    return _svg(fig, prefix, "per-joint residuals")


#: The acceptance test's pose panels in a row of the plot.
PANELS_PER_ROW = 6


def iso9283_svg(poses: list[IsoPose], prefix: str) -> str | None:
    """The acceptance test's poses: with their attained positions, each pose's positions about
    their barycentre (base x and y, µm) and the circle of radius RP; without, the bars of AP
    before and after and RP per pose (µm). None when there is nothing to draw."""
    if not poses:
        return None
    clusters = [p for p in poses if p.attained is not None and len(p.attained) >= 2]
    if clusters:  # at most six panels a row (a repeatability set of stops has dozens of poses)
        cols = min(len(clusters), PANELS_PER_ROW)
        rows = -(-len(clusters) // cols)
        fig = _figure(10.6, 2.6 * rows)
        grid = fig.subplots(rows, cols, squeeze=False)
        for ax in grid.ravel()[len(clusters) :]:
            ax.set_axis_off()
        axes = grid.ravel()[: len(clusters)]
        for ax, p in zip(axes, clusters, strict=True):
            assert p.attained is not None
            d = (p.attained - p.attained.mean(axis=0)) * 1e6
            ax.scatter(d[:, 0], d[:, 1], s=8, color=CALIBRATED_COLOUR, label="attained")
            ax.plot([0.0], [0.0], "+", color="#1b3a57", markersize=8)
            if p.RP is not None:
                t = np.linspace(0.0, 2 * np.pi, 181)
                r = p.RP * 1e6
                ax.plot(r * np.cos(t), r * np.sin(t), color=NOMINAL_COLOUR, linewidth=1.0)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_title(p.name, fontsize=9)
            ax.set_xlabel("x [µm]", fontsize=8)
            _style(ax)
        for ax in grid[:, 0]:
            ax.set_ylabel("y [µm]", fontsize=8)
        return _svg(fig, prefix, "attained positions of each test pose about their barycentre")
    series = [
        ("AP before", [p.AP_before for p in poses], NOMINAL_COLOUR),
        ("AP after", [p.AP_after for p in poses], CALIBRATED_COLOUR),
        ("RP", [p.RP for p in poses], FIT_COLOUR),
    ]
    series = [s for s in series if any(v is not None for v in s[1])]
    if not series:
        return None
    x = np.arange(len(poses), dtype=np.float64)
    width = 0.8 / len(series)
    fig = _figure(10.6, 2.6)
    ax = fig.add_subplot()
    for k, (label, values, colour) in enumerate(series):
        heights = np.array([np.nan if v is None else v * 1e6 for v in values])
        ax.bar(x + (k - (len(series) - 1) / 2) * width, heights, width, color=colour, label=label)
    ax.set_xticks(x, [p.name for p in poses])
    ax.set_ylabel("[µm]", fontsize=9)
    _style(ax)
    ax.legend(frameon=False, fontsize=8, loc="upper center", ncols=len(series))
    ax.set_ylim(top=ax.get_ylim()[1] * 1.2)
    return _svg(fig, prefix, "AP before and after calibration and RP per test pose")
