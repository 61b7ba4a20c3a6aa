"""What a session's log carries, as the writers and the in-memory reader take it.

A structural type: :class:`dhlog.simulator.session.Session` (a simulated session with its truth)
is one, so the writers stand below the simulator and never import it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray


class RecordedStreams(Protocol):
    """The streams of one session: tracker samples ``point_t_ns`` / ``point_xyz`` (m, 3) in the
    measurement frame, a 6-DoF target's ``point_rotation`` (m, 3, 3) or None, further targets'
    ``extra_point_xyz``; encoder samples ``joint_t_ns`` / ``joint_q`` (chain order, names
    ``joint_names``); probed base points; ``phase`` markers (t_ns, joint or None)."""

    @property
    def robot_name(self) -> str: ...

    @property
    def joint_names(self) -> list[str]: ...

    @property
    def point_t_ns(self) -> NDArray[np.int64]: ...

    @property
    def point_xyz(self) -> FloatArray: ...

    @property
    def point_rotation(self) -> FloatArray | None: ...

    @property
    def extra_point_xyz(self) -> list[FloatArray]: ...

    @property
    def joint_t_ns(self) -> NDArray[np.int64]: ...

    @property
    def joint_q(self) -> FloatArray: ...

    @property
    def base_t_ns(self) -> NDArray[np.int64]: ...

    @property
    def base_xyz(self) -> FloatArray: ...

    @property
    def phase(self) -> list[tuple[int, int | None]]: ...
