"""The notebooks of docs/notebooks/ as the repository keeps them: without outputs (CI executes
them: ``python docs/notebooks/run.py``; strip before a commit with ``--strip``) and written
against the public API alone (``import dhlog`` and its ``__all__``), as a user's code is.

Executing them is not a test here (seconds each, and a kernel): the site's build does it
(docs/hooks/notebooks.py, ``mkdocs build --strict`` in .ci/run), and renders their outputs."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import pytest

import dhlog

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "docs" / "notebooks").glob("*.ipynb"))

#: what a notebook may import besides the standard library
ALLOWED = {"dhlog", "numpy", "polars", "matplotlib", "rerun"}


def _read(path: Path) -> dict[str, object]:
    data = json.loads(path.read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def _code(path: Path) -> list[str]:
    cells = _read(path)["cells"]
    assert isinstance(cells, list)
    return ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]


def test_the_notebooks_are_there() -> None:
    names = {p.name for p in NOTEBOOKS}
    assert {
        "process_a_session.ipynb",
        "compare_sessions.ipynb",
        "compensate_targets.ipynb",
    } <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_no_outputs_in_the_repository(path: Path) -> None:
    nb = _read(path)
    assert nb["nbformat"] == 4
    cells = nb["cells"]
    assert isinstance(cells, list) and cells
    for i, cell in enumerate(cells):
        if cell["cell_type"] != "code":
            continue
        assert cell["outputs"] == [], f"{path.name}: cell {i} has outputs (run.py --strip)"
        assert cell["execution_count"] is None, f"{path.name}: cell {i} has an execution count"
    metadata = nb["metadata"]
    assert isinstance(metadata, dict)
    assert "widgets" not in metadata, f"{path.name}: widget state saved (run.py --strip)"
    assert metadata["kernelspec"]["name"] == "python3"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_only_the_public_api(path: Path) -> None:
    """No private module of dhlog, and every ``dhlog.X`` a public name."""
    import sys

    stdlib = sys.stdlib_module_names
    for source in _code(path):
        tree = ast.parse(source)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                modules = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                modules = [node.module or ""]
                if node.module == "dhlog":
                    assert all(a.name in dhlog.__all__ for a in node.names), ast.unparse(node)
            else:
                if (
                    isinstance(node, ast.Attribute)
                    and isinstance(node.value, ast.Name)
                    and node.value.id == "dhlog"
                ):
                    assert node.attr in dhlog.__all__, f"{path.name}: dhlog.{node.attr}"
                continue
            for module in modules:
                assert not module.startswith("dhlog."), f"{path.name}: {ast.unparse(node)}"
                top = module.split(".")[0]
                assert top in ALLOWED or top in stdlib, f"{path.name}: imports {module}"


def test_the_public_api_check_can_fail(tmp_path: Path) -> None:
    """The check above rejects a private import and a name outside ``__all__``."""
    source = "from dhlog.model.fk import fk_point\nimport dhlog\ndhlog.identify\n"
    tree = ast.parse(source)
    private = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert private[0].module is not None and private[0].module.startswith("dhlog.")
    assert "identify" not in dhlog.__all__
    notebook = {
        "nbformat": 4,
        "nbformat_minor": 5,
        "metadata": {"kernelspec": {"name": "python3"}},
        "cells": [{"cell_type": "code", "source": [source], "outputs": [], "metadata": {}}],
    }
    path = tmp_path / "bad.ipynb"
    path.write_text(json.dumps(notebook), encoding="utf-8")
    with pytest.raises(AssertionError, match=r"dhlog\.model\.fk"):
        test_only_the_public_api(path)
    notebook["cells"][0]["source"] = ["import dhlog\nx = dhlog.identify\n"]  # type: ignore[index]
    path.write_text(json.dumps(notebook), encoding="utf-8")
    with pytest.raises(AssertionError, match=r"dhlog\.identify"):
        test_only_the_public_api(path)
    notebook["cells"][0]["outputs"] = [{"output_type": "stream", "text": "x"}]  # type: ignore[index]
    path.write_text(json.dumps(notebook), encoding="utf-8")
    with pytest.raises(AssertionError, match="has outputs"):
        test_no_outputs_in_the_repository(path)
