"""Deprecated since 0.2, removed in 0.3: ``dhlog.dhfile`` (``load_dh``, as an earlier README
documented it) is ``dhlog.io.dhfile`` now, private; use ``dhlog.load(path)`` (``import dhlog``).
This path warns once (a ``DeprecationWarning``) and is the moved module itself (its other names
too).
"""

import sys

from dhlog._deprecated import moved
from dhlog.io import dhfile as _moved
from dhlog.io.dhfile import *  # noqa: F403

moved("dhlog.dhfile", "dhlog.load(path)", now="dhlog.io.dhfile")
sys.modules[__name__] = _moved
