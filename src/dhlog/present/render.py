"""Render a recording with the Rerun viewer itself, headless, and judge the picture.

The viewer (``rerun FILE --window-size WxH --screenshot-to PNG``) draws the recording's default
blueprint under an X server without a display (Xvfb, started here when ``DISPLAY`` is unset) with
Mesa's software Vulkan (``WGPU_BACKEND=vulkan``; Debian packages xvfb, mesa-vulkan-drivers,
libvulkan1). Used by ``benchmarks/render.py`` (the screenshots in ``docs/images``) and by the
render tests; not by ``dhlog`` itself.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

VULKAN_ICDS = Path("/usr/share/vulkan/icd.d")


def missing() -> str | None:
    """Why rendering cannot run here (None when it can)."""
    if shutil.which("Xvfb") is None and not os.environ.get("DISPLAY"):
        return "no X server: install xvfb (apt-get install xvfb)"
    if not any(VULKAN_ICDS.glob("lvp_icd*.json")) and not os.environ.get("DISPLAY"):
        return "no software Vulkan: install mesa-vulkan-drivers and libvulkan1"
    if ctypes.util.find_library("X11") is None and not os.environ.get("DISPLAY"):
        return "no Xlib to move Xvfb's pointer: install libx11-6"
    if not Path(sys.executable).with_name("rerun").exists():
        return "the rerun viewer is not installed beside this Python"
    return None


@contextmanager
def display(size: tuple[int, int] = (1600, 1000)) -> Iterator[str]:
    """An X display: the one in ``DISPLAY``, or an Xvfb started for the block (without the
    Composite extension, which the viewer's Vulkan surface does not work with). Its pointer is
    moved to the viewer's top bar (:func:`_pointer_away`): left at the screen's centre it hovers
    over the window, and the viewer draws a tooltip there (over a camera's image, hiding the
    board). ``-noreset``: without it the server resets, the pointer back at the centre, when the
    warp's connection closes. The window (at the top left, twice ``size`` on the viewer's
    default scale) covers the screen, so the pointer cannot leave it."""
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
            "-noreset",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        time.sleep(1.0)
        _pointer_away(f":{number}", (size[0] // 6, 16))
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=10)


def _pointer_away(name: str, at: tuple[int, int]) -> None:
    """The X server's pointer warped to ``at`` (Xlib's ``XWarpPointer`` through ctypes): there
    the viewer's top bar, between its menu and its navigation arrows (logical points half
    that on the viewer's default scale, the same on a scale of 1), hovers over nothing."""
    found = ctypes.util.find_library("X11")
    if found is None:
        raise RuntimeError("no Xlib to move Xvfb's pointer: install libx11-6")
    x11 = ctypes.CDLL(found)
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XDefaultRootWindow.restype = ctypes.c_ulong
    x11.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x11.XWarpPointer.argtypes = [
        ctypes.c_void_p,
        ctypes.c_ulong,
        ctypes.c_ulong,
        ctypes.c_int,
        ctypes.c_int,
        ctypes.c_uint,
        ctypes.c_uint,
        ctypes.c_int,
        ctypes.c_int,
    ]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    connection = x11.XOpenDisplay(name.encode())
    if not connection:
        raise RuntimeError(f"could not connect to the X server {name} (Xvfb did not start?)")
    try:
        root = x11.XDefaultRootWindow(connection)
        x11.XWarpPointer(connection, 0, root, 0, 0, 0, 0, at[0], at[1])
    finally:
        x11.XCloseDisplay(connection)  # flushes the request


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


Tab = Literal["3d", "camera"]


@dataclass(frozen=True)
class Judgement:
    """What the 3D view (the picture's left half, below the title bars; a camera's tab: its 3D
    part, the left half's lower part) shows: the share of its pixels that are coloured (drawn
    data: not the dark background, not the grey grid and text), and the share of those taken by
    the most common colour (quantised to 16 levels per channel) — an opaque plane or one colour
    over everything shows as one colour. For a camera's tab also its 2D view (the left half's
    upper part): ``frame``, the share of it lit (the image drawn, not the dark background), and
    ``marks``, the share coloured (the corners and error vectors over the grey image)."""

    coloured: float
    dominant: float
    frame: float | None = None
    marks: float | None = None

    @property
    def problems(self) -> list[str]:
        out = []
        camera = self.frame is not None
        # a camera's 3D part draws the camera's axes and the board, not a robot's samples
        if self.coloured < (0.001 if camera else 0.003):
            out.append(f"the 3D view is nearly empty ({self.coloured:.2%} coloured pixels)")
        if self.dominant > 0.5:
            out.append(f"one colour covers {self.dominant:.0%} of what the 3D view draws")
        if self.frame is not None and self.frame < 0.2:
            out.append(f"the 2D view shows no image ({self.frame:.0%} of it lit)")
        if self.marks is not None and self.marks < 0.0005:
            out.append(f"no corners drawn on the image ({self.marks:.3%} coloured pixels)")
        return out


def judge(png: Path, tab: Tab = "3d") -> Judgement:
    """The judgement of a screenshot of a ``dhlog process`` recording, open on a 3D tab
    (``"3d"``, the default blueprint's first) or on a camera's tab (``"camera"``: the 2D view
    above the 3D part, as ``present.recording.camera.camera_tabs`` lays them out)."""
    import numpy as np
    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), dtype=np.int64)
    h, w, _ = image.shape

    def coloured(rows: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        view = image[int(rows[0] * h) : int(rows[1] * h), : int(0.5 * w)].reshape(-1, 3)
        high, low = view.max(axis=1), view.min(axis=1)
        return view, (high > 60) & (high - low > 0.3 * high)

    view, mask = coloured((0.06, 0.95) if tab == "3d" else (0.53, 0.88))
    share = float(mask.mean())
    if np.any(mask):
        counts = np.bincount((view[mask] // 16) @ np.array([256, 16, 1]))
        dominant = float(counts.max() / counts.sum())
    else:
        share, dominant = 0.0, 0.0
    if tab == "3d":
        return Judgement(share, dominant)
    flat, marks = coloured((0.06, 0.5))
    lit = float((flat.max(axis=1) > 60).mean())
    return Judgement(share, dominant, frame=lit, marks=float(marks.mean()))
