"""A joint-state clock set back mid-session, as the stamps in the order logged show it.

A time daemon stepping the clock of the computer that stamps the joint states back (ntpd beyond
128 ms, chrony's ``makestep``, Windows' time service) leaves their stamps, in the order a
recorder wrote them, falling once by the step and rising on from there. Sorted by stamp, the
two stretches either side would interleave, and no later step could tell them apart again; so
the stamps from the fall on are moved to follow the last one before it at the stream's median
interval (:func:`unfolded`), and the log keeps what was added
(:attr:`dhlog.io.logdata.LogData.clock_set_back`) for the run to report. A stream whose stamps
fall in more than one place (two publishers on one topic), by an interval or two (messages
swapped), for one message only (one sent late) or from one stamp far ahead of the one before
(damage: :func:`~dhlog.io.decode.frames.clean` sets it aside) is sorted as before.
"""

from __future__ import annotations

import numpy as np
import polars as pl

#: A fall of the stamps is a clock set back when it is more than this many of the stream's
#: median intervals ...
SET_BACK_INTERVALS = 3.0
#: ... and more than this (ns): two messages swapped fall by an interval or two.
SET_BACK_FLOOR_NS = 1_000_000


def unfolded(frame: pl.DataFrame) -> tuple[pl.DataFrame, tuple[int, int] | None]:
    """``frame`` (``t_ns`` first, in the order logged) with its stamps from a single fall of
    more than :data:`SET_BACK_INTERVALS` median intervals and :data:`SET_BACK_FLOOR_NS`, the
    stamp after it still below the last before it, on moved to follow that one at the median
    interval, and (the first moved stamp as logged, ns added from it on); else ``frame`` as it
    is and None."""
    t = np.asarray(frame["t_ns"].to_numpy())
    if t.size < 3:
        return frame, None
    d = np.diff(t)
    fall = np.flatnonzero(d < 0)
    if fall.size != 1:
        return frame, None
    forward = d[d > 0]
    if forward.size == 0:
        return frame, None
    step = int(np.median(forward))
    k = int(fall[0]) + 1
    added = int(t[k - 1] - t[k]) + step
    if added <= max(SET_BACK_FLOOR_NS, SET_BACK_INTERVALS * step):
        return frame, None
    if k + 1 < t.size and t[k + 1] >= t[k - 1]:  # one message sent late, not a clock set back
        return frame, None
    if k >= 2 and not 0 < d[k - 2] <= SET_BACK_INTERVALS * step:  # one stamp damaged high
        return frame, None
    moved = frame.with_columns(
        pl.when(pl.int_range(pl.len()) >= k)
        .then(pl.col("t_ns") + added)
        .otherwise(pl.col("t_ns"))
        .alias("t_ns")
    )
    return moved, (int(t[k]), added)
