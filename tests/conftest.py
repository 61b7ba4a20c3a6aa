import os
import sys
from pathlib import Path

# One BLAS thread a process: the suite runs a worker per core (pytest-xdist), and each worker's
# OpenBLAS would otherwise start a thread per core too (2 × 2 on this machine: 5:22 against 3:58
# for the suite). Set before numpy is first imported; subprocesses inherit it.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

sys.path.insert(0, str(Path(__file__).parent))


import pytest  # noqa: E402


@pytest.fixture(scope="module")
def ur5_result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A UR5 off its nominal (0.2 mm, 0.02°), simulated and processed by the command line
    (``tests/test_export.py``, ``tests/test_export_ur.py``): its table on the fit's own branch
    (joints 2 and 3 in the Hayati form, the last frame aimed at the target: d6 = 0)."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app

    folder = tmp_path_factory.mktemp("ur5")
    log = folder / "ur5.mcap"
    runner = CliRunner()
    made = runner.invoke(
        app,
        ["simulate", "ur5", "-o", str(log), "--perturb-mm", "0.2", "--perturb-deg", "0.02",
         "--noise-mm", "0.01", "--seed", "3"],
    )  # fmt: skip
    assert made.exit_code == 0, made.output
    done = runner.invoke(app, ["process", str(log), "--no-rrd", "--out", str(folder)])
    assert done.exit_code == 0, done.output
    return folder / "ur5.dh.json"


@pytest.fixture(scope="module")
def ur5e_result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A UR5e off its nominal (0.2 mm, 0.02°), simulated and processed with ``--nominal ur5e``;
    the simulated log names its joints joint_1 … joint_6, not as the UR driver does."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app

    runner = CliRunner()
    folder = tmp_path_factory.mktemp("ur5e")
    log = folder / "run.mcap"
    made = runner.invoke(
        app,
        ["simulate", "ur5e", "-o", str(log), "--perturb-mm", "0.2", "--perturb-deg", "0.02",
         "--seed", "5"],
    )  # fmt: skip
    assert made.exit_code == 0, made.output
    done = runner.invoke(
        app, ["process", str(log), "--no-rrd", "--out", str(folder), "--nominal", "ur5e"]
    )
    assert done.exit_code == 0, done.output
    return folder / "run.dh.json"
