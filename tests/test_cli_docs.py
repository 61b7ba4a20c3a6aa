"""docs/cli.md against the command line it documents: one section per command (``## dhlog
NAME``) opening with a ``text`` synopsis block whose lines fit the site's code width, every option
named in a synopsis an option of that command, every option of the command named in its section,
and no Markdown-escaped pipe (a ``\\|`` in a table's code cell is shown as written: synopses live
in code blocks, where ``|`` needs no escape)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from typer.main import get_command

from dhlog.cli.app import app

PAGE = Path(__file__).parents[1] / "docs" / "cli.md"
SECTION = re.compile(r"^## dhlog (\S+)\n(.*?)(?=^## |\Z)", re.S | re.M)
SYNOPSIS = re.compile(r"\A\s*```text\n(.*?)^```", re.S | re.M)
OPTION = re.compile(r"(?<![\w-])(--[a-z0-9][a-z0-9-]*|-[a-z])\b")
#: characters of a code block's line the site shows without scrolling (1400 px wide window)
WIDTH = 76
#: commands whose section names the main options and leaves the rest to ``--help`` (it says so)
SOME_OPTIONS = {"simulate"}

COMMANDS: dict[str, Any] = dict(get_command(app).commands)  # type: ignore[attr-defined]
SECTIONS = dict(SECTION.findall(PAGE.read_text(encoding="utf-8")))


def _options(command: Any) -> list[set[str]]:
    """Each visible option's names (``{"--output", "-o"}``), ``--help`` left out."""
    return [
        set(p.opts)
        for p in command.params
        if p.param_type_name == "option" and not p.hidden and "--help" not in p.opts
    ]


def test_a_section_per_command() -> None:
    assert sorted(SECTIONS) == sorted(COMMANDS)


def test_no_escaped_pipe() -> None:
    assert "\\|" not in PAGE.read_text(encoding="utf-8")


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_the_synopsis_names_real_options(name: str) -> None:
    synopsis = SYNOPSIS.match(SECTIONS.get(name, ""))
    assert synopsis, f"docs/cli.md: the section of dhlog {name} opens with no ```text synopsis"
    lines = [line for line in synopsis.group(1).splitlines() if line.startswith("dhlog ")]
    assert lines and all(f"{line} ".startswith(f"dhlog {name} ") for line in lines), lines
    too_long = [line for line in synopsis.group(1).splitlines() if len(line) > WIDTH]
    assert not too_long, f"dhlog {name}: synopsis lines over {WIDTH} characters: {too_long}"
    known = set().union(*_options(COMMANDS[name]))
    named = set(OPTION.findall(synopsis.group(1)))
    assert not named - known, f"dhlog {name} has no {sorted(named - known)}"


@pytest.mark.parametrize("name", sorted(set(COMMANDS) - SOME_OPTIONS))
def test_every_option_is_in_its_section(name: str) -> None:
    named = set(OPTION.findall(SECTIONS.get(name, "")))
    missing = [sorted(opts) for opts in _options(COMMANDS[name]) if not opts & named]
    assert not missing, f"docs/cli.md, dhlog {name}: {missing} not documented"
