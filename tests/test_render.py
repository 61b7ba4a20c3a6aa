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


def test_the_camera_judge_wants_an_image_with_corners(tmp_path: Path) -> None:
    """``judge(png, "camera")``: a camera's tab passes with a lit image carrying coloured
    marks in its 2D view (the left half's upper part) and coloured marks in its 3D part; the
    same tab without the marks, or with a dark 2D view (no image decoded), fails — and the
    grey image alone would fail the 3D tab's check (nothing coloured in most of the half)."""
    import numpy as np
    from PIL import Image

    rng = np.random.default_rng(1)
    tab = np.full((1000, 1600, 3), 12, dtype=np.uint8)
    tab[70:490, 60:740] = 110  # the frame: a grey image
    tab[250:350, 300:450] = 235  # the board's paper
    bare = tab.copy()
    for _ in range(60):  # corners and error vectors over the board
        y, x = rng.integers(260, 340), rng.integers(310, 440)
        tab[y : y + 3, x : x + 3] = [80, 140, 255] if rng.random() < 0.5 else [230, 60, 200]
    for _ in range(40):  # the 3D part: axes and the board
        y, x = rng.integers(560, 860), rng.integers(100, 700)
        tab[y : y + 4, x : x + 4] = rng.integers(80, 256, 3)
    bare[530:] = tab[530:]
    Image.fromarray(tab).save(tmp_path / "tab.png")
    assert judge(tmp_path / "tab.png", "camera").problems == []
    Image.fromarray(bare).save(tmp_path / "bare.png")
    assert any("no corners" in p for p in judge(tmp_path / "bare.png", "camera").problems)
    dark = tab.copy()
    dark[70:490, 60:740] = 12
    Image.fromarray(dark).save(tmp_path / "dark.png")
    assert any("no image" in p for p in judge(tmp_path / "dark.png", "camera").problems)
    assert any("empty" in p for p in judge(tmp_path / "bare.png").problems)
