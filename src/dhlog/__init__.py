"""dhlog: exact Denavit–Hartenberg parameters from robot calibration logs."""

from __future__ import annotations

__all__ = ["__version__"]


def __getattr__(name: str) -> str:
    """``__version__`` on first use (the console entry point imports nothing heavy before it
    handles signals)."""
    if name != "__version__":
        raise AttributeError(name)
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dhlog")
    except PackageNotFoundError:  # running from a source tree without installation
        return "0.0.0+unknown"
