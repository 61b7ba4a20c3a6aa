"""The fast path's bulk decode, chunk by chunk while the MCAP walk runs, so that no channel's
payloads are ever all held: each chunk's PointStamped, PoseStamped, PoseWithCovarianceStamped
and JointState messages are decoded at once into numpy columns (grown in place), and the chunk's
bytes are dropped. The result is what :func:`dhlog.io.decode.blocks.bulk_decode` gives on the
whole channel's payloads, block for block.

A channel is decoded so only where that is certain: its definition met before its first chunk,
a bulk layout planned for it (``plan``), payloads not compressed one by one. Others are left to
the walk (their payloads kept, decoded later). A channel whose messages turn out not to fit the
bulk decode part-way (big-endian, a payload that lies about its layout) is ``refused``: its
columns are dropped and the reader reads its payloads again.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from dhlog.io import ros2
from dhlog.io.decode.blocks import BULK_ERRORS, Block, bulk_decode, bulk_layout
from dhlog.io.mcapscan import ZSTD_MAGIC
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.pipeline import Pipeline
from dhlog.io.scratch import Growing

#: What ``plan`` answers for a channel no stream reads: its messages are dropped unread.
SKIP = "skip"
#: The bulk layout (``blocks.BULK_LAYOUTS``) to decode a channel's messages as, ``SKIP``, or
#: None to leave them to the walk.
Plan = Callable[[ChannelInfo], str | None]


class _Group:
    """One block's columns: times and one column per value (point coordinates, or a joint-state
    layout's positions)."""

    def __init__(self, width: int, order: tuple[int, int, int] = (0, 0, 0)) -> None:
        self.t = Growing(np.int64)
        self.values = [Growing(np.float64) for _ in range(width)]
        #: where the block's first message is: (payload length, offer, index in the offer)
        self.order = order

    def add(self, t: NDArray[np.int64], values: NDArray[np.float64]) -> None:
        self.t.extend(t)
        for j, column in enumerate(self.values):
            column.extend(values[:, j])

    def done(self) -> tuple[NDArray[np.int64], tuple[NDArray[np.float64], ...]]:
        return self.t.done(), tuple(column.done() for column in self.values)


class _Decoded:
    """A channel's columns: one group for points; for joint states one group per layout, keyed
    by (payload length, the bytes that fix the layout), with the layout's names."""

    def __init__(self, info: ChannelInfo, layout: str) -> None:
        self.info, self.layout = info, layout
        self.groups: dict[tuple[int, bytes], tuple[list[str], _Group]] = {}
        self.offers = 0

    def add(self, raw: RawMessages) -> None:
        """Decode one offer's messages (one of ``BULK_ERRORS`` where they do not fit)."""
        if np.any(raw.lengths < 16) or not np.all(ros2.little_endian(raw)):
            raise ValueError("a payload too short for its type, or big-endian")
        if self.layout == "joints":
            for g in ros2.joint_state_groups(raw):
                if g.width > g.length:  # the positions run past the payload
                    raise ValueError("JointState payload shorter than its layout")
                key = (g.length, g.layout)
                if key not in self.groups:
                    order = (g.length, self.offers, g.first)
                    self.groups[key] = (g.names, _Group(len(g.names), order))
                self.groups[key][1].add(g.stamps, g.positions)
        else:
            ((t, values),) = bulk_decode(self.layout, raw)
            if not self.groups:
                self.groups[(0, b"")] = ([], _Group(values.shape[1]))
            self.groups[(0, b"")][1].add(t, values)
        self.offers += 1

    def blocks(self) -> list[Block]:
        """The blocks :func:`bulk_decode` gives on the channel's payloads, with each block's
        values as a tuple of columns. Joint-state layouts are in the order it finds them: by
        payload length when lengths differ, then by first message."""
        out: list[Block] = []
        for names, group in sorted(self.groups.values(), key=lambda ng: ng[1].order):
            t, columns = group.done()
            out.append((t, (names, columns)) if self.layout == "joints" else (t, columns))
        self.groups.clear()
        return out


class ColumnSink:
    """The walk's sink (:data:`dhlog.io.mcapwalk.Sink`) on the fast path: takes the messages
    of every channel ``plan`` gives a bulk layout (decoded at once) or ``SKIP`` (dropped)."""

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        #: per channel: its columns, or None when left to the walk (its payloads kept)
        self.channels: dict[int, _Decoded | None] = {}
        self.skipped: set[int] = set()
        #: channels whose messages did not fit the bulk decode part-way
        self.refused: set[int] = set()

    def __call__(self, cid: int, info: ChannelInfo | None, raw: RawMessages) -> bool:
        if cid not in self.channels and cid not in self.skipped:
            layout = self.plan(info) if info is not None else None
            if layout == SKIP:
                self.skipped.add(cid)
            # payloads compressed one by one are left to the reader (it decompresses them)
            elif layout is None or raw.payload(0)[:4] == ZSTD_MAGIC:
                self.channels[cid] = None
            else:
                assert info is not None
                self.channels[cid] = _Decoded(info, layout)
        if cid in self.skipped or cid in self.refused:
            return True
        decoded = self.channels[cid]
        if decoded is None:
            return False
        try:
            decoded.add(raw)
        except BULK_ERRORS:
            self.refused.add(cid)
            self.channels[cid] = None
        return True

    def decoded(self, cid: int) -> tuple[ChannelInfo, str] | None:
        """The definition and layout a channel was decoded with; None when its payloads were
        kept by the walk, or were not read at all (skipped, refused)."""
        decoded = self.channels.get(cid)
        return None if decoded is None else (decoded.info, decoded.layout)

    def blocks(self, cid: int) -> list[Block]:
        """The channel's blocks (once: its columns are handed over)."""
        decoded = self.channels.pop(cid)
        assert decoded is not None
        return decoded.blocks()


def layout_plan(pipelines: Sequence[Pipeline]) -> Plan:
    """The plan for the streams of ``pipelines`` (the one given, or every shipped one while the
    reader has still to choose): a channel's bulk layout where the streams reading its topic
    agree on one, None where they do not (or read it message by message), ``SKIP`` where none
    reads it."""

    def plan(info: ChannelInfo) -> str | None:
        layouts = set()
        for pipeline in pipelines:
            if pipeline.is_camera:  # no tracker streams to lay out
                continue
            orientation = pipeline.streams["point"].orientation
            for stream, spec in pipeline.streams.items():
                if info.topic in (spec.topic, *spec.extra_topics):
                    layouts.add(bulk_layout(stream, info, spec.fields, orientation))
        if not layouts:
            return SKIP
        return layouts.pop() if len(layouts) == 1 else None

    return plan
