"""Execute the notebooks of docs/notebooks/ (CI's step; needs the notebooks extra:
``.venv/bin/pip install -e '.[notebooks]'``), or strip their outputs before a commit.

    .venv/bin/python docs/notebooks/run.py                  # execute every notebook
    .venv/bin/python docs/notebooks/run.py compare_sessions.ipynb --executed /tmp/nb
    .venv/bin/python docs/notebooks/run.py --strip          # strip outputs in place

Each notebook runs in a fresh kernel with the repository's root as its working directory (the
notebooks read ``sample_logs/...``); its time is printed. Any cell's error fails the run (exit 1)
and so does a file a notebook left in the repository (the notebooks write into temporary
folders only). The executed copies are not kept unless ``--executed DIR`` is given: the
repository holds the notebooks without outputs (tests/test_notebooks.py checks it). The site's
build executes them the same way (docs/hooks/notebooks.py calls :func:`execute`) and renders the
executed copies: CI's run of the notebooks is that build."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def strip(path: Path) -> bool:
    """Remove the outputs, execution counts and run metadata of ``path`` in place; True when
    it changed."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    before = nbformat.writes(nb)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs = []
            cell.execution_count = None
        for key in ("execution", "collapsed", "scrolled", "ExecuteTime"):
            cell.metadata.pop(key, None)
    nb.metadata.pop("widgets", None)
    after = nbformat.writes(nb)
    if after != before:
        path.write_text(after, encoding="utf-8")
    return after != before


def files_in_reach() -> set[Path]:
    """The files a notebook writing into the working directory would leave: the root's, and
    those of docs/notebooks/ and sample_logs/."""
    found = {p for p in ROOT.iterdir() if p.is_file()}
    for folder in (HERE, ROOT / "sample_logs"):
        found |= {p for p in folder.rglob("*") if "__pycache__" not in p.parts}
    return found


def execute(path: Path, executed: Path | None, timeout: int) -> float:
    """Run ``path`` from the repository's root; seconds taken. Raises on a cell's error."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        resources={"metadata": {"path": str(ROOT)}},
    )
    start = time.perf_counter()
    client.execute()
    took = time.perf_counter() - start
    if executed is not None:
        executed.mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, executed / path.name)
    return took


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("notebooks", nargs="*", type=Path, help="default: every *.ipynb here")
    parser.add_argument("--strip", action="store_true", help="strip outputs in place; no run")
    parser.add_argument("--executed", type=Path, help="write the executed notebooks here")
    parser.add_argument("--timeout", type=int, default=300, help="seconds a cell may take")
    args = parser.parse_args(argv)
    paths = [HERE / p.name if not p.exists() else p for p in args.notebooks] or sorted(
        HERE.glob("*.ipynb")
    )
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        print(f"run.py: no such notebook: {', '.join(missing)}", file=sys.stderr)
        return 2
    if args.strip:
        for path in paths:
            print(f"{path.name}: {'stripped' if strip(path) else 'already clean'}")
        return 0
    from nbclient.exceptions import CellExecutionError

    before = files_in_reach()
    total = 0.0
    failed = []
    for path in paths:
        try:
            took = execute(path, args.executed, args.timeout)
        except CellExecutionError as exc:
            print(f"{path.name}: FAILED\n{exc}", file=sys.stderr)
            failed.append(path.name)
            continue
        total += took
        print(f"{path.name}: {took:.1f} s", flush=True)
    left = sorted(str(p.relative_to(ROOT)) for p in files_in_reach() - before)
    if left:
        print(f"the notebooks left files in the repository: {', '.join(left)}", file=sys.stderr)
        return 1
    if failed:
        print(f"{len(failed)} notebook(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"{len(paths)} notebooks executed in {total:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
