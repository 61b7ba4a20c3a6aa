"""The house of docs/architecture.md ("Layers"): every import inside dhlog goes to its own folder
or a lower one, and no modules import each other in a circle. Imports inside functions count."""

import ast
from graphlib import TopologicalSorter
from pathlib import Path

SRC = Path(__file__).parents[1] / "src"
FLOORS = (
    "errors geometry model vision io identify result simulate present fleet cell cli entry __main__"
)
MODULES = {
    ".".join(path.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__"): path
    for path in (SRC / "dhlog").rglob("*.py")
}


def imported(path: Path) -> set[str]:
    """The dhlog modules a file imports (`from dhlog.io import ros2`: dhlog.io.ros2)."""
    parts, found = path.relative_to(SRC).with_suffix("").parts, set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            prefix = parts[: -node.level] if node.level else ()
            base = ".".join([*prefix, node.module or ""]).strip(".")
            named = {f"{base}.{alias.name}" for alias in node.names}
            found |= (named & MODULES.keys()) | ({base} if named - MODULES.keys() else set())
    return {name for name in found if name.split(".")[0] == "dhlog"}


GRAPH = {name: imported(path) - {name} for name, path in MODULES.items()}


def floor(name: str) -> int:
    """A module's folder, counted from the bottom (dhlog itself, only `__version__`: -1)."""
    return FLOORS.split().index(name.split(".")[1]) if "." in name else -1


def test_imports_go_to_the_same_folder_or_a_lower_one() -> None:
    upward = [f"{m} → {t}" for m, ts in sorted(GRAPH.items()) for t in ts if floor(t) > floor(m)]
    assert not upward, "\n".join(upward)


def test_no_modules_import_each_other_in_a_circle() -> None:
    list(TopologicalSorter(GRAPH).static_order())  # a circle raises CycleError naming it
