"""Deprecated since 0.2, removed in 0.3: ``dhlog.identify.axismodel`` (``AxisModel``, as an earlier
README documented it) is ``dhlog.identify.fit.axismodel`` now, private; use ``dhlog.process(log,
...)`` (``import dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module
itself (its other names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.identify.fit import axismodel as _moved
from dhlog.identify.fit.axismodel import *  # noqa: F403

moved("dhlog.identify.axismodel", "dhlog.process(log, ...)", now="dhlog.identify.fit.axismodel")
sys.modules[__name__] = _moved
