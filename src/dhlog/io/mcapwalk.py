"""The walk of MCAP records: channels and schemas as they are defined, and each chunk's
messages located with numpy from the chunk's MessageIndex records, so no Python code runs per
message (a chunk without a trustworthy index is walked record by record). The wanted messages'
payloads are offered to a sink (which may decode and drop them) or copied out, per channel. The
file's top-level records are read by :mod:`dhlog.io.mcapscan`.

Record layout (MCAP specification): ``opcode u8, length u64, body``; strings are ``u32 length +
bytes``; a Message body is ``channel_id u16, sequence u32, log_time u64, publish_time u64, data``.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX = range(1, 8)
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_MESSAGE_HEADER = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, log, publish

U8 = NDArray[np.uint8]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class ChannelInfo:
    """A channel and its schema."""

    id: int
    topic: str
    message_encoding: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes


@dataclass
class RawMessages:
    """Payloads of one channel: ``data[starts[i] : starts[i] + lengths[i]]`` is message i."""

    data: U8
    starts: I64
    lengths: I64
    log_time: I64

    def payload(self, i: int) -> bytes:
        """Message ``i``'s bytes."""
        s = int(self.starts[i])
        return self.data[s : s + int(self.lengths[i])].tobytes()

    def __len__(self) -> int:
        return int(self.starts.shape[0])


#: Offered the messages of one kept channel, a chunk's at a time in the order of the file (then
#: the messages outside chunks): the channel's id, its definition (None while the walk has not
#: met it) and the messages (a view of the chunk, valid during the call). True when it took
#: them: the walk then keeps none of their bytes. It answers the same for every offer of a
#: channel.
Sink = Callable[[int, ChannelInfo | None, RawMessages], bool]


class DamagedRecordError(Exception):
    """A record whose fields lie about its own layout."""


def read_string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    if pos + 4 + n > len(buf):
        raise DamagedRecordError(f"a string of {n} bytes runs past its record")
    return bytes(buf[pos + 4 : pos + 4 + n]).decode("utf-8", "replace"), pos + 4 + n


def gather(buf: U8, positions: NDArray[np.int64], width: int, dtype: str) -> NDArray[np.generic]:
    """Values of ``dtype`` (``width`` bytes, little-endian) at each byte position in ``buf``.

    Reads through a view of the buffer with one element starting at every byte (stride 1), so
    each value, aligned or not, is one fancy-index load.
    """
    if positions.size == 0:
        return np.zeros(0, dtype=dtype)
    every_byte = np.ndarray(
        shape=(buf.shape[0] - width + 1,), dtype=dtype, buffer=buf, offset=0, strides=(1,)
    )
    return np.asarray(every_byte[positions])


def gather_rows(buf: U8, positions: NDArray[np.int64], width: int) -> U8:
    """The ``width`` bytes starting at each position, as an (m, width) array (one row copy each)."""
    if positions.size == 0:
        return np.zeros((0, width), dtype=np.uint8)
    rows = np.ndarray(
        shape=(buf.shape[0] - width + 1, width), dtype=np.uint8, buffer=buf, strides=(1, 1)
    )
    return np.asarray(rows[positions])


def _located(chunk: U8, pairs: NDArray[np.uint64]) -> tuple[I64, I64] | None:
    """Offsets and lengths of the message records a MessageIndex names, or None when any of
    them lies (outside the chunk, too short, or not a message record)."""
    size = chunk.shape[0]
    if pairs.shape[0] and (size < _MESSAGE_HEADER or int(pairs[:, 1].max()) > size - 31):
        return None
    offsets = pairs[:, 1].astype(np.int64)
    lengths = np.asarray(gather(chunk, offsets + 1, 8, "<u8"), dtype=np.uint64)
    if np.any(lengths < 22) or np.any(lengths > size):
        return None
    lengths_i = lengths.astype(np.int64)
    kinds = np.asarray(gather(chunk, offsets, 1, "u1"), dtype=np.int64)
    if np.any(offsets + 9 + lengths_i > size) or np.any(kinds != OP_MESSAGE):
        return None
    return offsets, lengths_i


class Walker:
    """One walk's state: the schemas and channels met so far, the payloads kept per channel
    (those the sink did not take), the metadata names, the messages counted and the damage
    noted."""

    def __init__(self, path: str, wanted: set[str] | None, sink: Sink | None = None) -> None:
        self.path = path
        self.wanted = wanted
        self.sink = sink
        self.schemas: dict[int, tuple[str, str, bytes]] = {}
        self.channels: dict[int, ChannelInfo] = {}
        self.pending_channels: dict[int, tuple[str, str, int]] = {}
        #: per kept channel: its payloads' bytes (compacted chunk by chunk: a chunk itself is
        #: dropped once its wanted payloads are copied out) and (starts, lengths, log times)
        self.data: dict[int, bytearray] = {}
        self.parts: dict[int, list[tuple[I64, I64, I64]]] = {}
        self.loose: dict[int, list[tuple[int, bytes]]] = {}
        self.metadata: list[str] = []
        self.count = 0
        self.damaged: list[str] = []

    def damage(self, where: str, why: object) -> None:
        """Note a damaged record or chunk (skipped; the scan goes on)."""
        self.damaged.append(f"{where}: {why}")

    # records that can appear at top level or inside chunks
    def record(self, op: int, body: bytes | memoryview, where: str = "") -> None:
        try:
            self._record(op, body)
        except (struct.error, DamagedRecordError, ValueError) as exc:
            self.damage(where or f"a record (opcode {op})", exc)

    def _record(self, op: int, body: bytes | memoryview) -> None:
        if op == OP_SCHEMA:
            (sid,) = struct.unpack_from("<H", body, 0)
            name, pos = read_string(body, 2)
            encoding, pos = read_string(body, pos)
            (n,) = struct.unpack_from("<I", body, pos)
            self.schemas[sid] = (name, encoding, bytes(body[pos + 4 : pos + 4 + n]))
            self._resolve_channels()
        elif op == OP_CHANNEL:
            cid, sid = struct.unpack_from("<HH", body, 0)
            topic, pos = read_string(body, 4)
            encoding, pos = read_string(body, pos)
            self.pending_channels[cid] = (topic, encoding, sid)
            self._resolve_channels()
        elif op == OP_METADATA:
            self.metadata.append(read_string(body, 0)[0])

    def _resolve_channels(self) -> None:
        for cid, (topic, encoding, sid) in list(self.pending_channels.items()):
            if sid == 0 or sid in self.schemas:
                name, s_enc, s_data = self.schemas.get(sid, ("", "", b""))
                self.channels[cid] = ChannelInfo(cid, topic, encoding, name, s_enc, s_data)
                del self.pending_channels[cid]

    def keep(self, cid: int) -> bool:
        """Whether channel ``cid``'s messages are wanted; a channel not defined yet is kept for
        now (its definition may come after: in the summary of a file whose in-chunk channel
        records are lost) and judged in :meth:`result`."""
        if self.wanted is None:
            return True
        info = self.channels.get(cid)
        if info is None and cid not in self.pending_channels:
            return True
        topic = info.topic if info else self.pending_channels[cid][0]
        return topic in self.wanted

    def chunk(self, chunk: U8, index: dict[int, NDArray[np.uint64]] | None) -> None:
        """Locate the messages of a decompressed chunk via its MessageIndex records (one per
        channel: log times and offsets), or record by record when it has none."""
        if index is None:
            self._walk_chunk(chunk, 0, chunk.shape[0])
            return
        covered = 0
        found: list[tuple[int, I64, I64, I64]] = []
        for cid, pairs in index.items():
            located = _located(chunk, pairs)
            if located is None:  # the index lies: walk the chunk record by record instead
                self.chunk(chunk, None)
                return
            offsets, lengths = located
            covered += int(lengths.sum()) + 9 * offsets.size
            found.append((cid, offsets, lengths, pairs[:, 0].astype(np.int64)))
        self.count += sum(int(f[1].size) for f in found)
        if covered < chunk.shape[0]:
            # records between the indexed messages (schemas, channels) are read one by one
            offsets = np.sort(np.concatenate([f[1] for f in found]))
            lengths = gather(chunk, offsets + 1, 8, "<u8").astype(np.int64)
            gap_starts = np.concatenate([[0], offsets + 9 + lengths])
            gap_ends = np.concatenate([offsets, [chunk.shape[0]]])
            has_gap = gap_ends > gap_starts
            for begin, stop in zip(gap_starts[has_gap], gap_ends[has_gap], strict=True):
                self._walk_chunk(chunk, int(begin), int(stop))
        for cid, offsets, lengths, log_times in found:
            if self.keep(cid):
                self._keep(cid, chunk, offsets + _MESSAGE_HEADER, lengths - 22, log_times)

    def _keep(self, cid: int, chunk: U8, starts: I64, lengths: I64, log_times: I64) -> None:
        """Offer the payloads at ``starts`` (``lengths`` bytes each) of ``chunk`` to the sink;
        those it does not take are copied to the end of channel ``cid``'s bytes."""
        data = self.data.setdefault(cid, bytearray())
        if starts.size == 0:
            return
        offered = RawMessages(chunk, starts, lengths, log_times)
        if self.sink is not None and self.sink(cid, self.channels.get(cid), offered):
            return
        ends = np.cumsum(lengths)
        width = int(lengths[0])
        if width > 0 and bool(np.all(lengths == width)):  # one layout: a row gather
            taken = gather_rows(chunk, starts, width).reshape(-1)
        else:  # every payload byte's place in the chunk: one gather for the chunk's messages
            shift = np.repeat(starts - (ends - lengths), lengths)
            taken = chunk[shift + np.arange(int(ends[-1]), dtype=np.int64)]
        self.parts.setdefault(cid, []).append((len(data) + ends - lengths, lengths, log_times))
        data += taken.data

    def _walk_chunk(self, chunk: U8, begin: int, stop: int) -> None:
        """The records of ``chunk[begin:stop]`` one by one."""
        buf = memoryview(chunk.data)[:stop]
        pos = begin
        starts: dict[int, list[int]] = {}
        lens: dict[int, list[int]] = {}
        times: dict[int, list[int]] = {}
        while pos + 9 <= len(buf):
            op = buf[pos]
            (length,) = struct.unpack_from("<Q", buf, pos + 1)
            body_end = pos + 9 + length
            if body_end > len(buf):
                break
            if op == OP_MESSAGE:
                if length < 22:
                    self.damage(f"a message record at byte {pos} of a chunk", "too short")
                    pos = body_end
                    continue
                cid, _, log_time = struct.unpack_from("<HIQ", buf, pos + 9)
                self.count += 1
                if log_time >= 2**63:
                    self.damage(f"a message at byte {pos} of a chunk", "log time too large")
                    pos = body_end
                    continue
                if self.keep(cid):
                    starts.setdefault(cid, []).append(pos + _MESSAGE_HEADER)
                    lens.setdefault(cid, []).append(length - 22)
                    times.setdefault(cid, []).append(log_time)
            else:
                self.record(op, buf[pos + 9 : body_end], f"a record in a chunk at byte {pos}")
            pos = body_end
        for cid in starts:
            self._keep(
                cid,
                chunk,
                np.asarray(starts[cid], dtype=np.int64),
                np.asarray(lens[cid], dtype=np.int64),
                np.asarray(times[cid], dtype=np.int64),
            )

    def result(self) -> dict[int, RawMessages]:
        out: dict[int, RawMessages] = {}
        for cid, loose in self.loose.items():  # messages outside chunks: after the chunks' bytes
            lengths = np.array([len(d) for _, d in loose], dtype=np.int64)
            starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
            times = np.array([t for t, _ in loose], np.int64)
            joined = b"".join(d for _, d in loose)
            offered = RawMessages(np.frombuffer(joined, dtype=np.uint8), starts, lengths, times)
            if self.sink is not None and self.sink(cid, self.channels.get(cid), offered):
                continue
            data = self.data.setdefault(cid, bytearray())
            self.parts.setdefault(cid, []).append((len(data) + starts, lengths, times))
            data += joined
        for cid, parts in self.parts.items():
            defined = cid in self.channels or cid in self.pending_channels
            if self.wanted is not None and not (defined and self.keep(cid)):
                continue  # kept while its channel was unknown: not wanted, or never defined
            out[cid] = RawMessages(
                data=np.frombuffer(self.data.pop(cid), dtype=np.uint8),
                starts=np.concatenate([s for s, _, _ in parts]),
                lengths=np.concatenate([n for _, n, _ in parts]),
                log_time=np.concatenate([t for _, _, t in parts]),
            )
        return out
