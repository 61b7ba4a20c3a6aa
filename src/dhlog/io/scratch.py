"""A long log's per-sample arrays out of memory: every array beyond :data:`SPILL_BYTES` lives in
a scratch file mapped into the process, and the pages read or written are handed back to the
system as the passes move on, so the memory a run holds stays bounded by the blocks it works on,
not by the log's length.

An array here is a plain numpy array (a view of a shared file mapping), so polars wraps it
without a copy and every pass reads it as before. The file is unlinked as soon as it is made: the
system frees its disk when the last array on it is gone, whatever ends the process. A pager thread
looks at the resident file pages every :data:`PAGER_PERIOD` s and gives the mapped pages back
(``madvise(MADV_DONTNEED)``) once more than :data:`PAGER_BUDGET` were read; what was written
stays in the file (the system's page cache writes it back, and drops it under memory pressure),
and a page read again is brought back from the cache or the file.

The files go to ``$DHLOG_SCRATCH``, else the system's temporary directory. On a tmpfs (``/tmp``
in RAM) they save no memory: point ``DHLOG_SCRATCH`` at a disk.
"""

from __future__ import annotations

import mmap
import os
import tempfile
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError

#: Arrays larger than this (bytes) live in scratch files; smaller ones in memory.
SPILL_BYTES = 8 << 20
#: How often (s) the pager looks at the pages resident.
PAGER_PERIOD = 0.002
#: Bytes of file pages read or written since the last hand-back that make the pager hand them
#: back.
PAGER_BUDGET = 16 << 20
#: Where the scratch files go, when set.
SCRATCH_ENV = "DHLOG_SCRATCH"
#: The spill limit (bytes) instead of ``SPILL_BYTES``, when set (0: every array spills).
SPILL_ENV = "DHLOG_SPILL_BYTES"

_spill_bytes: int | None = None


@contextmanager
def spill_above(nbytes: int | None) -> Iterator[None]:
    """Arrays larger than ``nbytes`` spilled while inside (tests: a small log out of memory)."""
    global _spill_bytes
    before, _spill_bytes = _spill_bytes, nbytes
    try:
        yield
    finally:
        _spill_bytes = before


def directory() -> str:
    """Where the scratch files go."""
    return os.environ.get(SCRATCH_ENV) or tempfile.gettempdir()


class _Pager:
    """The thread that hands the pages of every live mapping back, past ``PAGER_BUDGET``."""

    def __init__(self) -> None:
        self._maps: list[weakref.ref[mmap.mmap]] = []
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def watch(self, mapping: mmap.mmap) -> None:
        with self._lock:
            self._maps.append(weakref.ref(mapping))
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._run, name="dhlog-pager", daemon=True)
                self._thread.start()

    def live(self) -> bool:
        """Whether any scratch array may be live."""
        return bool(self._maps)

    def release(self) -> None:
        """Hand back the pages of every live mapping now."""
        with self._lock:
            live = [(r, r()) for r in self._maps]
            self._maps = [r for r, m in live if m is not None]
            mappings = [m for _, m in live if m is not None]
        for m in mappings:
            try:
                m.madvise(mmap.MADV_DONTNEED)
            except (ValueError, OSError):  # closed meanwhile
                pass
        del mappings

    def _run(self) -> None:
        statm = _Statm()
        floor = statm.shared()
        while True:
            time.sleep(PAGER_PERIOD)
            # a look at the resident file pages is one read; the hand-back (a system call per
            # mapping) only once the pages read since the last exceed the budget
            if statm.missing or statm.shared() - floor > PAGER_BUDGET:
                self.release()
                floor = statm.shared()
            with self._lock:
                self._maps = [r for r in self._maps if r() is not None]
                if not self._maps:
                    self._thread = None
                    statm.close()
                    return

    def after_fork(self) -> None:
        self._maps, self._lock, self._thread = [], threading.Lock(), None


class _Statm:
    """The process's resident file-backed pages, from ``/proc/self/statm`` (0 where there is
    none: the pager then hands the pages back every period)."""

    def __init__(self) -> None:
        try:
            self._fd: int | None = os.open("/proc/self/statm", os.O_RDONLY)
        except OSError:
            self._fd = None

    @property
    def missing(self) -> bool:
        return self._fd is None

    def shared(self) -> int:
        if self._fd is None:
            return 0
        return int(os.pread(self._fd, 128, 0).split()[2]) * mmap.PAGESIZE

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


_pager = _Pager()
os.register_at_fork(after_in_child=_pager.after_fork)


def release() -> None:
    """Hand back the pages of every scratch array now (the pager does it on its own too)."""
    _pager.release()


def _file(nbytes: int) -> int:
    """An unlinked scratch file of ``nbytes`` (sparse): its descriptor."""
    where = directory()
    try:
        fd, path = tempfile.mkstemp(prefix="dhlog-", suffix=".scratch", dir=where)
    except OSError as exc:
        raise InputError(
            f"{where}: cannot write a scratch file for a long log ({exc.strerror}); set "
            f"{SCRATCH_ENV} to a writable directory on a disk."
        ) from None
    os.unlink(path)
    try:
        os.ftruncate(fd, max(nbytes, 1))
    except OSError as exc:
        os.close(fd)
        raise InputError(
            f"{where}: cannot size a scratch file of {nbytes} bytes ({exc.strerror}); set "
            f"{SCRATCH_ENV} to a directory with room."
        ) from None
    return fd


def spool() -> BinaryIO:
    """An empty unlinked scratch file, open to write a stream into and read it back (a
    compressed log decompressed: on disk, not in memory)."""
    fd = _file(0)
    os.ftruncate(fd, 0)
    return os.fdopen(fd, "w+b")


def _mapped(fd: int, nbytes: int, dtype: np.dtype[Any], count: int) -> NDArray[Any]:
    mapping = mmap.mmap(fd, max(nbytes, 1))
    _pager.watch(mapping)
    return np.frombuffer(mapping, dtype=dtype, count=count)


def spill_limit() -> int:
    """Arrays larger than this many bytes go to scratch files (``spill_above``, else
    ``$DHLOG_SPILL_BYTES``, else ``SPILL_BYTES``)."""
    if _spill_bytes is not None:
        return _spill_bytes
    text = os.environ.get(SPILL_ENV)
    if not text:
        return SPILL_BYTES
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise InputError(
            f"{SPILL_ENV}={text!r}: the spill limit is a number of bytes (0 or more); correct "
            "or unset it."
        )
    return value


def spills(nbytes: int) -> bool:
    """Whether an array of ``nbytes`` goes to a scratch file."""
    return nbytes > spill_limit()


def empty(
    shape: int | tuple[int, ...], dtype: Any = np.float64, *, always: bool = False
) -> NDArray[Any]:
    """``np.empty(shape, dtype)``: in a scratch file when larger than the spill limit, or
    whatever its size with ``always``."""
    dt = np.dtype(dtype)
    dims = (shape,) if isinstance(shape, int) else tuple(shape)
    count = int(np.prod(dims, dtype=np.int64))
    nbytes = count * dt.itemsize
    if not (always or spills(nbytes)):
        return np.empty(dims, dtype=dt)
    fd = _file(nbytes)
    try:
        return _mapped(fd, nbytes, dt, count).reshape(dims)
    finally:
        os.close(fd)


def zeros(shape: int | tuple[int, ...], dtype: Any = np.float64) -> NDArray[Any]:
    """``np.zeros``: a scratch file reads as zeros until written."""
    out = empty(shape, dtype)
    if not _mapped_view(out):
        out.fill(0)
    return out


def full(shape: int | tuple[int, ...], value: Any, dtype: Any) -> NDArray[Any]:
    """``np.full``, in a scratch file when large (written a block at a time)."""
    out = empty(shape, dtype)
    flat = out.reshape(-1)
    for start in range(0, flat.size, BLOCK):
        flat[start : start + BLOCK] = value
    return out


def mapped(
    array: NDArray[Any],
    f: Callable[[NDArray[Any]], Any],
    dtype: Any = None,
    *,
    always: bool = False,
) -> NDArray[Any]:
    """``f(array)`` for an elementwise ``f``, computed a block at a time (into a scratch file
    when large, or whatever its size with ``always``)."""
    out = empty(array.shape, array.dtype if dtype is None else dtype, always=always)
    for start in range(0, array.shape[0], BLOCK):
        out[start : start + BLOCK] = f(array[start : start + BLOCK])
    return out


def gathered(source: NDArray[Any], index: NDArray[np.integer], dtype: Any = None) -> NDArray[Any]:
    """``source[index]`` (as ``dtype``) gathered a block at a time (into a scratch file when
    large)."""
    out = empty((index.shape[0], *source.shape[1:]), source.dtype if dtype is None else dtype)
    for start in range(0, index.shape[0], BLOCK):
        out[start : start + BLOCK] = source[index[start : start + BLOCK]]
    return out


def moved(array: NDArray[Any], *, copy: bool = False, always: bool = False) -> NDArray[Any]:
    """``array`` in a scratch file when larger than the spill limit, or whatever its size with
    ``always`` (copied a block at a time, unless already in one and no ``copy`` is asked), else
    ``array`` (or its copy)."""
    if not (always or spills(array.nbytes)):
        return array.copy() if copy else array
    if not copy and _mapped_view(array):
        return array
    return mapped(array, lambda part: part, always=always)


def _mapped_view(array: NDArray[Any]) -> bool:
    """Whether ``array`` is a view of a scratch mapping."""
    base: Any = array
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, memoryview):
        base = base.obj
    return isinstance(base, mmap.mmap)


#: Elements a step when a scratch array is filled or copied.
BLOCK = 1 << 20


#: Samples a gather from scratch arrays may span before their pages are handed back.
SPAN = 1 << 19


def in_spans(rows: Any, f: Callable[[Any], NDArray[Any]]) -> NDArray[Any]:
    """``f(rows)`` for a gather at ``rows`` (a slice or an index array), a piece at a time
    where scratch arrays are live and the rows spread over more than :data:`SPAN` samples,
    the mapped pages handed back after each piece: a strided subset of a long log never maps
    its columns whole (each read page of a column would otherwise stay in the process until
    the pager runs)."""
    if isinstance(rows, slice) or rows.size < 2 or not _pager.live():
        return f(rows)
    first, last = int(rows[0]), int(rows[-1])
    if abs(last - first) <= SPAN:
        return f(rows)
    if last > first and bool(np.all(rows[1:] >= rows[:-1])):
        cuts = np.searchsorted(rows, np.arange(first + SPAN, last + 1, SPAN))
    else:
        cuts = np.arange(1024, rows.size, 1024)
    parts = []
    for piece in np.split(rows, cuts):
        if piece.size:
            parts.append(f(piece))
            release()
    return np.concatenate(parts) if parts else f(rows[:0])


def flatnonzero(mask: NDArray[np.bool_], dtype: Any = np.intp) -> NDArray[Any]:
    """``np.flatnonzero(mask).astype(dtype)`` counted and written a block at a time (no
    index array of the whole mask in memory)."""
    count = 0
    for start in range(0, mask.size, BLOCK):
        count += int(np.count_nonzero(mask[start : start + BLOCK]))
    out = empty(count, dtype)
    at = 0
    for start in range(0, mask.size, BLOCK):
        found = np.flatnonzero(mask[start : start + BLOCK])
        out[at : at + found.size] = found + start
        at += found.size
    return out


class Growing:
    """A 1-D array grown at its end: in memory while small, then in a scratch file that grows
    in place (the file lengthened and mapped again: nothing copied)."""

    def __init__(self, dtype: Any) -> None:
        self._dtype = np.dtype(dtype)
        self._array: NDArray[Any] = np.empty(0, dtype=self._dtype)
        self._size = 0
        self._fd: int | None = None

    def _grow(self, end: int) -> None:
        capacity = max(end, self._array.shape[0] * 9 // 8, 4096)
        nbytes = capacity * self._dtype.itemsize
        if self._fd is None and not spills(nbytes):
            self._array.resize(capacity, refcheck=False)  # remapped by the system, not copied
            return
        capacity = max(end, self._array.shape[0] * 2)  # fewer mappings
        nbytes = capacity * self._dtype.itemsize
        if self._fd is None:
            self._fd = _file(nbytes)
            grown = _mapped(self._fd, nbytes, self._dtype, capacity)
            grown[: self._size] = self._array[: self._size]
        else:
            os.ftruncate(self._fd, nbytes)
            grown = _mapped(self._fd, nbytes, self._dtype, capacity)
        self._array = grown

    def extend(self, values: NDArray[Any]) -> None:
        end = self._size + values.shape[0]
        if end > self._array.shape[0]:
            self._grow(end)
        self._array[self._size : end] = values
        self._size = end

    def done(self) -> NDArray[Any]:
        """The values (the array is not extended after)."""
        if self._fd is None:
            self._array.resize(self._size, refcheck=False)
            return self._array
        os.close(self._fd)
        self._fd = None
        return self._array[: self._size]

    def __del__(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
