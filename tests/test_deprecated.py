"""The import paths an earlier README documented keep working for one minor version (issue 33,
item 2; CHANGELOG.md, "Versioning"): each warns once, naming the public import to use and the
module that holds its names now, and hands on the very objects that live there."""

import ast
import importlib
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

SRC = Path(__file__).parents[1] / "src"

#: old path, the names a README imported from it, the public import the notice names, where the
#: names live now (private). Found from every version of README.md (`git log -- README.md`).
OLD_PATHS = [
    ("dhlog.kinematics", ["fk_point"], "dhlog.fk_point", "dhlog.model.fk"),
    ("dhlog.extract", ["extract_dh"], "dhlog.extract_dh", "dhlog.identify.read.extract"),
    ("dhlog.robots", ["load_robot"], "dhlog.robot(name)", "dhlog.model.robots"),
    ("dhlog.dhfile", ["load_dh"], "dhlog.load(path)", "dhlog.io.dhfile"),
    ("dhlog.segment", ["segment_log"], "dhlog.process(log, ...)", "dhlog.identify.segment.segment"),
    ("dhlog.identify.noise", ["NoiseModel"], "dhlog.process(log, ...)", "dhlog.model.noise"),
    (
        "dhlog.simulate.config",
        ["SimulationConfig"],
        "dhlog.simulate(robot, out, ...)",
        "dhlog.simulator.config",
    ),
    (
        "dhlog.simulate.camera",
        ["simulate_detections", "simulate_vision"],
        "dhlog.simulate(robot, out, ...)",
        "dhlog.simulator.camera",
    ),
    (
        "dhlog.identify.whole",
        ["fit_whole_model", "AxisModel"],
        "dhlog.process(log, ...)",
        "dhlog.identify.fit.whole",
    ),
    ("dhlog.identify.extract", ["extract_dh"], "dhlog.extract_dh", "dhlog.identify.read.extract"),
    (
        "dhlog.identify.axismodel",
        ["AxisModel"],
        "dhlog.process(log, ...)",
        "dhlog.identify.fit.axismodel",
    ),
    (
        "dhlog.identify.vision",
        ["process_observations", "hand_eye", "CameraResult", "cross_validate_pixels"],
        "dhlog.process(log, ...)",
        "dhlog.identify.camera",
    ),
]

#: where each name the README took from dhlog.identify.vision is now (the package was split)
CAMERA_MODULES = {
    "process_observations": "dhlog.identify.camera.flow",
    "hand_eye": "dhlog.identify.camera.hand_eye",
    "CameraResult": "dhlog.identify.camera.report",
    "cross_validate_pixels": "dhlog.identify.camera.holdout",
}


@pytest.mark.parametrize(("old", "names", "new", "now"), OLD_PATHS, ids=[p[0] for p in OLD_PATHS])
def test_an_old_path_warns_naming_the_new_import_and_hands_on_the_same_objects(
    old: str, names: list[str], new: str, now: str
) -> None:
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=re.escape(f"use {new} (`import dhlog`)")) as said:
        __import__(
            old
        )  # as `import dhlog.robots` does (import_module's frame would be importlib's)
    module = sys.modules[old]
    (notice,) = [w for w in said if str(w.message).startswith(f"{old} is deprecated")]
    assert str(notice.message).startswith(f"{old} is deprecated and will be removed in 0.3:")
    assert f"its names are in {now} (private" in str(notice.message)
    assert notice.filename == __file__, "the notice points at the user's import, not the shim"
    for name in names:
        home = importlib.import_module(CAMERA_MODULES.get(name, now))
        assert getattr(module, name) is getattr(home, name), name
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        importlib.import_module(old)  # once: a second import is the cached module, silent


def test_the_public_successors_the_notices_name_exist() -> None:
    import dhlog

    for new in {new for _, _, new, _ in OLD_PATHS}:
        name = new.removeprefix("dhlog.").split("(")[0]
        assert name in dhlog.__all__, f"a notice names {new}, which dhlog does not export"
        assert callable(getattr(dhlog, name))
    model_fk = importlib.import_module("dhlog.model.fk")
    read_extract = importlib.import_module("dhlog.identify.read.extract")
    assert dhlog.fk_point is model_fk.fk_point
    assert dhlog.extract_dh is read_extract.extract_dh


SHIMS = {
    ".".join(path.relative_to(SRC).with_suffix("").parts)
    for path in (SRC / "dhlog").rglob("*.py")
    if "dhlog._deprecated" in path.read_text() and path.name != "_deprecated.py"
}


def test_dhlog_itself_imports_no_deprecated_path() -> None:
    """Only a user's old script sees a notice: no module of dhlog imports a shim (which would warn
    on every run of the public API)."""
    assert SHIMS == {p[0] for p in OLD_PATHS}
    using = []
    for path in (SRC / "dhlog").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                targets = {node.module} | {f"{node.module}.{a.name}" for a in node.names}
            elif isinstance(node, ast.Import):
                targets = {a.name for a in node.names}
            else:
                continue
            using += [f"{path.relative_to(SRC)} → {t}" for t in sorted(targets & SHIMS)]
    assert not using, "\n".join(using)


def test_the_public_api_raises_no_deprecation_warning_from_dhlog() -> None:
    """Every public name resolved in a fresh interpreter with dhlog's DeprecationWarnings as errors
    (a shim imported on the way would fail it)."""
    script = (
        "import warnings\n"
        "warnings.filterwarnings('error', category=DeprecationWarning, module=r'dhlog(\\.|$)')\n"
        "warnings.filterwarnings('error', message=r'dhlog\\.', category=DeprecationWarning)\n"
        "import dhlog\n"
        "for name in dhlog.__all__:\n"
        "    getattr(dhlog, name)\n"
        "print(len(dhlog.__all__))\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert int(run.stdout) >= 10, "the public API is resolved (not only __version__)"
