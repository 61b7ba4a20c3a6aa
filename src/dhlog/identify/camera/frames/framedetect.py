"""A camera log's frames looked at (:func:`_looked`): the payloads handed in tasks of
:data:`TASK_FRAMES` to ``jobs`` worker processes (spawned; one OpenCV thread each; SIGINT left to
the parent), at most :data:`IN_FLIGHT` tasks a worker waiting, each frame decoded
(:func:`~dhlog.identify.camera.frames.imagedecode.decode_payload`) and the board detected in it
(:func:`~dhlog.identify.camera.frames.detect.detect`), the results taken back in the frames' order;
with ``jobs=1`` the same work in the calling process. A frame asked for the recording is kept
JPEG-encoded (:data:`KEPT_JPEG_QUALITY` for a raw one).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
from collections import deque
from collections.abc import Generator, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.identify.camera.frames.detect import Detection, Rejected, detect
from dhlog.identify.camera.frames.imagedecode import (
    Decoder,
    ImageFaultError,
    _Cdr,
    _foxglove_bytes,
    _kind,
    decode_payload,
    payload_decoder,
    unzstd_payload,
)
from dhlog.identify.camera.frames.images import ImagePayload, ImageStream
from dhlog.identify.camera.frames.observations import (
    Decimation,
)
from dhlog.io import ros2
from dhlog.io.mcapwalk import ChannelInfo
from dhlog.io.safetext import printable
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics

#: Frames a task carries to a worker, and tasks a worker may have waiting: the bound on the
#: payloads in flight (a full-HD JPEG is 0.2–0.5 MB, a raw bgr8 frame 6.2 MB).
TASK_FRAMES = 4


IN_FLIGHT = 2


#: A raw frame kept for the recording is JPEG-encoded at this quality.
KEPT_JPEG_QUALITY = 90


@dataclass(frozen=True)
class _Setup:
    """What every frame is looked at with: the board and the intrinsics (their image size the
    one every frame is held against)."""

    board: BoardSpec
    camera: Intrinsics


@dataclass(frozen=True)
class _Seen:
    """One frame looked at: its stamp (the header's, else the log time), and a fault (not
    decoded), or its size (w, h) when not the intrinsics', or the detection's outcome and
    the frame kept compressed (when asked)."""

    index: int
    stamp_ns: int = 0
    fault: str | None = None
    size: tuple[int, int] | None = None
    outcome: Detection | Rejected | None = None
    kept: tuple[str, bytes] | None = None


_WORKER_SETUP: _Setup | None = None


_DECODERS: dict[ChannelInfo, Decoder | None] = {}


def _worker_start(setup: _Setup) -> None:
    """A worker's set-up: what it looks with; one OpenCV thread (``jobs`` workers use ``jobs``
    cores); SIGINT ignored (Ctrl-C stops the parent, which stops the workers: no traceback
    from each)."""
    global _WORKER_SETUP
    _WORKER_SETUP = setup
    cv2.setNumThreads(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _look_in_worker(frames: list[tuple[ImagePayload, bool]]) -> list[_Seen]:
    assert _WORKER_SETUP is not None  # (set by the pool's initializer)
    return _look(_WORKER_SETUP, frames)


def _look(setup: _Setup, frames: list[tuple[ImagePayload, bool]]) -> list[_Seen]:
    """Decode each payload and detect the board in it; ``keep``: return it compressed too."""
    out = []
    for payload, keep in frames:
        info = payload.channel
        if info not in _DECODERS:
            _DECODERS[info] = payload_decoder(info)
        decode = _DECODERS[info]
        buf = np.frombuffer(payload.data, dtype=np.uint8)
        try:
            if decode is None:  # (ImageStream refuses such a channel before any payload)
                raise ImageFaultError(f"not an image ({printable(info.schema_name[:80])})")
            stamp, _, pixels = decode_payload(decode, buf)
        except ImageFaultError as exc:
            out.append(_Seen(payload.index, fault=str(exc)))
            continue
        stamp = stamp if stamp > 0 else payload.log_time
        h, w = pixels.shape[:2]
        if (w, h) != setup.camera.size:
            out.append(_Seen(payload.index, stamp, size=(w, h)))
            continue
        outcome = detect(pixels, setup.board, camera=setup.camera)
        kept = _kept(info, buf, pixels) if keep else None
        out.append(_Seen(payload.index, stamp, outcome=outcome, kept=kept))
    return out


def _kept(info: ChannelInfo, buf: NDArray[np.uint8], pixels: NDArray[Any]) -> tuple[str, bytes]:
    """A frame as the recording keeps it: a JPEG or PNG as recorded; any other (raw, or a
    compressed form the recording cannot show) encoded by OpenCV — JPEG for 8 bits, PNG for
    16."""
    with contextlib.suppress(ImageFaultError, ValueError, TypeError, AttributeError):
        data, fmt = _compressed(info, unzstd_payload(buf))
        if data is not None:
            kind = _kind(data, fmt)
            if kind in ("JPEG", "PNG") and data[:2].tobytes() in (b"\xff\xd8", b"\x89P"):
                return kind.lower(), data.tobytes()
    if pixels.dtype == np.uint16:
        return "png", cv2.imencode(".png", pixels)[1].tobytes()
    params = [cv2.IMWRITE_JPEG_QUALITY, KEPT_JPEG_QUALITY]
    return "jpeg", cv2.imencode(".jpg", pixels, params)[1].tobytes()


def _compressed(info: ChannelInfo, buf: NDArray[np.uint8]) -> tuple[NDArray[np.uint8] | None, str]:
    """A compressed image message's data and format (None for a raw image)."""
    if info.schema_name == ros2.COMPRESSED_IMAGE and info.message_encoding == "cdr":
        cdr = _Cdr(buf)
        cdr.stamp()
        cdr.string()  # the header's stamp and frame id
        fmt = cdr.string()
        return cdr.octets(), fmt
    if info.schema_name == "foxglove.CompressedImage":
        from dhlog.io.decode.messages import message_decoder

        decode = message_decoder(info)
        if decode is not None:
            msg = decode(buf.tobytes())

            def get(field: str) -> Any:
                return msg.get(field) if isinstance(msg, dict) else getattr(msg, field, None)

            return _foxglove_bytes(get("data")), str(get("format") or "")
    return None, ""


def _tasks(
    stream: ImageStream, decimation: Decimation
) -> Iterator[list[tuple[ImagePayload, bool]]]:
    task: list[tuple[ImagePayload, bool]] = []
    for batch in stream.payload_batches():
        for payload in batch:
            task.append((payload, decimation.wanted(payload.index)))
            if len(task) == TASK_FRAMES:
                yield task
                task = []
    if task:
        yield task


def _looked(
    stream: ImageStream, setup: _Setup, jobs: int, decimation: Decimation
) -> Generator[list[_Seen], None, None]:
    """Each task's frames looked at, in the frames' order: in ``jobs`` worker processes, or
    here when ``jobs`` is 1."""
    if jobs <= 1:
        for task in _tasks(stream, decimation):
            yield _look(setup, task)
        return
    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads
    pool = ProcessPoolExecutor(jobs, context, initializer=_worker_start, initargs=(setup,))
    waiting: deque[Future[list[_Seen]]] = deque()
    try:
        for task in _tasks(stream, decimation):
            waiting.append(pool.submit(_look_in_worker, task))
            if len(waiting) >= IN_FLIGHT * jobs:
                yield waiting.popleft().result()
        while waiting:
            yield waiting.popleft().result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
