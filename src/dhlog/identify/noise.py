"""Deprecated since 0.2, removed in 0.3: ``dhlog.identify.noise`` (``NoiseModel``, as an earlier
README documented it) is ``dhlog.model.noise`` now, private; use ``dhlog.process(log, ...)``
(``import dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself
(its other names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.model import noise as _moved
from dhlog.model.noise import *  # noqa: F403

moved("dhlog.identify.noise", "dhlog.process(log, ...)", now="dhlog.model.noise")
sys.modules[__name__] = _moved
