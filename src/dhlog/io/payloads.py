"""A log's payloads made ready for the decoders: the channels the walk decoded taken from its sink,
those it could not read again (:func:`_decoded_columns`), payloads compressed one by one
decompressed (:func:`_unzstd_squeezed`), and every message through the mcap library's reader
and decoders for the general path (:func:`_read_general`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from dhlog.errors import InputError
from dhlog.io.decode.blocks import Block, bulk_layout
from dhlog.io.decode.columns import ColumnSink
from dhlog.io.decode.messages import (
    json_decoder,
)
from dhlog.io.mcapscan import ZSTD_MAGIC, McapScan, scan_mcap
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.pipeline import Pipeline


def _decoded_columns(
    sink: ColumnSink,
    scan: McapScan,
    infos: dict[str, list[ChannelInfo]],
    targets: list[list[ChannelInfo]],
    pipeline: Pipeline,
    topics: list[str] | None,
) -> dict[int, list[Block]]:
    """The blocks of the streams' channels the walk decoded as the streams read them. A channel
    decoded otherwise (its layout planned before the pipeline was chosen, or its definition
    changed after) or refused part-way (a message that does not fit the bulk decode) has its
    payloads read again, into ``scan.messages``: the per-message path decides on them."""
    orientation = pipeline.streams["point"].orientation
    needs: dict[int, set[str | None]] = {}
    for stream, channels in [*infos.items(), *(("point", c) for c in targets)]:
        fields = pipeline.streams[stream].fields
        for info in channels:
            needs.setdefault(info.id, set()).add(bulk_layout(stream, info, fields, orientation))
    out: dict[int, list[Block]] = {}
    again: set[int] = set()
    for cid, layouts in needs.items():
        done = sink.decoded(cid)
        fits = done is not None and done[0] == scan.channels[cid] and layouts == {done[1]}
        if cid in sink.refused or (done is not None and not fits):
            again.add(cid)
        elif fits:
            out[cid] = sink.blocks(cid)
    if again:
        rescan = scan_mcap(scan.path, topics=topics, sink=lambda cid, _, __: cid not in again)
        kept = {cid: raw for cid, raw in rescan.messages.items() if cid in again}
        _unzstd_squeezed(kept, scan.path, False)
        scan.messages.update(kept)
    return out


def _unzstd_squeezed(messages: dict[int, RawMessages], path: str, unzstd: bool) -> None:
    """Payloads compressed one by one (rosbag2 --compression-mode message), decompressed in
    place: said by the bag's metadata (``unzstd``), or seen in the payloads themselves (no CDR,
    JSON or protobuf message starts with zstd's magic number)."""
    squeezed = {
        cid: raw
        for cid, raw in messages.items()
        if unzstd or (len(raw) and raw.payload(0)[:4] == ZSTD_MAGIC)
    }
    if squeezed:
        messages.update(_unzstd_messages(squeezed, path))


def _unzstd_messages(messages: dict[int, RawMessages], path: str) -> dict[int, RawMessages]:
    """Payloads compressed one by one (rosbag2 ``--compression-mode message``), decompressed
    into one buffer per channel; a payload that is not zstd is damage (left out, counted by
    the decoders as an empty message)."""
    import zstandard

    out = {}
    for cid, raw in messages.items():
        d = zstandard.ZstdDecompressor()
        parts = []
        for i in range(len(raw)):
            payload = raw.payload(i)
            try:
                parts.append(d.decompress(payload, max_output_size=64 * len(payload) + 4096))
            except zstandard.ZstdError:
                parts.append(b"")
        lengths = np.array([len(p) for p in parts], dtype=np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        data = np.frombuffer(b"".join(parts), dtype=np.uint8)
        out[cid] = RawMessages(data, starts, lengths, raw.log_time)
    return out


def _read_general(path: str, infos: list[ChannelInfo]) -> dict[int, list[tuple[int, Any]]]:
    """Every message of ``infos``' topics through the mcap library's reader and decoders."""
    from mcap.decoder import DecoderFactory
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory as ProtobufFactory
    from mcap_ros2.decoder import DecoderFactory as Ros2Factory

    class JsonFactory(DecoderFactory):
        def decoder_for(self, message_encoding: str, schema: Any) -> Callable[[bytes], Any] | None:
            return json_decoder if message_encoding == "json" else None

    out: dict[int, list[tuple[int, Any]]] = {}
    topics = sorted({i.topic for i in infos})
    by_topic = {(i.topic, i.schema_name): i.id for i in infos}
    try:
        with open(path, "rb") as f:
            reader = make_reader(
                f, decoder_factories=[Ros2Factory(), ProtobufFactory(), JsonFactory()]
            )
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=topics, log_time_order=False
            ):
                key = by_topic.get((channel.topic, schema.name if schema else ""))
                if key is not None:
                    out.setdefault(key, []).append((message.log_time, decoded))
    except (McapError, EOFError, ValueError) as exc:
        raise InputError(f"{path}: the mcap library could not read it ({exc}).") from None
    return out
