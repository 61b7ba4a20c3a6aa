"""Deprecated since 0.2, removed in 0.3: ``dhlog.extract`` (``extract_dh``, as an earlier README
documented it) is ``dhlog.identify.read.extract`` now, private; use ``dhlog.extract_dh`` (``import
dhlog``). This path warns once (a ``DeprecationWarning``) and is the moved module itself (its other
names too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.identify.read import extract as _moved
from dhlog.identify.read.extract import *  # noqa: F403

moved("dhlog.extract", "dhlog.extract_dh", now="dhlog.identify.read.extract")
sys.modules[__name__] = _moved
