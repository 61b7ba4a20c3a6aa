"""Deprecated: ``dhlog.identify.whole`` moved to :mod:`dhlog.identify.fit.whole` when
identify/ was grouped by stage; this path keeps working for one minor version with a
``DeprecationWarning`` (and is that module itself: its private names too)."""

import sys
import warnings

from dhlog.identify.fit import whole as _moved
from dhlog.identify.fit.whole import *  # noqa: F403

warnings.warn(
    "dhlog.identify.whole moved to dhlog.identify.fit.whole; import it from there",
    DeprecationWarning,
    stacklevel=2,
)
sys.modules[__name__] = _moved
