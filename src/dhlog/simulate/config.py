"""Deprecated since 0.2, removed in 0.3: ``dhlog.simulate.config`` (as an earlier README documented
it) is ``dhlog.simulator.config`` now, private; use ``dhlog.simulate(robot, out, …)`` (``import
dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself.
"""

import sys

from dhlog._deprecated import moved
from dhlog.simulator import config as _moved
from dhlog.simulator.config import *  # noqa: F403

moved("dhlog.simulate.config", "dhlog.simulate(robot, out, ...)", now="dhlog.simulator.config")
sys.modules[__name__] = _moved
