"""A whole image topic of a log, a block at a time: :class:`ImageStream` walks the MCAP with
:func:`dhlog.io.mcapscan.scan_mcap` in a thread, its sink decoding each chunk's images as the
walk meets them (one payload: :mod:`~dhlog.identify.camera.frames.imagedecode`) and dropping the
chunk's bytes, and hands the frames on through a queue of at most :data:`QUEUED` batches of at most
:data:`BATCH_BYTES` decoded bytes: the log is never held whole. A frame that cannot be decoded (a
size that does not match its layout, a corrupt JPEG, an unknown encoding) is a counted fault
named by its index on the topic, never an exception (:meth:`ImageStream.warning`).
:meth:`ImageStream.payload_batches` hands on the payloads as recorded instead, for decoding in
worker processes (:mod:`dhlog.identify.camera.frames.observe`).

A ``.mcap.zstd`` is read as :mod:`dhlog.io.mcapscan` reads it; a rosbag2 bag folder's split files
are walked in order as one log (its ``metadata.yaml`` read by the rosbags library). The camera
infos of a topic: :func:`read_camera_infos`.
"""

from __future__ import annotations

import contextlib
import functools
import queue
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

from dhlog.errors import InputError, MissingTopicError
from dhlog.identify.camera.frames.imagedecode import (
    INFO_SCHEMAS,
    CameraImage,
    Decoder,
    ImageFaultError,
    decode_payload,
    payload_decoder,
)
from dhlog.io.mcapscan import McapScan, scan_mcap
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.ros2 import CameraInfo
from dhlog.io.safetext import printable

ACCEPTED_IMAGES = (
    "sensor_msgs/msg/Image, sensor_msgs/msg/CompressedImage (cdr), foxglove.RawImage, "
    "foxglove.CompressedImage (json, protobuf)"
)
ACCEPTED_INFOS = "sensor_msgs/msg/CameraInfo (cdr), foxglove.CameraCalibration (json, protobuf)"


#: Decoded bytes in one batch handed on, and batches waiting: the stream's memory bound.
BATCH_BYTES = 64 << 20
QUEUED = 2


@dataclass(frozen=True)
class Faults:
    """Frames that could not be decoded: per reason, their indices on the topic (:meth:`of`)."""

    by_reason: Mapping[str, tuple[int, ...]] = field(default_factory=dict)

    @staticmethod
    def of(faults: Iterable[tuple[str, int]]) -> Faults:
        """The faults ``(reason, index)`` grouped by reason, in the order met."""
        by_reason: dict[str, list[int]] = {}
        for reason, index in faults:
            by_reason.setdefault(reason, []).append(index)
        return Faults({reason: tuple(at) for reason, at in by_reason.items()})

    def __len__(self) -> int:
        return sum(len(v) for v in self.by_reason.values())

    def warning(self, path: str, topic: str, count: int) -> str | None:
        """One line naming the frames of ``topic`` (``count`` messages) not decoded, by reason
        (None when every frame was)."""
        if not self.by_reason:
            return None
        parts = []
        reasons = sorted(self.by_reason.items(), key=lambda kv: -len(kv[1]))
        for reason, indices in reasons[:4]:
            shown = ", ".join(str(i) for i in indices[:5])
            more = f" and {len(indices) - 5} more" if len(indices) > 5 else ""
            parts.append(f"{reason}: {len(indices)} (frame {shown}{more})")
        if len(reasons) > 4:
            parts.append(
                f"{sum(len(v) for _, v in reasons[4:])} for {len(reasons) - 4} other reasons"
            )
        return (
            f"{path}: {len(self)} of {count} frame(s) on {printable(topic)} not decoded, "
            f"skipped — {'; '.join(parts)}."
        )


@dataclass(frozen=True)
class ImagePayload:
    """One image message as recorded (:meth:`ImageStream.payload_batches`): its index among the
    topic's messages, log time (ns: the stamp where the header's is unset), channel (its
    schema decides the decoding) and payload bytes."""

    index: int
    log_time: int
    channel: ChannelInfo
    data: bytes


_T = TypeVar("_T")


class _StoppedError(Exception):
    """The consumer stopped reading: the walk ends."""


class ImageStream:
    """The frames of one image topic of an MCAP, in the order of the file, decoded a chunk at a
    time while the walk goes on in a thread (:meth:`batches`, or the frames one by one).

    ``info_topic`` (optional) is read in the same walk: its intrinsics in :attr:`infos`. After
    the walk: :attr:`count` (messages on the topic), :attr:`faults`, :attr:`warnings` (the
    scan's: damage, truncation) and :meth:`warning`. The iteration raises the reader's errors
    (``InputError``: not an MCAP, unreadable; ``MissingTopicError``; a topic of another
    type), never one for a single frame."""

    def __init__(
        self, path: str | Path, topic: str, info_topic: str | None = None, *, batch_bytes: int = 0
    ) -> None:
        self.path, self.topic, self.info_topic = str(path), topic, info_topic
        self.batch_bytes = batch_bytes or BATCH_BYTES
        self.count = 0
        self._faulted: list[tuple[str, int]] = []  # (reason, index) of the last walk
        self.infos: list[CameraInfo] = []
        self.warnings: list[str] = []
        self.schema = ""
        #: how far the last walk has read the log (0 to 1; set in the walk's thread)
        self.fraction = 0.0
        self._decoders: dict[int, Decoder] = {}

    def _decoder(self, cid: int, info: ChannelInfo) -> Decoder:
        """The decoder of channel ``cid`` (made at its first offer); a channel of another type
        than its topic's stream is an InputError."""
        if cid not in self._decoders:
            is_image = info.topic == self.topic
            made = payload_decoder(info)
            if made is None or (info.schema_name in INFO_SCHEMAS) == is_image:
                raise InputError(
                    f"{self.path}: topic {printable(info.topic)} carries "
                    f"'{printable(info.schema_name[:80])}' ({printable(info.message_encoding)}), "
                    f"not {'images' if is_image else 'camera intrinsics'}; accepted: "
                    f"{ACCEPTED_IMAGES if is_image else ACCEPTED_INFOS}. Give the camera's "
                    f"{'image' if is_image else 'camera-info'} topic."
                )
            self._decoders[cid] = made
        return self._decoders[cid]

    def _decode(self, cid: int, info: ChannelInfo, raw: RawMessages) -> Iterator[CameraImage]:
        """The frames of one offer of the image topic, decoded one at a time as they are
        taken (faults counted; a chunk's frames are never all decoded at once), and the camera
        infos kept."""
        is_image = info.topic == self.topic
        decode = self._decoder(cid, info)
        if is_image:
            self.schema = info.schema_name
        for i in range(len(raw)):
            index = self.count
            if is_image:
                self.count += 1
            start = int(raw.starts[i])
            buf = raw.data[start : start + int(raw.lengths[i])]
            try:
                stamp, frame_id, value = decode_payload(decode, buf)
            except ImageFaultError as exc:
                if is_image:
                    self._faulted.append((str(exc), index))
                continue
            stamp = stamp if stamp > 0 else int(raw.log_time[i])  # unset: the log time
            if is_image:
                yield CameraImage(stamp, frame_id, value, index)
            else:
                self.infos.append(value)

    def batches(self) -> Iterator[list[CameraImage]]:
        """The frames, in batches of at most ``batch_bytes`` decoded bytes (a single frame
        larger than that alone). Each iteration walks the log again, its tallies afresh."""
        return self._batches(self._decode, lambda frame: frame.pixels.nbytes)

    def payload_batches(self) -> Iterator[list[ImagePayload]]:
        """The image topic's payloads as recorded, not decoded (each copied out of its chunk),
        in batches of at most ``batch_bytes`` payload bytes: for decoding elsewhere (in worker
        processes, with :func:`payload_decoder` of the payload's channel and
        :func:`decode_payload`; its faults are then the decoder's to count). The camera infos
        are read as :meth:`batches` reads them."""
        return self._batches(self._payloads, lambda payload: len(payload.data))

    def _payloads(self, cid: int, info: ChannelInfo, raw: RawMessages) -> Iterator[ImagePayload]:
        if info.topic != self.topic:
            for _ in self._decode(cid, info, raw):  # camera infos: kept in self.infos
                pass
            return
        self._decoder(cid, info)  # (a channel of another type refused)
        self.schema = info.schema_name
        for i in range(len(raw)):
            start = int(raw.starts[i])
            data = raw.data[start : start + int(raw.lengths[i])].tobytes()
            yield ImagePayload(self.count, int(raw.log_time[i]), info, data)
            self.count += 1

    def _batches(
        self,
        produce: Callable[[int, ChannelInfo, RawMessages], Iterable[_T]],
        size_of: Callable[[_T], int],
    ) -> Iterator[list[_T]]:
        self.count, self._faulted, self.infos, self.warnings = 0, [], [], []
        self.fraction = 0.0
        hand: queue.Queue[list[_T] | BaseException | None] = queue.Queue(QUEUED)
        stop = threading.Event()

        def put(item: list[_T] | BaseException | None) -> None:
            while True:
                if stop.is_set():
                    raise _StoppedError
                try:
                    hand.put(item, timeout=0.1)
                    return
                except queue.Full:
                    continue

        def offer(frames: Iterable[_T]) -> None:
            batch: list[_T] = []
            size = 0
            for frame in frames:
                if batch and size + size_of(frame) > self.batch_bytes:
                    put(batch)
                    batch, size = [], 0
                batch.append(frame)
                size += size_of(frame)
            if batch:
                put(batch)

        def sink(cid: int, info: ChannelInfo | None, raw: RawMessages) -> bool:
            if info is None:
                return False  # defined later: decoded from the scan's kept payloads
            offer(produce(cid, info, raw))
            return True

        def check(done: float, file: int = 0, files: int = 1) -> None:
            # every few chunks: has the consumer stopped? (and how far the walk is)
            self.fraction = (file + min(max(done, 0.0), 1.0)) / files
            if stop.is_set():
                raise _StoppedError

        def walk() -> None:
            try:
                topics = [self.topic] + ([self.info_topic] if self.info_topic else [])
                present: set[str] = set()
                with contextlib.ExitStack() as stack:
                    paths = _log_files(self.path, stack)
                    for k, path in enumerate(paths):
                        self._decoders = {}  # channel ids are the file's own
                        step = functools.partial(check, file=k, files=len(paths))
                        scan = scan_mcap(path, topics, progress=step, sink=sink)
                        for cid, raw in scan.messages.items():  # channels defined late
                            info = scan.channels.get(cid)
                            if info is not None:
                                offer(produce(cid, info, raw))
                        present.update(scan.topics())
                        self.warnings.extend(scan.warnings)
                wanted = [("image", self.topic), ("camera info", self.info_topic)]
                _check_topics(self.path, sorted(present), wanted)
                put(None)
            except _StoppedError:
                pass
            except BaseException as exc:  # handed to the consumer, raised there
                try:
                    put(exc)
                except _StoppedError:
                    pass

        worker = threading.Thread(target=walk, name="dhlog-images", daemon=True)
        worker.start()
        try:
            while True:
                item = hand.get()
                if item is None:
                    return
                if isinstance(item, BaseException):
                    raise item
                yield item
        finally:
            stop.set()
            worker.join()

    def __iter__(self) -> Iterator[CameraImage]:
        for batch in self.batches():
            yield from batch

    @property
    def faults(self) -> Faults:
        """The frames of the last walk that could not be decoded."""
        return Faults.of(self._faulted)

    def warning(self) -> str | None:
        """One line naming the frames not decoded, by reason (None when every frame was)."""
        return self.faults.warning(self.path, self.topic, self.count)


def _check_topics(path: str, present: list[str], wanted: list[tuple[str, str | None]]) -> None:
    for what, topic in wanted:
        if topic and topic not in present:
            raise MissingTopicError(path, what, topic, present)


def _log_files(path: str, stack: contextlib.ExitStack) -> list[Path]:
    """The MCAP files of a log: the file itself, or a rosbag2 bag folder's split files in
    order (its ``metadata.yaml`` read by the rosbags library, open on ``stack`` while the
    files are walked)."""
    folder = Path(path)
    if not folder.is_dir():
        return [folder]
    from rosbags.rosbag2 import Reader, ReaderError

    try:
        bag = stack.enter_context(Reader(folder))
        files = [Path(s.path) for s in bag.storage.storages]  # type: ignore[attr-defined]
    except (ReaderError, FileNotFoundError, KeyError, ValueError, AttributeError) as exc:
        raise InputError(
            f"{path}: a folder, but not a rosbag2 bag dhlog can read ({exc}); give the bag "
            "folder (with metadata.yaml) or one .mcap file."
        ) from None
    if not files:
        raise InputError(f"{path}: the bag lists no storage files.")
    return files


def read_camera_infos(
    path: str | Path, topic: str, scan: McapScan | None = None
) -> list[CameraInfo]:
    """Every ``CameraInfo`` / ``CameraCalibration`` on ``topic`` (the walk reads no other
    topic's payloads; messages that cannot be read are left out). ``scan``: a walk of ``path``
    already made that kept ``topic``'s payloads (read from it, not walked again)."""
    stream = ImageStream(path, "", topic)
    if scan is None:
        scan = scan_mcap(path, [topic])
    _check_topics(str(path), scan.topics(), [("camera info", topic)])
    for cid, raw in scan.messages.items():
        info = scan.channels.get(cid)
        if info is not None and info.topic == topic:
            for _ in stream._decode(cid, info, raw):
                pass
    return stream.infos
