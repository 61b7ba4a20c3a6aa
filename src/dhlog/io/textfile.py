"""Reading untrusted text files (DH files, pipelines, tracker exports) as the log reader reads
logs: only a regular file, its size checked before reading, read with a cap (a file that grows
while read is cut there and refused), decoded strictly, every failure one line naming the file.

The callers give ``fail``, which makes their own error class from the problem (a sentence
without the file name, which the error class adds).
"""

from __future__ import annotations

import codecs
import os
import stat
from collections.abc import Callable
from pathlib import Path

from dhlog.errors import DhlogError

Fail = Callable[[str], DhlogError]


def shown_size(size: int) -> str:
    """A byte count as a reader says it (``12.3 MB``, ``512 kB``, ``80 bytes``)."""
    if size >= 10**6:
        return f"{size / 1e6:.1f} MB"
    if size >= 10**3:
        return f"{size / 1e3:.0f} kB"
    return f"{size} bytes"


def read_capped(
    path: str | Path,
    limit: int,
    fail: Fail,
    *,
    what: str,
    hint: str,
    check: str = "check the path.",
) -> bytes:
    """The bytes of ``path``: a regular file of at most ``limit`` bytes (``what`` names the kind
    of file in the message, ``hint`` says what to do with a larger one, ``check`` with one that
    cannot be opened)."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise fail(f"cannot be read ({exc.strerror or exc}); {check}") from None
    except ValueError:  # a NUL byte in the path
        raise fail("is not a valid path (it holds a NUL byte).") from None
    if stat.S_ISDIR(st.st_mode):
        raise fail(f"is a folder; give the {what} itself.")
    if not stat.S_ISREG(st.st_mode):
        raise fail(
            f"is not a regular file (a device, pipe or socket); dhlog reads a {what} only from "
            "a regular file: save it to one first."
        )
    # the limits are binary (2**20 multiples): said as such too
    binary = f"over {limit / 2**20:g} MiB: " if limit >= 2**20 else ""
    too_large = f"{binary}larger than any {what} dhlog reads ({shown_size(limit)} at most); {hint}"
    if st.st_size > limit:
        raise fail(f"is {shown_size(st.st_size)}, {too_large}")
    try:
        with open(path, "rb") as f:
            data = f.read(limit + 1)
    except OSError as exc:
        raise fail(f"cannot be read ({exc.strerror or exc}); {check}") from None
    if len(data) > limit:  # it grew since the stat
        raise fail(f"is {too_large}")
    return data


def line_of(data: bytes, offset: int) -> int:
    """The 1-based line holding byte ``offset`` of ``data``."""
    return data.count(b"\n", 0, max(offset, 0)) + 1


def decode_utf8(data: bytes, fail: Fail, *, what: str) -> str:
    """``data`` as UTF-8 text (a byte-order mark allowed); UTF-16/32 text, NUL bytes and bytes
    that are not UTF-8 are refused, naming the line."""
    if data.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        raise fail(f"is UTF-32 text; a {what} must be UTF-8: save it as UTF-8.")
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise fail(f"is UTF-16 text; a {what} must be UTF-8: save it as UTF-8.")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise fail(
            f"line {line_of(data, nul)}: holds a NUL byte: not a text file (UTF-16 without a "
            f"byte-order mark, or binary); a {what} must be UTF-8 text."
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise fail(
            f"line {line_of(data, exc.start)}: byte 0x{data[exc.start]:02x} is not UTF-8; "
            f"a {what} must be UTF-8 text: save it as UTF-8."
        ) from None
