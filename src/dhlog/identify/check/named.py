"""The samples a fit set aside or kept far off it, named as the export names them: by its point ids
(``dhlog import``'s ``dhlog.point_ids``, :mod:`dhlog.io.pointids`), else by their number in the
log's point stream (``#14``).

* :func:`sample_names`: each fitted sample's name;
* :func:`pose_names`: each scored pose of another session (``--validate``) by its first sample's
  name, the pose found by its measured position;
* :func:`name_outliers`: a note naming the whole-model fit's gross outliers (set aside, with
  their residual), and a warning naming the samples it kept though they lie more than
  :data:`FAR` times its RMS off it (no noise puts a sample there: 5× the RMS of a 3-D residual
  is 8.7 σ per coordinate) — a point the session or its source marks bad, pulling the model.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import overload

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.identify.fit.leaveout import pose_groups, pose_means
from dhlog.io.pointids import listed

#: A kept sample farther than this many times the fit's RMS (3-D residual) is named.
FAR = 5.0
#: ... and farther than this (m): below it nothing is worth a warning.
FAR_FLOOR = 1e-4


class SampleNames(Sequence[str]):
    """The name of each sample at point-stream ``rows`` (stamped ``t_ns``): the export's point
    id, else ``#k`` (its 1-based row in the point stream). Named when asked for: a run names
    a handful of its million samples (the outliers, the far ones, a held-out pose)."""

    def __init__(
        self, t_ns: NDArray[np.int64], rows: NDArray[np.intp], point_ids: dict[int, str] | None
    ) -> None:
        self._t, self._rows, self._ids = t_ns, rows, point_ids

    def __len__(self) -> int:
        return int(self._rows.size)

    @overload
    def __getitem__(self, i: int) -> str: ...

    @overload
    def __getitem__(self, i: slice) -> list[str]: ...

    def __getitem__(self, i: int | slice) -> str | list[str]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        row = int(self._rows[i])
        own = f"#{row + 1}"
        return own if self._ids is None else self._ids.get(int(self._t[i]), own)


def sample_names(
    t_ns: NDArray[np.int64], rows: NDArray[np.intp], point_ids: dict[int, str] | None
) -> SampleNames:
    """Each sample's name (:class:`SampleNames`)."""
    return SampleNames(t_ns, rows, point_ids)


def _shown(names: Sequence[str], norms: NDArray[np.float64], at: NDArray[np.intp]) -> str:
    order = at[np.argsort(-norms[at], kind="stable")]
    return listed([f"{names[i]} ({norms[i] * 1e3:.3g} mm)" for i in order.tolist()])


def name_outliers(
    names: Sequence[str],
    norms: NDArray[np.float64],
    inliers: NDArray[np.bool_],
) -> tuple[NDArray[np.intp], tuple[Note, ...]]:
    """The fit's outliers (``~inliers``; ``norms``: each sample's 3-D residual, m) as indices
    into ``names``, largest residual first, and what is said of them: the outliers named in a
    note (``outliers``), the kept samples beyond :data:`FAR` × the RMS in a warning
    (``far-samples``)."""
    out = np.flatnonzero(~inliers)
    order = out[np.argsort(-norms[out], kind="stable")]
    notes: list[Note] = []
    if out.size:
        said = (
            f"the whole-model fit set aside {out.size} sample(s) as gross outliers (residual "
            f"under the fitted model): {_shown(names, norms, out)}."
        )
        notes.append(Note.info(said, "outliers"))
    kept = np.flatnonzero(inliers)
    if kept.size:
        rms = float(np.sqrt(np.mean(norms[kept] ** 2)))
        far = kept[(norms[kept] > FAR * rms) & (norms[kept] > FAR_FLOOR)]
        if far.size:
            said = (
                f"{far.size} sample(s) the fit kept lie over {FAR:g}× its RMS "
                f"({rms * 1e3:.3g} mm) off it: {_shown(names, norms, far)}; no noise puts a "
                "sample there — if the session or the export marks these points bad, leave "
                "them out of the export (a gross error pulls the whole model)."
            )
            notes.append(Note.warning(said, "far-samples"))
    return np.asarray(order, dtype=np.intp), tuple(notes)


def pose_names(
    Q: NDArray[np.float64],
    P: NDArray[np.float64],
    names: Sequence[str],
    scored: NDArray[np.float64],
) -> list[str]:
    """The name of each ``scored`` pose position (k, 3, m): the name of the first sample of the
    session's pose (:func:`~dhlog.identify.fit.leaveout.pose_groups` of ``Q``) whose mean
    measured position it is (within 1 nm; ``""`` where none is)."""
    groups = pose_groups(Q)
    _, first = np.unique(groups, return_index=True)
    means = pose_means(groups, P)[1]
    out = []
    for pos in np.asarray(scored, dtype=np.float64):
        d = np.linalg.norm(means - pos, axis=1)
        k = int(np.argmin(d)) if d.size else -1
        out.append(names[int(first[k])] if k >= 0 and d[k] <= 1e-9 else "")
    return out
