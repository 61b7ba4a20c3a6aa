"""Per-sample quantities read a block at a time: the samples of a long log are never held as
one (m, n) array of encoder values next to another.

A :class:`PerSample` looks like an (m, …) array to the code that reads it by rows — a slice,
an index array, a mask, ``shape`` — and computes those rows when asked (the encoder values
interpolated from the joint-state stream, the points gathered from the point stream, the joints'
speeds, the table's joint values). Arithmetic on it as a whole fails loudly: a pass over every
sample goes through :func:`blocks`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.io import scratch

#: Rows (into the samples) a PerSample is asked for: a slice or an index array.
Index = slice | NDArray[np.intp]

#: Samples a block in the passes over every sample that build nothing per sample.
BLOCK = 1 << 16

#: The largest per-sample array :meth:`PerSample.filled` computes once and keeps (bytes): beyond
#: it the rows are computed at every pass. Kept, a long log's values are read back from a
#: scratch file at every pass; the page faults of that read cost more than the interpolation
#: they save beyond about this size (paired, the whole command: 1 M samples 0.94, 10 M 0.94,
#: 20 M 1.03 of the time computing at every pass; 6 joints' values are 48 B a sample).
FILL_BYTES = 1 << 29


def blocks(m: int, size: int = BLOCK) -> Iterator[slice]:
    """Consecutive slices of at most ``size`` covering ``range(m)``."""
    for start in range(0, m, size):
        yield slice(start, min(start + size, m))


class PerSample:
    """An (m, …) per-sample array whose rows ``fetch(index)`` computes on demand (``index`` a
    slice with step 1 or an index array). Indexing as numpy does by rows (a slice, an integer
    array, a boolean mask, and a tuple whose first item is one of those) returns a numpy array.
    """

    __array_priority__ = 1000.0

    def __init__(self, shape: tuple[int, ...], fetch: Callable[[Index], NDArray[Any]]) -> None:
        self._shape = shape
        self._fetch = fetch

    @property
    def shape(self) -> tuple[int, ...]:
        return self._shape

    @property
    def ndim(self) -> int:
        return len(self._shape)

    def __len__(self) -> int:
        return self._shape[0]

    def __repr__(self) -> str:
        return f"PerSample(shape={self._shape})"

    def __getitem__(self, index: Any) -> NDArray[Any]:
        if isinstance(index, tuple):
            rows, *rest = index
            return self[rows][(slice(None), *rest)]
        m = self._shape[0]
        if isinstance(index, slice):
            start, stop, step = index.indices(m)
            if step == 1:
                return self._fetch(slice(start, max(start, stop)))
            return self._fetch(np.arange(start, stop, step, dtype=np.intp))
        arr = np.asarray(index)
        if arr.dtype == np.bool_:
            if arr.shape != (m,):
                raise IndexError(f"a mask of shape {arr.shape} for {m} samples")
            return self._fetch(np.flatnonzero(arr))
        if np.issubdtype(arr.dtype, np.integer):
            idx = arr.astype(np.intp, copy=False)
            if idx.ndim != 1:
                raise IndexError("per-sample rows are indexed by a 1-D array")
            if idx.size and (int(idx.min()) < -m or int(idx.max()) >= m):
                raise IndexError(f"row out of range for {m} samples")
            return self._fetch(np.where(idx < 0, idx + m, idx))
        raise TypeError(f"per-sample rows cannot be indexed by {type(index).__name__}")

    def __array__(self, *args: object, **kwargs: object) -> NDArray[Any]:
        raise TypeError(
            "a PerSample is read a block at a time (persample.blocks); it is never made whole"
        )

    def map(self, f: Callable[[NDArray[Any]], NDArray[Any]], shape: tuple[int, ...]) -> PerSample:
        """``f`` applied to the rows as they are read (``shape``: the result's)."""
        return PerSample(shape, lambda index: f(self[index]))

    def filled(self) -> PerSample:
        """The same rows computed once, a block at a time, into an array (a scratch file when
        large) and read from there, read-only, in place of computing them at every pass; itself
        beyond :data:`FILL_BYTES`."""
        if not fills(self._shape):
            return self
        values = scratch.empty(self._shape)
        for sl in blocks(self._shape[0]):
            values[sl] = self._fetch(sl)
        return PerSample.kept(values)

    @staticmethod
    def kept(values: NDArray[Any]) -> PerSample:
        """``values`` (m, …) read by rows, read-only (a gather spread over a long log a piece
        at a time: :func:`~dhlog.io.scratch.in_spans`)."""
        values.flags.writeable = False
        return PerSample(values.shape, lambda index: scratch.in_spans(index, lambda r: values[r]))


def fills(shape: tuple[int, ...]) -> bool:
    """Whether per-sample float64 values of ``shape`` are kept (:meth:`PerSample.filled`)."""
    return 8 * int(np.prod(shape, dtype=np.int64)) <= FILL_BYTES


def rows_where(mask: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The row numbers where ``mask`` holds, as int32 where they fit (half the memory of a
    long log's index arrays), found a block at a time (a long log's in a scratch file)."""
    return scratch.flatnonzero(mask, np.int32 if mask.size < 2**31 else np.intp)


#: What the passes over the samples read: an array, or a PerSample read a block at a time.
SampleArray = NDArray[np.float64] | PerSample
