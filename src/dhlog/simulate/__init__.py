"""Deprecated since 0.2, removed in 0.3: the simulator's modules moved to ``dhlog.simulator``
(private), and ``dhlog.simulate`` is the function ``dhlog.simulate(robot, out, …)`` (``import
dhlog``). This package only hands on the module paths an earlier README documented
(``dhlog.simulate.config``, ``dhlog.simulate.camera``: each warns once); once one of them is
imported, Python binds ``dhlog.simulate`` to this package, so the package is callable and runs the
function.
"""

import sys
import types
from typing import Any


class _CallablePackage(types.ModuleType):
    """This package, callable as the function ``dhlog.simulate`` it stands in for."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        from dhlog.api.operations import simulate

        return simulate(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
