"""The README's two set-up commands are the ones CI runs, verbatim."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).parents[1]


def setup_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    section = text.split("## Set-up on a fresh machine", 1)[1].split("\n## ", 1)[0]
    return [block.strip() for block in re.findall(r"```sh\n(.*?)```", section, re.S)]


def test_readme_has_two_setup_commands_and_ci_runs_them() -> None:
    commands = setup_commands()
    assert len(commands) == 2
    assert "dhlog process sample_logs/" in commands[0]
    assert commands[1].endswith("pytest")
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    for command in commands:
        assert command in ci, command


def test_the_sample_log_of_the_readme_exists() -> None:
    log = re.search(r"dhlog process (\S+\.mcap)", setup_commands()[0])
    assert log is not None and (ROOT / log.group(1)).exists()
