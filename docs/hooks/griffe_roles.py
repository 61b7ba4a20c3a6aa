"""A griffe extension for the API page (mkdocs.yml): the docstrings' Sphinx roles
(:func:`process`, :class:`~dhlog.Compensation`, :attr:`covariance`) rendered as code, and as a
link where the target is a public name of ``dhlog`` (``__all__``), which docs/api.md documents."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?[a-z]+:`(~?)([A-Za-z_][\w.]*)(\(\))?`")
SRC = Path(__file__).resolve().parents[2] / "src" / "dhlog"


def _public() -> frozenset[str]:
    for node in ast.parse((SRC / "__init__.py").read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            return frozenset(ast.literal_eval(node.value))
    return frozenset()


PUBLIC = _public()


def _rewrite(match: re.Match[str]) -> str:
    tilde, target, call = match.group(1), match.group(2), match.group(3) or ""
    shown = (target.rsplit(".", 1)[-1] if tilde else target) + call
    name = target.removeprefix("dhlog.")
    if name in PUBLIC:
        return f"[`{shown}`][dhlog.{name}]"
    return f"`{shown}`"


def rewrite(text: str) -> str:
    """``text`` with every Sphinx role as Markdown code (a link for a public name)."""
    return ROLE.sub(_rewrite, text)


class SphinxRoles(griffe.Extension):
    """Rewrites each docstring's roles before mkdocstrings renders it."""

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = rewrite(obj.docstring.value)
