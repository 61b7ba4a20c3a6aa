"""The installed package's version (``dhlog.__version__``), read from its metadata on first use:
the console entry point imports nothing heavy before it handles signals."""

from __future__ import annotations

from functools import cache


@cache
def version() -> str:
    """The version pyproject.toml gives (``0.0.0+unknown`` in a source tree never installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("dhlog")
    except PackageNotFoundError:
        return "0.0.0+unknown"


def __getattr__(name: str) -> str:
    if name != "__version__":
        raise AttributeError(name)
    return version()
