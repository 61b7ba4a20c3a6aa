"""A user's script type-checks against the installed package (issue 33, item 5): the README's
"From Python" script (also in docs/api.md; nothing but ``import dhlog``: process the bundled
sample, print the held-out table, export a URDF, compensate ten targets — tests/test_docs.py runs
it) passes ``mypy --strict`` from the user's side, dhlog found as an installed package, which mypy
reads only with its ``py.typed`` marker (without it: ``import-untyped``). A wrong variant of the
script must fail the check.

mypy runs with an empty configuration (not the project's) and the repository's own cache
(``.mypy_cache`` beside pyproject.toml, which CI's ``mypy`` step warms): about 1 s a check warm,
10 s cold on this 2-core machine."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import dhlog

ROOT = Path(__file__).parents[1]


def readme_script() -> str:
    """The first ```python block of the README's "From Python" section."""
    section = (ROOT / "README.md").read_text().split("## From Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "README.md's 'From Python' section has no ```python block"
    return str(blocks[0])


def mypy_strict(script: Path) -> subprocess.CompletedProcess[str]:
    """``mypy --strict script`` as a user runs it: an empty configuration, run beside the script
    (no dhlog there), dhlog from the interpreter's site-packages (an editable install's .pth as
    well as a wheel's files)."""
    pytest.importorskip("mypy")
    config = script.with_name("mypy.ini")
    config.write_text("[mypy]\n")
    env = {k: v for k, v in os.environ.items() if k not in ("MYPYPATH", "PYTHONPATH")}
    command = [sys.executable, "-m", "mypy", "--config-file", str(config), "--strict"]
    command += ["--cache-dir", str(ROOT / ".mypy_cache"), "--no-error-summary", script.name]
    return subprocess.run(
        command, cwd=script.parent, env=env, capture_output=True, text=True, timeout=300
    )


def test_the_readmes_script_type_checks_strictly_against_the_installed_package(
    tmp_path: Path,
) -> None:
    assert (Path(dhlog.__file__).parent / "py.typed").is_file()
    text = readme_script()
    assert "import dhlog\n" in text and not re.search(r"from dhlog|import dhlog\.", text)
    script = tmp_path / "user_script.py"
    script.write_text(text)
    run = mypy_strict(script)
    assert run.returncode == 0, run.stdout + run.stderr


def test_a_wrong_script_fails_the_type_check(tmp_path: Path) -> None:
    """The check can fail: a fold count given as text and an export format dhlog does not write
    are each an error at their line (a package mypy could not read would pass both as Any)."""
    wrong = readme_script().replace("holdout=5", 'holdout="5"').replace('"urdf"', '"pdf"')
    assert wrong.count('holdout="5"') == 1 and wrong.count('"pdf"') == 1
    script = tmp_path / "wrong_script.py"
    script.write_text(wrong)
    run = mypy_strict(script)
    errors = re.findall(r"^wrong_script\.py:(\d+): error: (.*)$", run.stdout, flags=re.MULTILINE)
    lines = wrong.splitlines()
    assert run.returncode == 1, run.stdout + run.stderr
    assert len(errors) == 2, run.stdout
    (l1, e1), (l2, e2) = errors
    assert 'holdout="5"' in lines[int(l1) - 1] and '"holdout" to "process"' in e1, errors
    assert '"pdf"' in lines[int(l2) - 1] and '"export" of "Calibration"' in e2, errors
