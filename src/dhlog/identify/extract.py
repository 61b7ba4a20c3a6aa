"""Deprecated: ``dhlog.identify.extract`` moved to :mod:`dhlog.identify.read.extract` when
identify/ was grouped by stage; this path keeps working for one minor version with a
``DeprecationWarning`` (and is that module itself: its private names too)."""

import sys
import warnings

from dhlog.identify.read import extract as _moved
from dhlog.identify.read.extract import *  # noqa: F403

warnings.warn(
    "dhlog.identify.extract moved to dhlog.identify.read.extract; import it from there",
    DeprecationWarning,
    stacklevel=2,
)
sys.modules[__name__] = _moved
