"""The documentation's Python runs as it is written: every ```python block of README.md and of
docs/**/*.md, executed from the repository's root, the blocks of one page in order in one
namespace (a fresh one per page). A block that needs data the repository does not hold is marked
with a ``<!-- no-run -->`` line right before its fence (sparingly: such a block is not checked).
The site itself (mkdocs.yml) is built with ``mkdocs build --strict`` in .ci/run."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
NO_RUN = "<!-- no-run -->"
FENCE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def python_blocks(text: str) -> list[tuple[int, str]]:
    """The page's ```python blocks as (line of the fence, code), those marked no-run left out."""
    found = []
    for match in FENCE.finditer(text):
        before = text[: match.start()].rstrip("\n").rsplit("\n", 1)[-1]
        if before.strip() != NO_RUN:
            found.append((text.count("\n", 0, match.start()) + 1, match.group(1)))
    return found


def test_blocks_are_found_and_no_run_is_honoured() -> None:
    text = "a\n```python\nx = 1\n```\n\n<!-- no-run -->\n```python\nraise SystemExit\n```\n"
    assert python_blocks(text) == [(2, "x = 1\n")]


RUNNABLE = [p for p in pages() if python_blocks(p.read_text(encoding="utf-8"))]


@pytest.mark.parametrize("page", RUNNABLE, ids=[str(p.relative_to(ROOT)) for p in RUNNABLE])
def test_the_pages_python_runs(page: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    (ROOT / "results").mkdir(exist_ok=True)  # where the examples write (ignored by git)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for line, code in python_blocks(page.read_text(encoding="utf-8")):
        where = f"{page.relative_to(ROOT)}:{line}"
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(code, where, "exec"), namespace)


def test_every_page_with_python_is_collected() -> None:
    """The README's example and the library pages are among the pages run (a fence written
    differently, e.g. ```py, would silently escape the test)."""
    names = {str(p.relative_to(ROOT)) for p in RUNNABLE}
    assert {"docs/api.md", "docs/camera.md"} <= names
    for page in pages():
        text = page.read_text(encoding="utf-8")
        assert not re.search(r"^```(py|python3|pycon)\s*$", text, re.M), page


def test_every_public_name_is_documented() -> None:
    """docs/api.md renders ``dhlog`` with mkdocstrings (``::: dhlog``, every member of
    ``__all__``; no ``members:`` list that could leave one out) and every public name has a
    docstring to render. A name that a subpackage of the same name would hide from ``::: dhlog``
    needs its own ``:::`` directive (none does); ``__version__`` is named in the text."""
    import inspect

    import dhlog

    page = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    directives = re.findall(r"^::: (\S+)\n((?:    .*\n|\n)*)", page, re.M)
    options = dict(directives)
    assert "dhlog" in options and "members:" not in options["dhlog"]
    for name in dhlog.__all__:
        if name.startswith("__"):
            assert f"dhlog.{name}" in page, name
            continue
        assert inspect.getdoc(getattr(dhlog, name)), f"dhlog.{name} has no docstring"
        src = ROOT / "src" / "dhlog"
        if (src / name).is_dir() or (src / f"{name}.py").exists():
            assert any(d.endswith(f".{name}") for d in options if d != "dhlog"), name
