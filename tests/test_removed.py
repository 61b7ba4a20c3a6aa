"""The import paths 0.2 deprecated are gone in 0.3 (CHANGELOG.md, "Versioning" and "Removed"):
each old path fails to import as a module that does not exist, and what the changelog names in its
place does what the old path's names did in an earlier README's script."""

import importlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dhlog

ROOT = Path(__file__).parents[1]
SRC = ROOT / "src"

#: old path → what to use instead (`import dhlog`), as CHANGELOG.md's "Removed" lists them. The
#: old paths were found from every version of README.md (`git log -- README.md`).
OLD_PATHS = {
    "dhlog.kinematics": "dhlog.fk_point",
    "dhlog.extract": "dhlog.extract_dh",
    "dhlog.identify.extract": "dhlog.extract_dh",
    "dhlog.robots": "dhlog.robot",
    "dhlog.dhfile": "dhlog.load",
    "dhlog.simulate.config": "dhlog.simulate",
    "dhlog.simulate.camera": "dhlog.simulate",
    "dhlog.segment": "dhlog.process",
    "dhlog.identify.noise": "dhlog.process",
    "dhlog.identify.whole": "dhlog.process",
    "dhlog.identify.axismodel": "dhlog.process",
    "dhlog.identify.vision": "dhlog.process",
}


@pytest.mark.parametrize("old", sorted(OLD_PATHS))
def test_an_old_path_is_no_module(old: str) -> None:
    sys.modules.pop(old, None)
    with pytest.raises(ModuleNotFoundError) as gone:
        importlib.import_module(old)
    # the missing module is the old path itself (or its package), not something it imported
    assert gone.value.name is not None and old.startswith(gone.value.name), gone.value.name
    assert gone.value.name.count(".") >= 1


def test_no_file_or_folder_of_an_old_path_is_left() -> None:
    """A folder left behind (``simulate/`` holding only ``__pycache__``) would import as a
    namespace package and rebind ``dhlog.simulate``: nothing of the old paths stays."""
    bases = [SRC.joinpath(*old.split(".")) for old in OLD_PATHS] + [SRC / "dhlog" / "simulate"]
    left = [str(p) for base in bases for p in (base.with_suffix(".py"), base) if p.exists()]
    assert not left, left


def test_the_successors_the_changelog_names_are_the_public_api() -> None:
    for new in set(OLD_PATHS.values()):
        name = new.removeprefix("dhlog.")
        assert name in dhlog.__all__, f"the changelog names {new}, which dhlog does not export"
        assert callable(getattr(dhlog, name))
    assert dhlog.fk_point is importlib.import_module("dhlog.model.fk").fk_point
    assert dhlog.extract_dh is importlib.import_module("dhlog.identify.read.extract").extract_dh


def test_an_earlier_readmes_script_runs_on_the_public_names() -> None:
    """The old README's ``load_dh``, ``load_robot`` and ``fk_point``, written with the names that
    replace them: the bundled real-like sample's truth loaded, its FK by ``dhlog.fk_point`` on its
    own table equal to the loaded model's (a geometric model: one computation, so to 1e-12 m), and
    the library's KR5 it perturbs 1.7–5.4 mm from it at these joints (a nominal equal to the truth,
    a wrong robot or a wrong unit is 0 or metres off)."""
    truth = dhlog.load(ROOT / "sample_logs" / "kr5_real.truth.json")
    kr5 = dhlog.robot("kr5")
    Q = np.random.default_rng(7).uniform(kr5.limits[:, 0], kr5.limits[:, 1], (50, 6))
    by_table = dhlog.fk_point(truth.table, Q, truth.tool_point, T_base=truth.T_base)
    assert np.allclose(by_table, truth.fk(Q), rtol=0, atol=1e-12)
    nominal = dhlog.fk_point(kr5.table, Q, truth.tool_point, T_base=truth.T_base)
    offset = np.linalg.norm(nominal - by_table, axis=1)
    assert 1e-4 < np.min(offset) and np.max(offset) < 1e-2


def test_simulate_is_the_function_after_an_old_import_fails() -> None:
    """``dhlog.simulate`` was also the package of the simulator's old paths; an old script's
    failed ``from dhlog.simulate.config import …`` leaves it the function."""
    code = (
        "import dhlog\n"
        "try:\n"
        "    from dhlog.simulate.config import SimulationConfig\n"
        "except ModuleNotFoundError as e:\n"
        "    print(e.name)\n"
        "from dhlog.api.simulation import simulate\n"
        "print(dhlog.simulate is simulate, callable(dhlog.simulate))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.split() == ["dhlog.simulate", "True", "True"], out.stderr[-2000:]


def test_the_public_api_raises_no_deprecation_warning_from_dhlog() -> None:
    """Every public name resolved in a fresh interpreter with dhlog's DeprecationWarnings as
    errors: nothing of dhlog's own is deprecated now."""
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
