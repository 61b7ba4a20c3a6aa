"""Several targets on the tool in one export (``dhlog import --targets mA,mB,mC``): each target's
position is a prefixed triple of columns (``mA_x_m, mA_y_m, mA_z_m``), read in its header's unit
as the primary target's is. The first prefix is the primary target (``/tracker/point``), each
further one goes to ``/tracker/point_2``, ``/tracker/point_3``, … at the same stamps, and the
log's ``dhlog.import`` record names their topics, so that ``dhlog process`` and ``dhlog
iso9283`` read them without a pipeline file (:func:`dhlog.io.reader.read_log`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dhlog.io.exports.layout import position_prefixes
from dhlog.io.exports.options import ImportOptions
from dhlog.io.exports.table import (
    DEFAULT_LENGTH_UNIT,
    LENGTH_UNITS,
    ConversionError,
    Table,
    column_unit,
    parse_header,
    stated_alike,
)

#: The topic of further target k (2, 3, …), as ``dhlog simulate --extra-targets`` writes it.
FURTHER_TOPIC = "/tracker/point_{k}"
#: The fewest and most targets ``--targets`` takes.
MAX_TARGETS = 16


def target_triples(table: Table, prefixes: list[str]) -> list[tuple[str, str, str]]:
    """The x, y, z columns (as written) of each prefix (``mA`` → ``mA_x_m, mA_y_m, mA_z_m``:
    the header's keys ``max``, ``may``, ``maz``); a prefix without its triple, or named twice,
    is refused naming the triples the header holds."""
    if len(prefixes) > MAX_TARGETS:
        raise ConversionError(
            table.path, f"--targets names {len(prefixes)} targets; at most {MAX_TARGETS}."
        )
    keys = [parse_header(p).key for p in prefixes]
    if len(set(keys)) != len(keys):
        twice = next(p for p, k in zip(prefixes, keys, strict=True) if keys.count(k) > 1)
        raise ConversionError(table.path, f"--targets names '{twice}' twice; name each once.")
    out = []
    for prefix, key in zip(prefixes, keys, strict=True):
        found = [table.key(key + a) for a in "xyz"]
        if any(k is None for k in found):
            held = ", ".join(position_prefixes(table)) or "none"
            raise ConversionError(
                table.path,
                f"--targets: no columns {prefix} x, y, z (keys {key}x, {key}y, {key}z); the "
                f"header's prefixed triples are: {held}; name them with --targets.",
            )
        x, y, z = (table.header[k] for k in found if k is not None)
        out.append((x, y, z))
    return out


def further_positions(
    table: Table, triples: list[tuple[str, str, str]], opts: ImportOptions
) -> NDArray[np.float64]:
    """The further targets' positions (k, m, 3) in m, each column in its header's unit (else
    ``--length-unit``, else mm), the three of a target stated alike."""
    out = np.empty((len(triples), len(table.rows), 3))
    for t, triple in enumerate(triples):
        ks = [
            table.column(c, f"target {t + 2}'s {a}", "--targets")
            for c, a in zip(triple, "xyz", strict=True)
        ]
        stated_alike(table, ks, "length", opts.length_unit, "coordinate")
        for c, k in enumerate(ks):
            unit = column_unit(table, k, "length", opts.length_unit, DEFAULT_LENGTH_UNIT)
            out[t, :, c] = (
                table.numbers(k, table.header[k], "is --targets the right prefix?")
                * LENGTH_UNITS[unit]
            )
            table.in_range(k, out[t, :, c], table.header[k], -1000.0, 1000.0, "m")
    return out


def further_topics(count: int) -> list[str]:
    """The topics of ``count`` further targets: ``/tracker/point_2``, …"""
    return [FURTHER_TOPIC.format(k=k + 2) for k in range(count)]
