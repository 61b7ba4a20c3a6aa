"""Deprecated: ``dhlog.identify.axismodel`` moved to :mod:`dhlog.identify.fit.axismodel` when
identify/ was grouped by stage; this path keeps working for one minor version with a
``DeprecationWarning`` (and is that module itself: its private names too)."""

import sys
import warnings

from dhlog.identify.fit import axismodel as _moved
from dhlog.identify.fit.axismodel import *  # noqa: F403

warnings.warn(
    "dhlog.identify.axismodel moved to dhlog.identify.fit.axismodel; import it from there",
    DeprecationWarning,
    stacklevel=2,
)
sys.modules[__name__] = _moved
