"""What reading a log gives: :class:`LogData`, its streams as polars tables in SI units."""

from __future__ import annotations

from dataclasses import dataclass, field

import polars as pl

from dhlog.io.jointnames import ChainOrder
from dhlog.io.pipeline import Pipeline


@dataclass
class LogData:
    """The decoded streams of one log, in SI units, sorted by time.

    ``points``/``base``: ``t_ns, x, y, z``; ``joints``: ``t_ns, q_1 … q_n`` in chain order
    (``joint_names``); ``phase``: ``t_ns, joint`` (1-based, null between sweeps);
    ``commanded``: the controller's commanded joints (``[streams.commanded]``, an ISO 9283
    test's), ``t_ns, q_1 … q_n`` as ``joints``, None where the log has no such stream.
    ``set_aside`` counts samples dropped on reading, by reason.
    """

    path: str
    pipeline: Pipeline
    points: pl.DataFrame
    joints: pl.DataFrame | None
    joint_names: list[str]
    base: pl.DataFrame | None
    phase: pl.DataFrame | None
    set_aside: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    pipeline_reason: str | None = None
    commanded: pl.DataFrame | None = None
    #: how the joint-state stream's joints were matched to the chain (None: no joint states,
    #: or not decided on reading: :func:`dhlog.io.jointnames.chain_order`)
    joint_order: ChainOrder | None = None
    #: the export's point ids by stamp (``dhlog import``'s ``dhlog.point_ids``), or None
    point_ids: dict[int, str] | None = None
    #: the joint states' clock set back mid-session (:mod:`dhlog.io.decode.setback`): their
    #: first stamp after it as logged, and the ns added to it and every one after; None: none
    clock_set_back: tuple[int, int] | None = None
