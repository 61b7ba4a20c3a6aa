"""Render a recording with the Rerun viewer itself, headless, and judge the picture.

The viewer (``rerun FILE --window-size WxH --screenshot-to PNG``) draws the recording's default
blueprint under an X server without a display (Xvfb, started here when ``DISPLAY`` is unset) with
Mesa's software Vulkan (``WGPU_BACKEND=vulkan``; Debian packages xvfb, mesa-vulkan-drivers,
libvulkan1). Used by ``benchmarks/render.py`` (the screenshots in ``docs/images``) and by the
render test; not by ``dhlog`` itself.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

VULKAN_ICDS = Path("/usr/share/vulkan/icd.d")


def missing() -> str | None:
    """Why rendering cannot run here (None when it can)."""
    if shutil.which("Xvfb") is None and not os.environ.get("DISPLAY"):
        return "no X server: install xvfb (apt-get install xvfb)"
    if not any(VULKAN_ICDS.glob("lvp_icd*.json")) and not os.environ.get("DISPLAY"):
        return "no software Vulkan: install mesa-vulkan-drivers and libvulkan1"
    if not Path(sys.executable).with_name("rerun").exists():
        return "the rerun viewer is not installed beside this Python"
    return None


@contextmanager
def display(size: tuple[int, int] = (1600, 1000)) -> Iterator[str]:
    """An X display: the one in ``DISPLAY``, or an Xvfb started for the block (without the
    Composite extension, which the viewer's Vulkan surface does not work with)."""
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    number = 90 + os.getpid() % 500
    server = subprocess.Popen(
        [
            "Xvfb",
            f":{number}",
            "-screen",
            "0",
            f"{size[0]}x{size[1]}x24",
            "-extension",
            "Composite",
            "-nolisten",
            "tcp",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        time.sleep(1.0)
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=10)


def screenshot(rrd: Path, png: Path, size: tuple[int, int] = (1600, 1000)) -> None:
    """The viewer's own screenshot of ``rrd``'s default blueprint at ``size`` (logical points;
    the image is twice that on the viewer's default scale)."""
    viewer = str(Path(sys.executable).with_name("rerun"))
    with display(size) as name:
        env = {**os.environ, "DISPLAY": name, "WGPU_BACKEND": "vulkan", "RERUN_ANALYTICS": "false"}
        done = subprocess.run(
            [
                viewer,
                str(rrd),
                "--window-size",
                f"{size[0]}x{size[1]}",
                "--screenshot-to",
                str(png),
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=180,
        )
    if done.returncode != 0 or not png.exists():
        tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
        raise RuntimeError(f"the viewer did not write {png}: {' / '.join(tail)}")


@dataclass(frozen=True)
class Judgement:
    """What the 3D view (the picture's left half, below the title bars) shows: the share of its
    pixels that are coloured (drawn data: not the dark background, not the grey grid and
    text), and the share of those taken by the most common colour (quantised to 16 levels per
    channel) — an opaque plane or one colour over everything shows as one colour."""

    coloured: float
    dominant: float

    @property
    def problems(self) -> list[str]:
        out = []
        if self.coloured < 0.003:
            out.append(f"the 3D view is nearly empty ({self.coloured:.2%} coloured pixels)")
        if self.dominant > 0.5:
            out.append(f"one colour covers {self.dominant:.0%} of what the 3D view draws")
        return out


def judge(png: Path) -> Judgement:
    """The judgement of a screenshot of a ``dhlog process`` recording."""
    import numpy as np
    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), dtype=np.int64)
    h, w, _ = image.shape
    view = image[int(0.06 * h) : int(0.95 * h), : int(0.5 * w)].reshape(-1, 3)
    high, low = view.max(axis=1), view.min(axis=1)
    coloured = (high > 60) & (high - low > 0.3 * high)
    share = float(coloured.mean())
    if not np.any(coloured):
        return Judgement(0.0, 0.0)
    quantised = (view[coloured] // 16) @ np.array([256, 16, 1])
    counts = np.bincount(quantised)
    return Judgement(share, float(counts.max() / counts.sum()))
