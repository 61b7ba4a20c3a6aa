"""The deprecation notice of an old import path (one wording for every shim).

An import path a README of a release documented keeps working for one minor version after it
moves: the old module warns once, when first imported, and hands on the names from where they live
now. The notice names the public import to use (`import dhlog`) and, where the old names are private
now, the module that holds them until the removal (CHANGELOG.md, "Versioning").
"""

import warnings

#: The release that removes the old paths (deprecated in 0.2: one minor version).
REMOVED_IN = "0.3"


def moved(old: str, new: str, *, now: str) -> None:
    """Warn that module ``old`` is deprecated: use ``new`` (the public import, e.g.
    ``dhlog.robot(name)``); ``now`` is the private module that holds the old names meanwhile.

    Called at the top level of the shim module, so the warning points at the user's import (two
    frames up; the import machinery's own frames are skipped by ``warnings``).
    """
    warnings.warn(
        f"{old} is deprecated and will be removed in {REMOVED_IN}: use {new} (`import dhlog`); "
        f"meanwhile its names are in {now} (private: it may move without notice)",
        DeprecationWarning,
        stacklevel=3,
    )
