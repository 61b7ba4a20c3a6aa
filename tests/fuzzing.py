"""Seeded, structure-aware mutations of MCAP logs, and one run of ``dhlog process`` on each.

Shared by ``tests/test_fuzz.py`` (a few hundred cases in CI) and ``benchmarks/fuzz.py`` (long
runs). The logs start as small simulated sessions written by dhlog's writers (the mcap library's
writer; ROS 2 CDR as rosbag2 writes it, JSON and protobuf with the Foxglove schemas); the
mutations come in four families:

* ``bytes``: truncation, bit flips (anywhere, or in the header, a chunk, the summary, the
  footer), spans overwritten with random bytes or zeros, spans duplicated;
* ``records``: record lengths that lie, chunk compression names and sizes that lie, garbage
  compressed payloads, channel and schema ids that point nowhere, records dropped or doubled,
  message indexes that point outside their chunk;
* ``payloads``: message payloads rewritten inside their (recompressed) chunks: random bytes,
  CDR sequence lengths that lie, truncated or deeply nested JSON, invalid UTF-8;
* ``odd``: well-formed logs with odd content, written by the real writers: NaN/Inf samples,
  reversed and duplicated stamps, a year-long gap, joint names changing mid-log, no samples at
  all, phase markers naming joint 999999999 without joint states, coordinates of 1e300, one
  joint never moving.

:func:`run_case` runs the command in-process (Typer's runner) or as a subprocess and judges the
outcome: exit in {0, 2, 3}, no traceback, one line on stderr for 2 and 3, the input unchanged,
no partial output (every output complete, or none).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import random
import signal
import struct
import threading
import time
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 1, 2, 3, 4, 5, 6
OP_MESSAGE_INDEX, OP_DATA_END = 7, 15
FAMILIES = ("bytes", "records", "payloads", "odd")
ENCODINGS = ("ros2", "json", "protobuf")


@dataclass(frozen=True)
class Case:
    """One mutated log: its family, what was done, and the bytes."""

    family: str
    name: str
    data: bytes


@dataclass(frozen=True)
class Outcome:
    """How a command ended on a case, and what was wrong with it (empty: nothing); every fuzzer's
    (the logs', the inputs', the results') and the long runs' of ``benchmarks/fuzz.py``."""

    case: str
    family: str
    exit_code: int
    problems: tuple[str, ...]
    stderr: str
    seconds: float = 0.0


class Hang(BaseException):
    """The time limit of a case ran out (the input fuzzers' in-process runs)."""


@dataclass(frozen=True)
class Invoked:
    """How the app ended on one command line run in this process: exit code, standard output
    and error (a crash's traceback appended), seconds, whether it raised."""

    code: int
    stdout: str
    stderr: str
    seconds: float
    crashed: bool


def invoke(args: list[str], timeout: float) -> Invoked | None:
    """``dhlog ARGS`` through Typer's runner in this process, within ``timeout`` seconds (None:
    it hung)."""
    import traceback

    from typer.testing import CliRunner

    from dhlog.cli.app import app

    start = time.monotonic()
    try:
        with time_limit(timeout):
            result = CliRunner().invoke(app, args)
    except Hang:
        return None
    stderr = result.stderr
    crashed = result.exception is not None and not isinstance(result.exception, SystemExit)
    if crashed:
        stderr += "".join(traceback.format_exception(result.exception))
    return Invoked(result.exit_code, result.stdout, stderr, time.monotonic() - start, crashed)


def common_problems(
    ran: Invoked,
    before: dict[str, str],
    after: dict[str, str],
    *,
    codes: tuple[int, ...],
    refuse: bool,
) -> tuple[list[str], list[str]]:
    """What every input fuzzer holds a run to — no traceback, an exit code of ``codes``, a
    refusal where the case must be refused, its inputs unchanged (``before`` and ``after``: each
    file's fingerprint), nothing written on exit 2 — and the files it added."""
    problems: list[str] = []
    if ran.crashed or "Traceback" in ran.stderr or "Traceback" in ran.stdout:
        problems.append("traceback")
    if ran.code not in codes:
        problems.append(f"exit {ran.code}")
    if refuse and ran.code == 0:
        problems.append("accepted (exit 0) where it must be refused")
    changed = [n for n, h in before.items() if after.get(n) != h]
    if changed:
        problems.append(f"input changed: {changed}")
    new = sorted(set(after) - set(before))
    if ran.code == 2 and new:
        problems.append(f"output written on exit 2: {new}")
    return problems, new


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (elsewhere: no limit)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise Hang()

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# ---------------------------------------------------------------------------- base logs


def _session(seed: int, **kw: object):  # type: ignore[no-untyped-def]
    from dhlog.model.robots import load_robot
    from dhlog.simulator.config import SimulationConfig
    from dhlog.simulator.session import simulate_session

    cfg = SimulationConfig(
        seed=seed,
        sweep=math.radians(30.0),
        tracker_rate=20.0,
        joint_rate=50.0,
        dwell=0.1,
        base_points=4,
        **kw,  # type: ignore[arg-type]
    )
    return simulate_session(load_robot("kr5"), cfg)


def _write(session, encoding: str, path: Path) -> bytes:  # type: ignore[no-untyped-def]
    from dhlog.io.writer import write_session

    write_session(session, path, encoding)  # type: ignore[arg-type]
    return path.read_bytes()


def base_logs(folder: Path) -> dict[str, bytes]:
    """Small simulated KR5 sessions (about 700 target samples) in each encoding."""
    folder.mkdir(parents=True, exist_ok=True)
    session = _session(1)
    return {enc: _write(session, enc, folder / f"base_{enc}.mcap") for enc in ENCODINGS}


# ---------------------------------------------------------------------------- records


def records(data: bytes) -> list[tuple[int, int, int]]:
    """Top-level records ``(offset, opcode, body length)`` up to the data end (or damage)."""
    out, pos = [], len(MAGIC)
    while pos + 9 <= len(data):
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if pos + 9 + length > len(data):
            break
        out.append((pos, op, length))
        pos += 9 + length
        if op == OP_FOOTER:
            break
    return out


def _chunk_parts(data: bytes, pos: int) -> tuple[bytes, str, bytes, int, int]:
    """(fixed head, compression, compressed records, offset of the records' length, body end)."""
    body = pos + 9
    (length,) = struct.unpack_from("<Q", data, pos + 1)
    (n,) = struct.unpack_from("<I", data, body + 28)
    compression = data[body + 32 : body + 32 + n].decode()
    rec_len_at = body + 32 + n
    (m,) = struct.unpack_from("<Q", data, rec_len_at)
    payload = data[rec_len_at + 8 : rec_len_at + 8 + m]
    return data[body : body + 28], compression, payload, rec_len_at, body + length


def _decompress(compression: str, payload: bytes, size: int) -> bytes:
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdDecompressor().decompress(payload, max_output_size=size)
    if compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]

        return bytes(lz4.frame.decompress(payload))
    return payload


def _compress(compression: str, raw: bytes) -> bytes:
    if compression == "zstd":
        import zstandard

        return zstandard.ZstdCompressor().compress(raw)
    if compression == "lz4":
        import lz4.frame

        return bytes(lz4.frame.compress(raw))
    return raw


def _rebuild_chunk(data: bytes, pos: int, raw: bytes) -> bytes:
    """``data`` with the chunk at ``pos`` holding the (already mutated) uncompressed ``raw``."""
    head, compression, _, _, end = _chunk_parts(data, pos)
    start, stop = struct.unpack_from("<QQ", head, 0)
    packed = _compress(compression, raw)
    name = compression.encode()
    body = (
        struct.pack("<QQQI", start, stop, len(raw), zlib.crc32(raw))
        + struct.pack("<I", len(name))
        + name
        + struct.pack("<Q", len(packed))
        + packed
    )
    record = bytes([OP_CHUNK]) + struct.pack("<Q", len(body)) + body
    return data[:pos] + record + data[end:]


def _chunk_records(raw: bytes) -> list[tuple[int, int, int]]:
    return records(b"\0" * len(MAGIC) + raw)


def _chunks(data: bytes) -> list[int]:
    return [pos for pos, op, _ in records(data) if op == OP_CHUNK]


def _with_chunk(
    data: bytes, rng: random.Random, change: Callable[[bytearray, list[tuple[int, int, int]]], None]
) -> bytes:
    """``data`` with one random chunk's uncompressed records changed by ``change`` (offsets in
    the records list are into the uncompressed bytes, shifted by the magic's length)."""
    chunks = _chunks(data)
    if not chunks:
        return data
    pos = rng.choice(chunks)
    head, compression, payload, _, _ = _chunk_parts(data, pos)
    (size,) = struct.unpack_from("<Q", head, 16)
    raw = bytearray(_decompress(compression, payload, size))
    change(raw, [(p - len(MAGIC), op, n) for p, op, n in _chunk_records(bytes(raw))])
    return _rebuild_chunk(data, pos, bytes(raw))


# ---------------------------------------------------------------------------- families


def _bytes_case(data: bytes, rng: random.Random) -> tuple[str, bytes]:
    buf = bytearray(data)
    kind = rng.choice(["truncate", "flip", "flip_region", "overwrite", "zeros", "duplicate"])
    if kind == "truncate":
        cut = rng.randrange(len(MAGIC), len(buf))
        return f"truncate@{cut}", bytes(buf[:cut])
    if kind == "flip":
        k = rng.choice([1, 2, 8, 64])
        for _ in range(k):
            i = rng.randrange(len(buf))
            buf[i] ^= 1 << rng.randrange(8)
        return f"flip{k}", bytes(buf)
    if kind == "flip_region":
        recs = records(data)
        region = rng.choice(["header", "chunk", "summary", "footer"])
        if region == "header":
            lo, hi = 0, min(64, len(buf))
        elif region == "footer":
            lo, hi = max(0, len(buf) - 40), len(buf)
        elif region == "chunk" and _chunks(data):
            pos = rng.choice(_chunks(data))
            lo, hi = pos, pos + 9 + struct.unpack_from("<Q", data, pos + 1)[0]
        else:
            ends = [p for p, op, _ in recs if op == OP_DATA_END]
            lo, hi = (ends[0], len(buf)) if ends else (0, len(buf))
        for _ in range(rng.choice([1, 4, 16])):
            i = rng.randrange(lo, hi)
            buf[i] ^= 1 << rng.randrange(8)
        return f"flip_{region}", bytes(buf)
    start = rng.randrange(len(buf))
    span = rng.choice([1, 8, 64, 4096])
    if kind == "overwrite":
        buf[start : start + span] = rng.randbytes(min(span, len(buf) - start))
        return f"overwrite{span}@{start}", bytes(buf)
    if kind == "zeros":
        buf[start : start + span] = bytes(min(span, len(buf) - start))
        return f"zeros{span}@{start}", bytes(buf)
    return f"duplicate{span}@{start}", bytes(buf[: start + span] + buf[start:])


LIES = [0, 1, 7, 2**31, 2**32 + 5, 2**63, 2**64 - 1]


def _records_case(data: bytes, rng: random.Random) -> tuple[str, bytes]:
    recs = records(data)
    kind = rng.choice(
        [
            "length",
            "compression",
            "size",
            "payload",
            "channel_id",
            "schema_id",
            "drop",
            "double",
            "index",
            "records_length",
        ]
    )
    buf = bytearray(data)
    if kind == "length" and recs:
        pos, op, _ = rng.choice(recs)
        lie = rng.choice(LIES)
        struct.pack_into("<Q", buf, pos + 1, lie)
        return f"length_op{op}={lie}", bytes(buf)
    chunks = _chunks(data)
    if kind in ("compression", "size", "payload", "records_length") and chunks:
        pos = rng.choice(chunks)
        head, _, payload, rec_len_at, _ = _chunk_parts(data, pos)
        if kind == "compression":
            name = rng.choice(["lz4", "zstd", "gzip", "", "zstd" * 50]).encode()
            body = head + struct.pack("<I", len(name)) + name + data[rec_len_at : rec_len_at + 8]
            body += payload
            rec = bytes([OP_CHUNK]) + struct.pack("<Q", len(body)) + body
            end = rec_len_at + 8 + len(payload)
            return f"compression={name[:8]!r}", data[:pos] + rec + data[end:]
        if kind == "size":
            lie = rng.choice(LIES)
            struct.pack_into("<Q", buf, pos + 9 + 16, lie)
            return f"uncompressed_size={lie}", bytes(buf)
        if kind == "records_length":
            lie = rng.choice(LIES)
            struct.pack_into("<Q", buf, rec_len_at, lie)
            return f"records_length={lie}", bytes(buf)
        garbage = rng.randbytes(len(payload))
        buf[rec_len_at + 8 : rec_len_at + 8 + len(payload)] = garbage
        return "chunk_payload_garbage", bytes(buf)
    if kind == "channel_id":

        def recid(raw: bytearray, inner: list[tuple[int, int, int]]) -> None:
            msgs = [p for p, op, _ in inner if op == OP_MESSAGE]
            for p in rng.sample(msgs, min(len(msgs), rng.choice([1, 5, 50]))):
                struct.pack_into("<H", raw, p + 9, rng.choice([0, 77, 65535]))

        return "message_channel_nowhere", _with_chunk(data, rng, recid)
    if kind == "schema_id":
        chans = [(p, n) for p, op, n in recs if op == OP_CHANNEL]
        if not chans:

            def chan(raw: bytearray, inner: list[tuple[int, int, int]]) -> None:
                for p, op, _ in inner:
                    if op == OP_CHANNEL:
                        struct.pack_into("<H", raw, p + 11, rng.choice([0, 99, 65535]))

            return "channel_schema_nowhere_in_chunk", _with_chunk(data, rng, chan)
        pos, _ = rng.choice(chans)
        struct.pack_into("<H", buf, pos + 11, rng.choice([0, 99, 65535]))
        return "channel_schema_nowhere", bytes(buf)
    if kind in ("drop", "double") and recs:
        pos, op, n = rng.choice(recs[1:] or recs)
        rec = data[pos : pos + 9 + n]
        if kind == "drop":
            return f"drop_op{op}", data[:pos] + data[pos + 9 + n :]
        return f"double_op{op}", data[: pos + 9 + n] + rec + data[pos + 9 + n :]
    idx = [(p, n) for p, op, n in recs if op == OP_MESSAGE_INDEX]
    if idx:
        pos, n = rng.choice(idx)
        if n >= 6 + 16:
            struct.pack_into("<Q", buf, pos + 9 + 6 + 8, rng.choice(LIES))
        return "message_index_outside", bytes(buf)
    return "noop", data


def _payloads_case(data: bytes, rng: random.Random, encoding: str) -> tuple[str, bytes]:
    kind = rng.choice(["random", "length_lie", "truncate", "json_deep", "json_types", "utf8"])

    def change(raw: bytearray, inner: list[tuple[int, int, int]]) -> None:
        msgs = [(p, n) for p, op, n in inner if op == OP_MESSAGE]
        if not msgs:
            return
        for p, n in rng.sample(msgs, min(len(msgs), rng.choice([1, 3, 30]))):
            start, size = p + 9 + 22, n - 22
            if size <= 0:
                continue
            if kind == "random":
                raw[start : start + size] = rng.randbytes(size)
            elif kind == "length_lie" and size >= 8:
                at = start + 4 * rng.randrange(max(1, size // 4 - 1))
                struct.pack_into("<I", raw, at, rng.choice([2**31 - 1, 2**32 - 1, 1000000]))
            elif kind == "truncate":
                cut = rng.randrange(size)
                raw[start + cut : start + size] = b"\0" * (size - cut)
            elif kind == "json_deep":
                blob = (b"[" * size)[:size]
                raw[start : start + size] = blob
            elif kind == "json_types":
                blob = b'{"x": "abc", "y": [], "z": {}}'.ljust(size, b" ")[:size]
                raw[start : start + size] = blob
            else:
                raw[start : start + size] = b"\xff\xfe" * (size // 2) + b"\xff" * (size % 2)

    return f"{kind}", _with_chunk(data, rng, change)


def _odd_case(rng: random.Random, encoding: str, folder: Path) -> tuple[str, bytes]:
    kind = rng.choice(
        [
            "nan",
            "reversed",
            "duplicated",
            "year_gap",
            "no_points",
            "phase_999999999",
            "huge",
            "still",
            "renamed",
            "few",
        ]
    )
    seed = rng.randrange(1000)
    s = _session(seed, phase=kind == "phase_999999999")
    if kind == "nan":
        xyz = s.point_xyz.copy()
        idx = rng.sample(range(len(xyz)), 10)
        xyz[idx] = [np.nan, np.inf, -np.inf][rng.randrange(3)]
        s = dataclasses.replace(s, point_xyz=xyz)
    elif kind == "reversed":
        s = dataclasses.replace(s, point_t_ns=s.point_t_ns[::-1].copy())
    elif kind == "duplicated":
        t = s.point_t_ns.copy()
        t[1::2] = t[::2][: len(t[1::2])]
        s = dataclasses.replace(s, point_t_ns=t)
    elif kind == "year_gap":
        t, tj = s.point_t_ns.copy(), s.joint_t_ns.copy()
        gap = 365 * 86400 * 10**9
        mid = int(t[len(t) // 2])
        s = dataclasses.replace(
            s, point_t_ns=np.where(t > mid, t + gap, t), joint_t_ns=np.where(tj > mid, tj + gap, tj)
        )
    elif kind == "no_points":  # every chunk (and its indexes) dropped: channels, no messages
        path = folder / f"odd_{kind}_{encoding}_{seed}.mcap"
        data = _write(s, encoding, path)
        kept = [
            data[p : p + 9 + n]
            for p, op, n in records(data)
            if op not in (OP_CHUNK, OP_MESSAGE_INDEX, OP_MESSAGE)
        ]
        return kind, MAGIC + b"".join(kept) + MAGIC
    elif kind == "phase_999999999":
        s = dataclasses.replace(
            s,
            joint_t_ns=s.joint_t_ns[:0],
            joint_q=s.joint_q[:0],
            phase=[(t, 999999999 if j else None) for t, j in s.phase],
        )
    elif kind == "huge":
        xyz = s.point_xyz.copy()
        xyz[rng.randrange(len(xyz))] = 1e300
        s = dataclasses.replace(s, point_xyz=xyz)
    elif kind == "still":
        q = s.joint_q.copy()
        q[:, 2] = q[0, 2]
        s = dataclasses.replace(s, joint_q=q)
    elif kind == "renamed":
        names = list(s.joint_names)
        names[rng.randrange(len(names))] = "[bold]x[/bold]"
        s = dataclasses.replace(s, joint_names=names)
    else:
        keep = rng.choice([1, 2, 5])
        s = dataclasses.replace(s, point_t_ns=s.point_t_ns[:keep], point_xyz=s.point_xyz[:keep])
    path = folder / f"odd_{kind}_{encoding}_{seed}.mcap"
    try:
        return kind, _write(s, encoding, path)
    except Exception as exc:  # the writer refuses it: an odd log that cannot exist on disk
        return f"{kind}(unwritable: {type(exc).__name__})", b""


def cases(n: int, seed: int, folder: Path, families: tuple[str, ...] = FAMILIES) -> Iterator[Case]:
    """``n`` seeded cases, families in turn, encodings at random."""
    bases = base_logs(folder)
    rng = random.Random(seed)
    for k in range(n):
        family = families[k % len(families)]
        encoding = rng.choice(ENCODINGS)
        data = bases[encoding]
        if family == "bytes":
            name, out = _bytes_case(data, rng)
        elif family == "records":
            name, out = _records_case(data, rng)
        elif family == "payloads":
            name, out = _payloads_case(data, rng, encoding)
        else:
            name, out = _odd_case(rng, encoding, folder)
        if out:
            yield Case(family, f"{family}/{encoding}/{name}#{k}", out)


# ---------------------------------------------------------------------------- judging


def judge(
    case: Case, code: int, stderr: str, log: Path, before: str, out: Path, crashed: bool
) -> Outcome:
    """The problems with one run (empty when it ended as it should)."""
    problems = []
    if crashed or "Traceback" in stderr:
        problems.append("traceback")
    if code not in (0, 2, 3):
        problems.append(f"exit {code}")
    lines = [line for line in stderr.splitlines() if line.strip()]
    if code in (2, 3) and len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr")
    if hashlib.sha256(log.read_bytes()).hexdigest() != before:
        problems.append("input modified")
    written = sorted(p.name for p in out.iterdir()) if out.exists() else []
    if code == 2 and written:
        problems.append(f"partial output {written}")
    if code in (0, 3):
        want = {f"{log.stem}.dh.json", f"{log.stem}.dh.csv"}
        if not want <= set(written) or any(n.startswith(".") or "tmp" in n for n in written):
            problems.append(f"outputs {written}")
    return Outcome(case.name, case.family, code, tuple(problems), stderr.strip()[-300:])


def run_in_process(case: Case, folder: Path) -> Outcome:
    """``dhlog process LOG --no-rrd --out DIR --model geometric`` through Typer's runner, in
    this process."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app

    log = folder / "case.mcap"
    log.write_bytes(case.data)
    out = folder / "out"
    if out.exists():
        for p in out.iterdir():
            p.unlink()
        out.rmdir()
    before = hashlib.sha256(case.data).hexdigest()
    runner = CliRunner()
    # --model geometric: the readers and the damage checks are what the mutations test (the model
    # selection is tested on whole logs): 58 s → 36 s for the four families
    result = runner.invoke(
        app, ["process", str(log), "--no-rrd", "--out", str(out), "--model", "geometric"]
    )
    crashed = result.exception is not None and not isinstance(result.exception, SystemExit)
    stderr = result.stderr if hasattr(result, "stderr") else result.output
    if crashed:
        import traceback

        stderr += "".join(traceback.format_exception(result.exception))
    return judge(case, result.exit_code, stderr, log, before, out, crashed)
