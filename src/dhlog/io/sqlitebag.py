"""A rosbag2 bag in sqlite3 storage (``.db3``, as ROS 2 Humble records by default) as MCAP.

The bag — a folder with ``metadata.yaml`` and its ``.db3`` files, or one ``.db3`` file — is read
by the rosbags library (which decompresses a file-compressed bag's ``.db3.zstd`` files and each
message of a message-compressed one) and its messages, as recorded (CDR, in the order of their
log time), are copied into a temporary MCAP file: ROS 2 profile, one channel per connection, each
schema the bag's own message definition (Iron and later store it), else the definition of the
type in rosbags' type store (Humble stores none). The MCAP reader then reads it as any bag
(:func:`dhlog.io.reader.read_log`), so both storages go through one decoder. Messages are
streamed one at a time into chunks of :data:`CHUNK_BYTES`: the memory held stays bounded
whatever the bag's length; the temporary file (in ``$DHLOG_SCRATCH``, else the temp dir) is as
large as the bag's messages and removed once read.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dhlog.errors import DhlogError, InputError
from dhlog.io import ros2

#: The temporary MCAP file's chunk size (bytes; rosbag2's MCAP default).
CHUNK_BYTES = 768 * 1024
#: Messages between two calls of ``progress``.
PROGRESS_EVERY = 20_000


def is_sqlite3(bag: Any) -> bool:
    """Whether the open rosbags ``Reader`` ``bag`` reads sqlite3 storage."""
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    storages = getattr(bag.storage, "storages", None) or [bag.storage]
    return any(isinstance(s, Sqlite3Reader) for s in storages)


def _definition(msgtype: str, msgdef: Any, distro: str | None) -> tuple[str, bytes]:
    """The schema encoding and text of ``msgtype``: the bag's own definition, else rosbags'
    type store's for the bag's ROS distribution (Humble's when not named), else dhlog's own
    (:data:`dhlog.io.ros2.MSGDEFS`), else none (a topic no stream reads needs none)."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_typestore

    if msgdef is not None and msgdef.format != MessageDefinitionFormat.NONE and msgdef.data:
        kind = "ros2msg" if msgdef.format == MessageDefinitionFormat.MSG else "ros2idl"
        return kind, str(msgdef.data).encode()
    store = {s.value: s for s in Stores}.get(f"ros2_{distro}", Stores.ROS2_HUMBLE)
    try:
        text, _ = get_typestore(store).generate_msgdef(msgtype, ros_version=2)
        return "ros2msg", text.encode()
    except Exception:  # a type the store does not know (a package of the cell's own)
        known = ros2.MSGDEFS.get(msgtype)
        return "ros2msg", known.encode() if known else b""


def sqlite3_storage(path: Path) -> bool:
    """Whether ``path`` is a ``.db3`` file or a bag folder whose storage files are ``.db3``
    (file-compressed: ``.db3.zstd``)."""
    if not path.is_dir():
        return path.suffix == ".db3"
    try:
        return any(p.name.endswith((".db3", ".db3.zstd")) for p in path.iterdir())
    except OSError:
        return False


@dataclass(frozen=True)
class Copy:
    """The temporary MCAP copy of the bag at ``bag``: its ``path``, what the bag is
    (``stored``, for the reader's message), and ``reading``: the progress callback for the
    read of the copy (the second half of the work)."""

    bag: Path
    path: Path
    stored: str
    reading: Callable[[float], None] | None

    def renamed(self, text: str) -> str:
        """``text`` naming the bag where it names the copy."""
        return text.replace(str(self.path), str(self.bag))


@contextmanager
def as_mcap(path: Path, progress: Callable[[float], None] | None = None) -> Iterator[Copy]:
    """The sqlite3 bag at ``path`` copied into a temporary MCAP file (:class:`Copy`), removed on
    leaving; an error raised inside names the bag, not the copy. ``progress`` gets the fraction
    of the work done: the copy's first half, the read of the copy (``Copy.reading``) the rest."""
    copy = _copied(path, None if progress is None else (lambda f: progress(f / 2)))
    with copy as (tmp, files, mode):
        stored = f"a rosbag2 bag in sqlite3 storage ({files} .db3 file(s)"
        stored += f", {mode}-compressed)" if mode else ")"
        reading = None if progress is None else (lambda f: progress(0.5 + f / 2))
        found = Copy(path, tmp, stored, reading)
        try:
            yield found
        except DhlogError as exc:
            exc.args = tuple(found.renamed(str(a)) for a in exc.args)
            raise


@contextmanager
def _copied(
    path: Path, progress: Callable[[float], None] | None = None
) -> Iterator[tuple[Path, int, str | None]]:
    """The sqlite3 bag at ``path`` copied into a temporary MCAP file: yields its path, the
    number of storage files read and the bag's compression mode ("file", "message" or None);
    the file is removed on leaving. ``progress`` gets the fraction of messages copied."""
    from mcap.writer import CompressionType, Writer
    from rosbags.rosbag2 import Reader, ReaderError

    scratch_dir = os.environ.get("DHLOG_SCRATCH") or None
    fd, tmp = tempfile.mkstemp(prefix="dhlog-db3-", suffix=".mcap", dir=scratch_dir)
    try:
        try:
            with os.fdopen(fd, "wb") as f, Reader(path) as bag:
                if not is_sqlite3(bag):
                    raise InputError(f"{path}: not a rosbag2 bag in sqlite3 storage.")
                files = len(getattr(bag.storage, "storages", None) or [bag.storage])
                writer = Writer(f, chunk_size=CHUNK_BYTES, compression=CompressionType.NONE)
                writer.start(profile="ros2", library="dhlog (from a rosbag2 sqlite3 bag)")
                distro = getattr(bag, "ros_distro", None)
                schemas: dict[str, int] = {}
                channels: dict[int, int] = {}
                for conn in bag.connections:
                    if conn.msgtype not in schemas:
                        kind, text = _definition(conn.msgtype, conn.msgdef, distro)
                        schemas[conn.msgtype] = writer.register_schema(conn.msgtype, kind, text)
                    encoding = getattr(conn.ext, "serialization_format", "cdr")
                    channels[conn.id] = writer.register_channel(
                        conn.topic, encoding, schemas[conn.msgtype]
                    )
                total = max(bag.message_count, 1)
                for k, (conn, stamp, data) in enumerate(bag.messages()):
                    writer.add_message(channels[conn.id], stamp, bytes(data), stamp, sequence=k)
                    if progress is not None and k % PROGRESS_EVERY == 0:
                        progress(min(k / total, 1.0))
                writer.finish()  # type: ignore[no-untyped-call]
                mode = bag.compression_mode
        except FileNotFoundError:
            raise InputError(
                f"{path}: a folder of .db3 files without the bag's metadata.yaml; give the bag "
                "folder as recorded (with metadata.yaml), or one .db3 file."
            ) from None
        except (ReaderError, KeyError, ValueError, AttributeError, OSError) as exc:
            raise InputError(
                f"{path}: a rosbag2 bag in sqlite3 storage that rosbags cannot read ({exc}); "
                "give the bag folder (with metadata.yaml) or its .db3 file as recorded."
            ) from None
        except Exception as exc:  # sqlite3 (apsw) errors: a damaged or foreign .db3
            if type(exc).__module__.split(".")[0] != "apsw":
                raise
            raise InputError(
                f"{path}: the sqlite3 storage cannot be read ({exc}); copy the bag again from "
                "where it was recorded."
            ) from None
        yield Path(tmp), files, mode
    finally:
        Path(tmp).unlink(missing_ok=True)
