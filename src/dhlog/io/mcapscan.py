"""The MCAP file read record by record: its top-level records in Python (there are few: one
chunk per megabyte or so), each chunk decompressed in worker threads ahead of the walk
(:mod:`dhlog.io.mcapwalk`), which locates its messages with numpy. Neither the file nor the
payloads are held whole: a record's bytes are dropped once walked, and a sink may take the
messages as they come. A file cut short inside a record keeps everything before the damage and
says how many messages were recovered.
"""

from __future__ import annotations

import os
import re
import struct
from collections import deque
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, NotMcapError
from dhlog.io.mcapwalk import (
    MAGIC,
    OP_CHANNEL,
    OP_CHUNK,
    OP_DATA_END,
    OP_FOOTER,
    OP_HEADER,
    OP_MESSAGE,
    OP_MESSAGE_INDEX,
    OP_METADATA,
    OP_SCHEMA,
    ChannelInfo,
    DamagedRecordError,
    RawMessages,
    Sink,
    Walker,
    read_string,
)


@dataclass
class McapScan:
    """What a walk of an MCAP file found."""

    path: str
    channels: dict[int, ChannelInfo]
    #: per channel, the payloads kept (none of the channels a sink took)
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


#: A chunk may claim at most this many times its compressed size uncompressed (zstd and lz4
#: reach about 250x on runs of zeros), and at most this many bytes: a size that lies must not
#: make the reader allocate it.
MAX_RATIO = 1000
MAX_CHUNK = 2**31


def _decompress(compression: str, payload: bytes | memoryview, size: int, path: str) -> bytes:
    """The chunk's records, checked against the size it claims (``DamagedRecordError`` when they
    differ or the data is not what the compression says)."""
    if compression == "":
        out = bytes(payload)
    elif compression == "zstd":
        import zstandard

        try:
            # a frame that claims more content than the chunk does is refused by max_output_size
            out = zstandard.ZstdDecompressor().decompress(payload, max_output_size=size)
        except zstandard.ZstdError as exc:
            raise DamagedRecordError(f"zstd: {exc}") from None
    elif compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]

        try:
            with lz4.frame.LZ4FrameDecompressor() as d:
                out = bytes(d.decompress(payload, max_length=size + 1))
        except RuntimeError as exc:
            raise DamagedRecordError(f"lz4: {exc}") from None
    else:
        raise DamagedRecordError(f"compression '{compression[:40]}' is not supported (zstd, lz4)")
    if len(out) != size:
        raise DamagedRecordError(f"{len(out)} bytes where the chunk claims {size}")
    return out


ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
#: Chunks decompressed ahead of the walk, per worker thread.
IN_FLIGHT = 4
#: Bytes read from the file at a time (the records in them are read from memory).
READ_AHEAD = 1 << 20


def _unzstd_file(source: BinaryIO, compressed: int, name: str) -> tuple[BinaryIO, int]:
    """A zstd-compressed log, decompressed a block at a time into a scratch file (at most
    MAX_RATIO times its ``compressed`` size): the file, at its start, and its size."""
    import zstandard

    from dhlog.io import scratch

    limit = MAX_RATIO * compressed
    out = scratch.spool()
    total = 0
    try:
        with zstandard.ZstdDecompressor().stream_reader(source, closefd=False) as reader:
            while block := reader.read(READ_AHEAD):
                total += len(block)
                if total > limit:
                    raise InputError(
                        f"{name}: decompresses to more than {MAX_RATIO}x its size; damaged?"
                    )
                out.write(block)
        out.seek(0)
    except BaseException as exc:
        out.close()
        if isinstance(exc, zstandard.ZstdError):
            raise InputError(f"{name}: a zstd file that cannot be decompressed ({exc}).") from None
        raise
    return out, total


class _Log:
    """The log's bytes, read a block at a time as the walk goes, so the whole file is never
    held (a record's bytes are dropped once walked); a ``.mcap.zstd`` is decompressed first,
    a block at a time, into a scratch file read the same way. (Mapped
    instead, a log cut short or failing to read while it is walked — another process truncating
    it, a network file system's error — ended the process with SIGBUS and no word; read, it is
    an error naming the file, or the part read.)"""

    def __init__(self, path: str | Path) -> None:
        self.name = str(path)
        try:
            self.file: BinaryIO = open(path, "rb")
        except OSError as exc:
            raise self._unreadable(exc) from None
        try:
            self.size = os.fstat(self.file.fileno()).st_size
            self.at = 0
            if self.read(0, 4) == ZSTD_MAGIC:  # a file-compressed log (rosbag2 file mode)
                self.file.seek(0)
                logged, size = _unzstd_file(self.file, self.size, self.name)
                self.file.close()
                self.file, self.size, self.at = logged, size, 0
        except BaseException:
            self.file.close()
            raise

    def _unreadable(self, exc: OSError) -> InputError:
        return InputError(f"{self.name}: cannot be read ({exc.strerror}); check the path.")

    def read(self, pos: int, n: int) -> bytes:
        """Up to ``n`` bytes from ``pos`` (fewer where the file ends)."""
        try:
            if pos != self.at:
                self.file.seek(pos)
            data = self.file.read(n)
        except OSError as exc:
            raise self._unreadable(exc) from None
        self.at = pos + len(data)
        return data

    def close(self) -> None:
        self.file.close()


#: The records whose bodies the walk reads (the others are skipped unread).
_READ = frozenset(
    (OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX, OP_METADATA)
)


def _in_file(exc: Exception, base: int) -> Exception:
    """A record's parse error (its buffer read from byte ``base`` of the file) with its offsets
    and sizes counted from the file's start, as the rest of the walk's words on damage."""
    if not isinstance(exc, struct.error):
        return exc
    text = re.sub(
        r"(at least |offset |size is |for )(\d+)", lambda m: m[1] + str(int(m[2]) + base), str(exc)
    )
    return struct.error(text)


def scan_mcap(
    path: str | Path,
    topics: Iterable[str] | None = None,
    progress: Callable[[float], None] | None = None,
    sink: Sink | None = None,
) -> McapScan:
    """Walk ``path`` and return its channels and the raw payloads of ``topics`` (all if None).

    ``progress`` (optional) is called with the fraction of the work done; ``sink`` (optional) is
    offered each chunk's messages of every kept channel as the walk meets them (see ``Sink``):
    the payloads it takes are left out of the scan."""
    log = _Log(path)
    try:
        # the pool is shut down however the walk ends (a sink or progress that raises: its
        # worker threads do not outlive the call)
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            return _scan(log, set(topics) if topics is not None else None, progress, sink, pool)
    finally:
        log.close()


def _scan(
    log: _Log,
    wanted: set[str] | None,
    progress: Callable[[float], None] | None,
    sink: Sink | None,
    decompressed: ThreadPoolExecutor,
) -> McapScan:
    name = log.name
    if log.read(0, len(MAGIC)) != MAGIC:
        raise NotMcapError(name)
    walker = Walker(name, wanted, sink)
    pos, end = len(MAGIC), log.size
    profile = ""
    truncated_at: int | None = None
    pending: tuple[Future[bytes], dict[int, NDArray[np.uint64]], int] | None = None
    chunks: deque[tuple[Future[bytes], dict[int, NDArray[np.uint64]], int]] = deque()
    workers = os.cpu_count() or 1  # as many as the pool has
    done = 0

    def walk_oldest() -> None:
        """Walk the oldest decompressed chunk (its records dropped after: the chunks in
        flight are bounded, not the whole file's)."""
        nonlocal done
        future, index, at = chunks.popleft()
        try:
            records = future.result()
        except DamagedRecordError as exc:
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

    # the file's bytes from ``start``, read a block at a time: most records are read from it
    window, start, filled = b"", 0, 0
    while pos < end:
        off = pos - start
        if off + 9 > filled:
            if pos + 9 <= end:
                window, start, off = log.read(pos, READ_AHEAD), pos, 0
                filled = len(window)
            if off + 9 > filled:  # (or the file shrank while it was read)
                truncated_at = pos
                break
        op = window[off]
        (length,) = struct.unpack_from("<Q", window, off + 1)
        if pos + 9 + length > end:
            truncated_at = pos
            break
        # the record's body: blob[at:stop] (blob starts at byte pos + 9 - at of the file)
        blob, at, stop = window, off + 9, off + 9 + length
        if stop > filled and op in _READ:
            blob, at, stop = log.read(pos + 9, length), 0, length
            if len(blob) < length:  # the file shrank while it was read
                truncated_at = pos
                break
        if op == OP_MESSAGE_INDEX and pending is not None:
            if length < 6:
                walker.damage(f"the message index at byte {pos}", "too short")
            else:
                cid, n = struct.unpack_from("<HI", blob, at)
                if 6 + n > length:
                    walker.damage(f"the message index at byte {pos}", "runs past its record")
                    pending[1][-1] = np.zeros((0, 2), dtype=np.uint64)  # distrust the index
                else:
                    pairs = np.frombuffer(blob, dtype="<u8", count=n // 16 * 2, offset=at + 6)
                    pending[1][cid] = pairs.reshape(-1, 2)
        else:
            flush()
            if op == OP_HEADER:
                try:
                    profile = read_string(memoryview(blob)[:stop], at)[0]
                except (struct.error, DamagedRecordError) as exc:
                    walker.damage(f"the header at byte {pos}", _in_file(exc, pos + 9 - at))
            elif op == OP_CHUNK:
                try:
                    record = memoryview(blob)[:stop]
                    _, _, size, _ = struct.unpack_from("<QQQI", record, at)
                    compression, p = read_string(record, at + 28)
                    (n,) = struct.unpack_from("<Q", record, p)
                    if p + 8 + n > stop:
                        raise DamagedRecordError(f"its records ({n} bytes) run past the chunk")
                    if size > min(MAX_CHUNK, MAX_RATIO * max(n, 1024)):
                        raise DamagedRecordError(f"it claims {size} bytes uncompressed from {n}")
                except (struct.error, DamagedRecordError) as exc:
                    walker.damage(f"the chunk at byte {pos}", _in_file(exc, pos + 9 - at))
                else:
                    pending = (
                        decompressed.submit(
                            _decompress, compression, record[p + 8 : p + 8 + n], size, name
                        ),
                        {},
                        pos,
                    )
            elif op == OP_MESSAGE:
                if length < 22:
                    walker.damage(f"the message at byte {pos}", "too short")
                    pos += 9 + length
                    continue
                cid, _, log_time = struct.unpack_from("<HIQ", blob, at)
                walker.count += 1
                if log_time >= 2**63:
                    walker.damage(f"the message at byte {pos}", "log time too large")
                    pos += 9 + length
                    continue
                if walker.keep(cid):
                    walker.loose.setdefault(cid, []).append((log_time, blob[at + 22 : stop]))
            elif op in (OP_DATA_END, OP_FOOTER):
                break
            elif op in _READ:
                walker.record(op, memoryview(blob)[at:stop], f"a record at byte {pos}")
        pos += 9 + length
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
