"""Deprecated since 0.2, removed in 0.3: ``dhlog.segment`` (``segment_log``, as an earlier README
documented it) is ``dhlog.identify.segment.segment`` now, private; use ``dhlog.process(log, ...)``
(``import dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself
(its other names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.identify.segment import segment as _moved
from dhlog.identify.segment.segment import *  # noqa: F403

moved("dhlog.segment", "dhlog.process(log, ...)", now="dhlog.identify.segment.segment")
sys.modules[__name__] = _moved
