"""A vectorised MCAP record walk: channels, schemas and raw message payloads, per channel.

Top-level records are walked in Python (there are few: one chunk per megabyte or so); the message
records inside each chunk are located with numpy from the chunk's MessageIndex records, so no
Python code runs per message. Chunks without index (a file cut short after the chunk) are walked
record by record. A file cut short inside a record keeps everything before the damage and says how
many messages were recovered.

Record layout (MCAP specification): ``opcode u8, length u64, body``; strings are ``u32 length +
bytes``; a Message body is ``channel_id u16, sequence u32, log_time u64, publish_time u64, data``.
"""

from __future__ import annotations

import os
import struct
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, NotMcapError

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


@dataclass
class McapScan:
    """What a walk of an MCAP file found."""

    path: str
    channels: dict[int, ChannelInfo]
    messages: dict[int, RawMessages]
    metadata_names: list[str]
    profile: str = ""
    truncated_at: int | None = None
    recovered: int = 0
    warnings: list[str] = field(default_factory=list)
    #: the file's length in bytes (decompressed, for a ``.mcap.zstd``)
    size: int = 0
    #: the damaged records and chunks skipped, each with its byte offset and what was wrong
    damaged: list[str] = field(default_factory=list)

    def topics(self) -> list[str]:
        """Topics present, sorted."""
        return sorted({c.topic for c in self.channels.values()})


class _DamagedError(Exception):
    """A record whose fields lie about its own layout."""


#: A chunk may claim at most this many times its compressed size uncompressed (zstd and lz4
#: reach about 250x on runs of zeros), and at most this many bytes: a size that lies must not
#: make the reader allocate it.
MAX_RATIO = 1000
MAX_CHUNK = 2**31


def _string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, pos)
    if pos + 4 + n > len(buf):
        raise _DamagedError(f"a string of {n} bytes runs past its record")
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


class _Walker:
    def __init__(self, path: str, wanted: set[str] | None) -> None:
        self.path = path
        self.wanted = wanted
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
        except (struct.error, _DamagedError, ValueError) as exc:
            self.damage(where or f"a record (opcode {op})", exc)

    def _record(self, op: int, body: bytes | memoryview) -> None:
        if op == OP_SCHEMA:
            (sid,) = struct.unpack_from("<H", body, 0)
            name, pos = _string(body, 2)
            encoding, pos = _string(body, pos)
            (n,) = struct.unpack_from("<I", body, pos)
            self.schemas[sid] = (name, encoding, bytes(body[pos + 4 : pos + 4 + n]))
            self._resolve_channels()
        elif op == OP_CHANNEL:
            cid, sid = struct.unpack_from("<HH", body, 0)
            topic, pos = _string(body, 4)
            encoding, pos = _string(body, pos)
            self.pending_channels[cid] = (topic, encoding, sid)
            self._resolve_channels()
        elif op == OP_METADATA:
            self.metadata.append(_string(body, 0)[0])

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
        """Copy the payloads at ``starts`` (``lengths`` bytes each) of ``chunk`` to the end of
        channel ``cid``'s bytes."""
        data = self.data.setdefault(cid, bytearray())
        if starts.size == 0:
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
            data = self.data.setdefault(cid, bytearray())
            lengths = np.array([len(d) for _, d in loose], dtype=np.int64)
            starts = len(data) + np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
            self.parts.setdefault(cid, []).append(
                (starts, lengths, np.array([t for t, _ in loose], np.int64))
            )
            data += b"".join(d for _, d in loose)
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


def _decompress(compression: str, payload: bytes | memoryview, size: int, path: str) -> bytes:
    """The chunk's records, checked against the size it claims (``_DamagedError`` when they differ
    or the data is not what the compression says)."""
    if compression == "":
        out = bytes(payload)
    elif compression == "zstd":
        import zstandard

        try:
            # a frame that claims more content than the chunk does is refused by max_output_size
            out = zstandard.ZstdDecompressor().decompress(payload, max_output_size=size)
        except zstandard.ZstdError as exc:
            raise _DamagedError(f"zstd: {exc}") from None
    elif compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]

        try:
            with lz4.frame.LZ4FrameDecompressor() as d:
                out = bytes(d.decompress(payload, max_length=size + 1))
        except RuntimeError as exc:
            raise _DamagedError(f"lz4: {exc}") from None
    else:
        raise _DamagedError(f"compression '{compression[:40]}' is not supported (zstd, lz4)")
    if len(out) != size:
        raise _DamagedError(f"{len(out)} bytes where the chunk claims {size}")
    return out


ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
#: Chunks decompressed ahead of the walk, per worker thread.
IN_FLIGHT = 4


def _read(path: str | Path) -> bytes:
    """The file's bytes. (Mapped instead, a log cut short or failing to read while it is walked
    — another process truncating it, a network file system's error — ended the process with
    SIGBUS and no word; read, it is an error naming the file, or the part read.)"""
    try:
        return Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror}); check the path.") from None


def _unzstd_file(blob: bytes, name: str) -> bytes:
    """A whole zstd-compressed log, decompressed (at most MAX_RATIO times its size)."""
    import zstandard

    try:
        reader = zstandard.ZstdDecompressor().stream_reader(blob)
        out = reader.read(MAX_RATIO * len(blob) + 1)
    except zstandard.ZstdError as exc:
        raise InputError(f"{name}: a zstd file that cannot be decompressed ({exc}).") from None
    if len(out) > MAX_RATIO * len(blob):
        raise InputError(f"{name}: decompresses to more than {MAX_RATIO}x its size; damaged?")
    return out


def scan_mcap(
    path: str | Path,
    topics: Iterable[str] | None = None,
    progress: Callable[[float], None] | None = None,
) -> McapScan:
    """Walk ``path`` and return its channels and the raw payloads of ``topics`` (all if None).

    ``progress`` (optional) is called with the fraction of the work done."""
    name = str(path)
    blob = _read(path)
    if blob[:4] == ZSTD_MAGIC:  # a file-compressed log (rosbag2 --compression-mode file)
        blob = _unzstd_file(bytes(blob), name)
    if blob[: len(MAGIC)] != MAGIC:
        raise NotMcapError(name)
    walker = _Walker(name, set(topics) if topics is not None else None)
    view = memoryview(blob)
    pos, end = len(MAGIC), len(blob)
    profile = ""
    truncated_at: int | None = None
    pending: tuple[Future[bytes], dict[int, NDArray[np.uint64]], int] | None = None
    chunks: deque[tuple[Future[bytes], dict[int, NDArray[np.uint64]], int]] = deque()
    workers = os.cpu_count() or 1
    decompressed = ThreadPoolExecutor(max_workers=workers)
    done = 0

    def walk_oldest() -> None:
        """Walk the oldest decompressed chunk (its records dropped after: the chunks in
        flight are bounded, not the whole file's)."""
        nonlocal done
        future, index, at = chunks.popleft()
        try:
            records = future.result()
        except _DamagedError as exc:
            walker.damage(f"the chunk at byte {at}", exc)
        else:
            trusted = None if not index or -1 in index else index
            walker.chunk(np.frombuffer(records, dtype=np.uint8), trusted)
        done += 1
        if progress is not None and done % 16 == 0:
            progress(min(1.0, (chunks[0][2] if chunks else pos) / end))

    def flush() -> None:
        nonlocal pending
        if pending is not None:
            chunks.append(pending)
            pending = None
            if len(chunks) > IN_FLIGHT * workers:
                walk_oldest()

    while pos < end:
        if pos + 9 > end:
            truncated_at = pos
            break
        op = blob[pos]
        (length,) = struct.unpack_from("<Q", blob, pos + 1)
        body = pos + 9
        if body + length > end:
            truncated_at = pos
            break
        if op == OP_MESSAGE_INDEX and pending is not None:
            if length < 6:
                walker.damage(f"the message index at byte {pos}", "too short")
            else:
                (cid,) = struct.unpack_from("<H", blob, body)
                (n,) = struct.unpack_from("<I", blob, body + 2)
                if 6 + n > length:
                    walker.damage(f"the message index at byte {pos}", "runs past its record")
                    pending[1][-1] = np.zeros((0, 2), dtype=np.uint64)  # distrust the index
                else:
                    count = n // 16 * 2
                    pairs = np.frombuffer(blob, dtype="<u8", count=count, offset=body + 6)
                    pending[1][cid] = pairs.reshape(-1, 2)
        else:
            flush()
            if op == OP_HEADER:
                try:
                    profile = _string(view[: body + length], body)[0]
                except (struct.error, _DamagedError) as exc:
                    walker.damage(f"the header at byte {pos}", exc)
            elif op == OP_CHUNK:
                try:
                    record = view[: body + length]
                    _, _, size, _ = struct.unpack_from("<QQQI", record, body)
                    compression, p = _string(record, body + 28)
                    (n,) = struct.unpack_from("<Q", record, p)
                    if p + 8 + n > body + length:
                        raise _DamagedError(f"its records ({n} bytes) run past the chunk")
                    if size > min(MAX_CHUNK, MAX_RATIO * max(n, 1024)):
                        raise _DamagedError(f"it claims {size} bytes uncompressed from {n}")
                except (struct.error, _DamagedError) as exc:
                    walker.damage(f"the chunk at byte {pos}", exc)
                else:
                    pending = (
                        decompressed.submit(
                            _decompress, compression, view[p + 8 : p + 8 + n], size, name
                        ),
                        {},
                        pos,
                    )
            elif op == OP_MESSAGE:
                if length < 22:
                    walker.damage(f"the message at byte {pos}", "too short")
                    pos = body + length
                    continue
                cid, _, log_time = struct.unpack_from("<HIQ", blob, body)
                walker.count += 1
                if log_time >= 2**63:
                    walker.damage(f"the message at byte {pos}", "log time too large")
                    pos = body + length
                    continue
                if walker.keep(cid):
                    data = blob[body + 22 : body + length]
                    walker.loose.setdefault(cid, []).append((log_time, data))
            elif op in (OP_DATA_END, OP_FOOTER):
                break
            else:
                walker.record(op, view[body : body + length], f"a record at byte {pos}")
        pos = body + length
    flush()
    with decompressed:
        while chunks:
            walk_oldest()
    scan = McapScan(
        path=name,
        channels=dict(walker.channels),
        messages=walker.result(),
        metadata_names=walker.metadata,
        profile=profile,
        truncated_at=truncated_at,
        recovered=walker.count,
        size=end,
        damaged=list(walker.damaged),
    )
    if truncated_at is not None:
        scan.warnings.append(
            f"{name}: the file is cut short (or a record's length lies) at byte {truncated_at} "
            f"of {end}; recovered the {walker.count} message(s) before the damage."
        )
    if walker.damaged:
        more = f" and {len(walker.damaged) - 1} more" if len(walker.damaged) > 1 else ""
        scan.warnings.append(
            f"{name}: {len(walker.damaged)} damaged record(s) skipped: {walker.damaged[0]}{more}."
        )
    return scan
