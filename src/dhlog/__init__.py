"""dhlog: exact Denavit–Hartenberg parameters from robot calibration logs."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("dhlog")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
