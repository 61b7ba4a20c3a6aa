"""The recording as a reviewer first sees it: the Rerun viewer renders a sample log's recording
(default blueprint, 1600×1000) under Xvfb with Mesa's software Vulkan, and the 3D view draws
data that no single colour dominates. Skipped, with the reason, where Xvfb or Mesa's Vulkan is
not installed (apt-get install xvfb mesa-vulkan-drivers libvulkan1)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.present.render import judge, missing, screenshot

SAMPLES = Path(__file__).parents[1] / "sample_logs"
runner = CliRunner()


@pytest.mark.skipif(missing() is not None, reason=f"cannot render here: {missing()}")
def test_the_recording_renders_with_its_data_visible(tmp_path: Path) -> None:
    done = runner.invoke(
        app, ["process", str(SAMPLES / "scara.mcap"), "--out", str(tmp_path), "--force"]
    )
    assert done.exit_code == 0, done.output
    png = tmp_path / "scara.png"
    screenshot(tmp_path / "scara.rrd", png)
    verdict = judge(png)
    assert verdict.problems == [], verdict


def test_the_judge_rejects_a_view_of_one_colour(tmp_path: Path) -> None:
    """The check itself: a picture whose 3D view is one opaque colour (as the old base plane
    was) or empty fails; one with many coloured marks passes."""
    import numpy as np
    from PIL import Image

    image = np.full((1000, 1600, 3), 12, dtype=np.uint8)
    image[200:800, 100:700] = [240, 220, 20]  # an opaque yellow square
    Image.fromarray(image).save(tmp_path / "plane.png")
    assert any("one colour" in p for p in judge(tmp_path / "plane.png").problems)
    Image.fromarray(np.full((1000, 1600, 3), 12, dtype=np.uint8)).save(tmp_path / "empty.png")
    assert any("empty" in p for p in judge(tmp_path / "empty.png").problems)
    rng = np.random.default_rng(0)
    marks = np.full((1000, 1600, 3), 12, dtype=np.uint8)
    for _ in range(400):
        y, x = rng.integers(80, 900), rng.integers(0, 780)
        marks[y : y + 6, x : x + 6] = rng.integers(80, 256, 3)
    Image.fromarray(marks).save(tmp_path / "marks.png")
    assert judge(tmp_path / "marks.png").problems == []
