"""Deprecated since 0.2, removed in 0.3: ``dhlog.kinematics`` (``fk_point``, as an earlier README
documented it) is ``dhlog.model.fk`` now, private; use ``dhlog.fk_point`` (``import dhlog``). This
path warns once (a ``DeprecationWarning``) and is the moved module itself (its other names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.model import fk as _moved
from dhlog.model.fk import *  # noqa: F403

moved("dhlog.kinematics", "dhlog.fk_point", now="dhlog.model.fk")
sys.modules[__name__] = _moved
