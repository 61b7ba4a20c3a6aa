"""A mkdocs hook (mkdocs.yml ``hooks:``): the notebook pages with their outputs.

The repository keeps docs/notebooks/*.ipynb without outputs (tests/test_notebooks.py). At each
build this hook executes every notebook of the nav with docs/notebooks/run.py (a fresh kernel,
the repository's root as working directory, the bundled sample logs) into a temporary folder
and hands the executed copy to mkdocs-jupyter, which renders it (``execute: false``) and offers
it for download. A cell's error fails the build, and so does a file a notebook left in the
repository. The site therefore shows what the code of this checkout prints and plots.

A widget output (the Rerun viewer of ``notebook_show``) needs a live kernel and would bring the
viewer's code into the page: on the site it is replaced by the figure the cell's metadata names,
``{"dhlog": {"site_figure": {"src": "images/….png", "caption": "…"}}}`` (a path in docs/); a
widget output without one fails the build.

``DHLOG_DOCS_NOTEBOOKS=stored mkdocs serve`` renders the notebooks as stored (no outputs, no
kernel: for editing prose). Under ``mkdocs serve`` a notebook is executed again only when its
file changed.
"""

from __future__ import annotations

import hashlib
import html
import importlib.util
import logging
import os
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

import mkdocs.plugins
from mkdocs.config.defaults import MkDocsConfig
from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files
from mkdocs.utils import get_relative_url

log = logging.getLogger("mkdocs.hooks.notebooks")

RUN = Path(__file__).resolve().parents[1] / "notebooks" / "run.py"
WIDGET = "application/vnd.jupyter.widget-view+json"
#: seconds a cell may take
TIMEOUT = 300

#: sha256 of a notebook as stored → its executed copy (``mkdocs serve`` rebuilds reuse it)
_executed: dict[str, Path] = {}
_folder = tempfile.TemporaryDirectory(prefix="dhlog-docs-notebooks-")


def _run() -> ModuleType:
    spec = importlib.util.spec_from_file_location("dhlog_docs_notebooks_run", RUN)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _figure(cell: Any, where: str, page_url: str, files: Files) -> dict[str, Any]:
    """The display output that stands for ``cell``'s widget outputs on the site."""
    figure = cell.metadata.get("dhlog", {}).get("site_figure")
    if not figure or "src" not in figure:
        raise PluginError(
            f"{where}: a widget output cannot be shown on a static page: name a figure in the "
            'cell\'s metadata, {"dhlog": {"site_figure": {"src": "images/….png", "caption": '
            '"…"}}}.'
        )
    if files.get_file_from_path(figure["src"]) is None:
        raise PluginError(f"{where}: the site figure {figure['src']} is not in docs/.")
    src = html.escape(get_relative_url(figure["src"], page_url))
    caption = html.escape(figure.get("caption", ""))
    return {
        "output_type": "display_data",
        "metadata": {},
        "data": {
            "text/html": (
                f'<figure><img src="{src}" alt="{caption}" style="max-width: 100%">'
                f"<figcaption>{caption}</figcaption></figure>"
            ),
            "text/plain": caption,
        },
    }


def for_the_site(path: Path, page_url: str, files: Files) -> None:
    """Rewrite the executed notebook at ``path`` for the page at ``page_url``: each cell's widget
    outputs replaced by one figure, the widget state dropped."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    for i, cell in enumerate(nb.cells):
        outputs = cell.get("outputs", [])
        if not any(WIDGET in o.get("data", {}) for o in outputs):
            continue
        figure = nbformat.from_dict(_figure(cell, f"{path.name}, cell {i}", page_url, files))
        kept = [o for o in outputs if WIDGET not in o.get("data", {})]
        first = next(k for k, o in enumerate(outputs) if WIDGET in o.get("data", {}))
        cell.outputs = [*kept[:first], figure, *kept[first:]]
    nb.metadata.pop("widgets", None)
    nbformat.write(nb, path)


def _execute(run: ModuleType, file: File, files: Files) -> Path:
    source = Path(str(file.abs_src_path))
    key = hashlib.sha256(source.read_bytes()).hexdigest()
    if key in _executed:
        return _executed[key]
    # under a folder named notebooks/, so that mkdocs-jupyter's include pattern still matches
    folder = Path(_folder.name) / key[:16] / "notebooks"
    from nbclient.exceptions import CellExecutionError

    try:
        took = run.execute(source, folder, TIMEOUT)
    except CellExecutionError as exc:
        raise PluginError(f"{file.src_uri}: a cell failed:\n{exc}") from exc
    log.info("%s: executed in %.1f s", file.src_uri, took)
    executed = folder / source.name
    for_the_site(executed, file.url, files)
    _executed[key] = executed
    return executed


@mkdocs.plugins.event_priority(-100)  # after mkdocs-jupyter has taken the notebooks as pages
def on_files(files: Files, config: MkDocsConfig) -> Files:
    """Point every notebook page at its executed copy."""
    if os.environ.get("DHLOG_DOCS_NOTEBOOKS") == "stored":
        log.info("DHLOG_DOCS_NOTEBOOKS=stored: the notebooks are rendered without outputs")
        return files
    notebooks = [f for f in files if f.src_uri.endswith(".ipynb")]
    if not notebooks:
        return files
    run = _run()
    before = run.files_in_reach()
    for file in notebooks:
        file.abs_src_path = str(_execute(run, file, files))
    left = sorted(str(p.relative_to(run.ROOT)) for p in run.files_in_reach() - before)
    if left:
        raise PluginError(f"the notebooks left files in the repository: {', '.join(left)}")
    return files
