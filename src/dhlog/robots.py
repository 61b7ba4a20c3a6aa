"""Deprecated since 0.2, removed in 0.3: ``dhlog.robots`` (``load_robot``, as an earlier README
documented it) is ``dhlog.model.robots`` now, private; use ``dhlog.robot(name)`` (``import
dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself (its other
names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.model import robots as _moved
from dhlog.model.robots import *  # noqa: F403

moved("dhlog.robots", "dhlog.robot(name)", now="dhlog.model.robots")
sys.modules[__name__] = _moved
