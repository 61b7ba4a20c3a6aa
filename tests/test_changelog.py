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


def test_deprecations_are_removed_one_minor_version_on() -> None:
    """The deprecation notices (dhlog._deprecated) and the changelog name the same removal: the
    minor version after the newest release."""
    from dhlog._deprecated import REMOVED_IN

    major, minor, _ = RELEASED[0][0].split(".")
    assert REMOVED_IN == f"{major}.{int(minor) + 1}"
    newest = CHANGELOG.split("\n## [")[2]  # the newest release's section
    assert f"will be removed in {REMOVED_IN}" in newest
