"""The house of docs/architecture.md ("Layers"): every import inside dhlog goes to its own folder
or a lower one, and no modules import each other in a circle. Imports inside functions count. Its
module table names only modules that exist."""

import ast
from graphlib import TopologicalSorter
from pathlib import Path

SRC = Path(__file__).parents[1] / "src"
FLOORS = (
    "_version errors geometry model vision io identify result iso9283 simulator present"
    " fleet"
    " cell api cli entry __main__"
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
    """A module's folder, counted from the bottom (dhlog itself, the public names re-exported
    from api/ and below: api's floor)."""
    return FLOORS.split().index(name.split(".")[1] if "." in name else "api")


def test_imports_go_to_the_same_folder_or_a_lower_one() -> None:
    upward = [f"{m} → {t}" for m, ts in sorted(GRAPH.items()) for t in ts if floor(t) > floor(m)]
    assert not upward, "\n".join(upward)


def test_no_modules_import_each_other_in_a_circle() -> None:
    list(TopologicalSorter(GRAPH).static_order())  # a circle raises CycleError naming it


#: identify/ by stage (docs/architecture.md, "Layers"): a stage imports its own folder and the
#: stages below it; model/ and check/ stand side by side (neither imports the other), as do
#: options.py (what a run is asked) and stages.py (the frozen stage values and the result), then
#: the first fit as the clock leaves it (clocked.py), then camera/, the session (session.py), the
#: fit of the whole model (wholefit.py) and the held-out logs (heldout.py); run.py on top.
IDENTIFY_FLOORS = {
    "segment": 0,
    "joints": 1,
    "fit": 2,
    "read": 3,
    "model": 4,
    "check": 4,
    "options": 5,
    "stages": 5,
    "clocked": 6,
    "camera": 7,
    "wholefit": 7,
    "heldout": 7,
    "session": 7,
    "run": 8,
}


def test_identify_stages_import_only_their_own_or_lower_ones() -> None:
    def stage(name: str) -> int | None:
        parts = name.split(".")
        if parts[:2] != ["dhlog", "identify"] or len(parts) < 3:
            return None
        return IDENTIFY_FLOORS.get(parts[2])

    unplaced = [m for m in GRAPH if m.startswith("dhlog.identify.") and stage(m) is None]
    assert not unplaced, f"modules in no stage of identify/: {unplaced}"
    wrong = [
        f"{m} → {t}"
        for m, ts in sorted(GRAPH.items())
        for t in ts
        if stage(m) is not None
        and stage(t) is not None
        and (stage(t) > stage(m) or (stage(t) == stage(m) and m.split(".")[2] != t.split(".")[2]))
    ]
    assert not wrong, "\n".join(wrong)


def test_the_camera_is_one_package_read_through_the_result() -> None:
    """identify/camera/ is the camera's work, from its images to its calibration: only the run
    hands a log to it; the result document, the export, the certificate and the recording read
    what it found through the result (vision/'s blocks), never the package itself."""
    camera = "dhlog.identify.camera"
    outside = [
        f"{m} → {t}"
        for m, ts in sorted(GRAPH.items())
        for t in ts
        if (t == camera or t.startswith(camera + "."))
        and not (m == camera or m.startswith(camera + "."))
        and m != "dhlog.identify.run"
    ]
    assert not outside, "\n".join(outside)


def test_the_module_table_names_only_modules_that_exist() -> None:
    """docs/architecture.md's module table ("The modules, floor by floor") describes the house as
    it stands: a row whose module was split, moved or removed is stale."""
    import re

    doc = (SRC.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `(dhlog(?:\.[A-Za-z_0-9]+)+)`", doc, re.MULTILINE)
    assert len(rows) > 100, "the module table was not found"
    stale = sorted(set(rows) - MODULES.keys())
    assert not stale, f"rows naming no module of src/dhlog: {stale}"
