"""Deprecated since 0.2, removed in 0.3: ``dhlog.simulate.camera`` (as an earlier README documented
it) is ``dhlog.simulator.camera`` now, private; use ``dhlog.simulate(robot, out, …)`` (``import
dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself.
"""

import sys

from dhlog._deprecated import moved
from dhlog.simulator import camera as _moved
from dhlog.simulator.camera import *  # noqa: F403

moved("dhlog.simulate.camera", "dhlog.simulate(robot, out, ...)", now="dhlog.simulator.camera")
sys.modules[__name__] = _moved
