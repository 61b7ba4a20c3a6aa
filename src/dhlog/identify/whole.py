"""Deprecated since 0.2, removed in 0.3: ``dhlog.identify.whole`` (``fit_whole_model, AxisModel``,
as an earlier README documented it) is ``dhlog.identify.fit.whole`` now, private; use
``dhlog.process(log, ...)`` (``import dhlog``). This path warns once (a ``DeprecationWarning``) and
is the moved module itself (its other names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.identify.fit import whole as _moved
from dhlog.identify.fit.whole import *  # noqa: F403

moved("dhlog.identify.whole", "dhlog.process(log, ...)", now="dhlog.identify.fit.whole")
sys.modules[__name__] = _moved
