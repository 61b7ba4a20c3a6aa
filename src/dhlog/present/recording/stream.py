"""A recording streamed to a file: written beside its target and moved into place only when
complete, so a failed or interrupted run never leaves half a recording (also used by
``dhlog compare --rrd``)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb


@contextmanager
def recording_file(
    path: str | Path, application_id: str, blueprint: rrb.Blueprint, recording_id: str | None = None
) -> Iterator[rr.RecordingStream]:
    """A recording streamed to a temporary file beside ``path``, renamed into place (complete:
    flushed and disconnected) only when the block finishes without error."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    try:
        # a signal while the stream is being built would leave a half-made object whose
        # finaliser prints a traceback: defer signals until it exists
        from dhlog.io.writer import signals_deferred

        with signals_deferred():
            rec = rr.RecordingStream(application_id, recording_id=recording_id)
        rec.save(tmp, default_blueprint=blueprint)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        yield rec
        rec.flush()
        rec.disconnect()
        from dhlog.io.writer import publish

        publish(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
