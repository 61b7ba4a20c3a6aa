"""The version lives in pyproject.toml and moves with releases (issue 33, item 2): CHANGELOG.md's
newest release is that version, ``dhlog.__version__`` reads it from the installed package, and the
changelog keeps Keep a Changelog 1.1.0's form. A version bumped without its changelog entry (or the
reverse, or a package not reinstalled after the bump) fails here."""

import re
import tomllib
from datetime import date
from importlib.metadata import version as installed
from pathlib import Path

import dhlog

ROOT = Path(__file__).parents[1]
CHANGELOG = (ROOT / "CHANGELOG.md").read_text()
HEADINGS = re.findall(r"^## \[([^\]]+)\](?: - (\S+))?$", CHANGELOG, flags=re.MULTILINE)
RELEASED = [(v, d) for v, d in HEADINGS if v != "Unreleased"]
#: Keep a Changelog 1.1.0's kinds of change
KINDS = {"Added", "Changed", "Deprecated", "Removed", "Fixed", "Security"}


def test_the_newest_release_is_the_version_of_pyproject_and_of_the_package() -> None:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    newest, _ = RELEASED[0]
    assert newest == pyproject == dhlog.__version__ == installed("dhlog"), (
        "bump pyproject.toml and CHANGELOG.md together, then reinstall (pip install -e . --no-deps)"
    )


def test_the_changelog_has_keep_a_changelogs_form() -> None:
    assert HEADINGS[0] == ("Unreleased", ""), "## [Unreleased] comes first"
    assert len(HEADINGS) == len(re.findall(r"^## ", CHANGELOG, flags=re.MULTILINE))
    versions = [tuple(int(p) for p in v.split(".")) for v, _ in RELEASED]
    assert all(len(v) == 3 for v in versions), "semantic versions: MAJOR.MINOR.PATCH"
    assert versions == sorted(versions, reverse=True) and len(set(versions)) == len(versions)
    dates = [date.fromisoformat(d) for _, d in RELEASED]  # ISO 8601, as the format asks
    assert dates == sorted(dates, reverse=True)
    kinds = set(re.findall(r"^### (.+)$", CHANGELOG, flags=re.MULTILINE))
    assert kinds <= KINDS, kinds - KINDS


def sections() -> dict[str, str]:
    """Each heading's text ("Unreleased", "0.2.0", …) to its section's body."""
    parts = re.split(r"^## \[([^\]]+)\].*$", CHANGELOG, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


def kind(body: str, name: str) -> str:
    """The ``### name`` subsection of a section ("" if it has none)."""
    parts = re.split(r"^### (.+)$", body, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2], strict=True)).get(name, "")


def first_column_paths(table: str) -> set[str]:
    """The import paths (`dhlog.…`) in the first column of a Markdown table's rows."""
    rows = [line.split("|")[1] for line in table.splitlines() if line.strip().startswith("|")]
    return {path for row in rows for path in re.findall(r"`(dhlog(?:\.\w+)+)`", row)}


def test_deprecations_are_removed_one_minor_version_on() -> None:
    """What a release deprecated ("will be removed in X.Y") goes in the release X.Y: once X.Y is
    the next minor version (the unreleased section) or released, its "Removed" lists every path
    of the deprecation's table, and each fails to import."""
    import importlib
    import sys

    by_version = sections()
    major, minor, _ = RELEASED[0][0].split(".")
    upcoming = f"{major}.{int(minor) + 1}"
    checked = 0
    for version, body in by_version.items():
        deprecated = kind(body, "Deprecated")
        due = re.search(r"will be removed in (\d+\.\d+)", deprecated)
        if version == "Unreleased" or not deprecated or due is None:
            continue
        paths = first_column_paths(deprecated)
        assert paths, f"{version}'s Deprecated names no import path"
        home = "Unreleased" if due[1] == upcoming else f"{due[1]}.0"
        if home not in by_version:
            continue  # due later than the next minor version
        removed = first_column_paths(kind(by_version[home], "Removed"))
        missing = paths - removed
        assert not missing, f"deprecated in {version}, not removed in {home}: {missing}"
        for path in sorted(paths):
            sys.modules.pop(path, None)
            try:
                importlib.import_module(path)
            except ModuleNotFoundError:
                checked += 1
            else:
                raise AssertionError(f"{path} still imports; the changelog says it is removed")
    assert checked >= 12, "0.2.0 deprecated twelve import paths"
