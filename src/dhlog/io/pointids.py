"""The export's own point ids (``Point ID``, ``Point Name``…), carried from ``dhlog import`` into
the log and out into the result: an MCAP metadata record ``dhlog.point_ids`` holding two JSON
arrays of the same length, ``t_ns`` (each point's stamp on ``/tracker/point``) and ``ids``. The
input contract is unchanged (a reader that does not know the record ignores it); dhlog names
outliers, held-out poses and the recording's points by these ids.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

#: The metadata record's name.
POINT_IDS_METADATA = "dhlog.point_ids"
#: An id is cut to this many characters (untrusted text in a message).
MAX_ID = 80
#: How many ids a message names before "and N more".
SHOWN = 12


def point_ids_record(t_ns: NDArray[np.int64], ids: list[str]) -> dict[str, str]:
    """The ``dhlog.point_ids`` metadata of points stamped ``t_ns`` named ``ids``."""
    return {"t_ns": json.dumps([int(t) for t in t_ns]), "ids": json.dumps(list(ids))}


def read_point_ids(path: str | Path, warnings: list[str]) -> dict[int, str] | None:
    """The point ids (stamp → id) of the MCAP file at ``path``, or None when it has none; a
    record that cannot be read is one warning (the ids are left out, nothing else)."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            for record in make_reader(f).iter_metadata():
                if record.name != POINT_IDS_METADATA:
                    continue
                stamps = json.loads(record.metadata.get("t_ns", "[]"))
                ids = json.loads(record.metadata.get("ids", "[]"))
                if (
                    not isinstance(stamps, list)
                    or not isinstance(ids, list)
                    or len(stamps) != len(ids)
                    or not all(isinstance(t, int) and not isinstance(t, bool) for t in stamps)
                    or not all(isinstance(i, str) for i in ids)
                ):
                    raise ValueError("malformed")
                return {int(t): _shown(i) for t, i in zip(stamps, ids, strict=True)}
    except Exception:  # an unreadable record loses the names only
        warnings.append(
            f"{path}: its {POINT_IDS_METADATA} record cannot be read; the points are named by "
            "their number instead of the export's ids."
        )
    return None


def _shown(text: str) -> str:
    text = "".join(c if c.isprintable() else "?" for c in text)
    return text if len(text) <= MAX_ID else text[: MAX_ID - 1] + "…"


def listed(names: list[str]) -> str:
    """``names`` for a message: the first :data:`SHOWN`, then how many more."""
    shown = ", ".join(names[:SHOWN])
    more = len(names) - SHOWN
    return shown if more <= 0 else f"{shown} and {more} more"
