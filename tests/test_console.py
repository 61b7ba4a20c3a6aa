"""The console report (``dhlog.present.console``): user text — joint names, the nominal's source,
notes, warnings, a failed joint's reason — prints as it is and on one line, never as rich markup
or terminal control."""

from __future__ import annotations

import dataclasses
import io
from pathlib import Path

import pytest
from rich.console import Console

from dhlog.errors import Note
from dhlog.identify.run import Identification, ProcessOptions, process_log
from dhlog.io.dhfile import load_dh
from dhlog.present.console import print_result
from dhlog.present.console.layout import NAME_WIDTH, literal, short_name

SAMPLES = Path(__file__).parents[1] / "sample_logs"

#: Joint names a pipeline or a log could carry: markup, an unbalanced closing tag (rich raises
#: MarkupError on it when parsed), a terminal escape, a line break, a trailing backslash.
HOSTILE = ("[bold]x[/]", "[/]", "a\x1b[31mb", "one\ntwo", "back\\", "[link=x]y")


@pytest.mark.parametrize(
    ("text", "printed"),
    [
        ("plain", "plain"),
        ("[bold]x[/]", "[bold]x[/]"),
        ("[/]", "[/]"),
        ("a\x1b[2Jb", "a\\x1b[2Jb"),
        ("one\ntwo", "one\\x0atwo"),
        ("back\\", "back\\"),
        ("two\\\\", "two\\\\"),
        ("\\[bold]", "\\[bold]"),
    ],
)
def test_literal_prints_user_text_as_it_is_on_one_line(text: str, printed: str) -> None:
    out = io.StringIO()
    Console(file=out, width=200, emoji=False).print(literal(text))
    assert out.getvalue() == printed + "\n"
    out = io.StringIO()
    Console(file=out, width=200, emoji=False).print(f"({literal(text)})")
    assert out.getvalue() == f"({printed})\n"


def test_a_long_name_is_cut_after_its_controls_are_made_visible() -> None:
    out = io.StringIO()
    Console(file=out, width=200).print(short_name("\x1b" * 10))
    assert out.getvalue() == ("\\x1b" * 5)[: NAME_WIDTH - 1] + "…\n"


@pytest.fixture(scope="module")
def hostile() -> Identification:
    """kr5_0.1mm with its truth as nominal, every user text replaced by a hostile one."""
    log = SAMPLES / "kr5_0.1mm.mcap"
    result = process_log(
        log, ProcessOptions(nominal=load_dh(log.with_name(log.stem + ".truth.json")))
    )
    assert result.nominal is not None
    joints = [
        dataclasses.replace(joint, name=name)
        for joint, name in zip(result.joints, HOSTILE, strict=True)
    ]
    joints[-1] = dataclasses.replace(joints[-1], reason="[i]why[/]\nnext\\")
    session = dataclasses.replace(
        result.session,
        joints=tuple(joints),
        nominal=dataclasses.replace(result.nominal, source="[red]nominal[/]\r"),
    )
    return dataclasses.replace(
        result,
        session=session,
        notes=(
            *result.notes,
            Note.info("note [bold]n[/] \x1b[2J end", "test"),
            Note.warning("warn [/] end\\", "test"),
        ),
    )


def test_print_result_prints_user_text_literally(hostile: Identification) -> None:
    out = io.StringIO()
    print_result(Console(file=out, width=100, emoji=False), hostile)
    text = out.getvalue()
    assert "\x1b" not in text and "\r" not in text
    for shown in ("[bold]x[/]", "[/]", "a\\x1b[31mb", "one\\x0atwo"):
        # the DH table, measured − nominal and the fits each show the identified joints
        assert text.count(shown) >= 3, shown
    assert text.count("back\\ ") >= 3 and "back\\\\" not in text
    assert "Measured − nominal ([red]nominal[/]\\x0d)" in text
    assert "joint 6 ([link=x]y) not identified: [i]why[/]\\x0anext\\" in text
    assert "note [bold]n[/] \\x1b[2J end" in text
    assert "Warning: warn [/] end\\" in text and "end\\\\" not in text
