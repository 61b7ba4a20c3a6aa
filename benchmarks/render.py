"""Render the sample logs' recordings as a reviewer first sees them, and check the pictures.

    .venv/bin/python benchmarks/render.py [--logs kr5_0.01mm … camera_view] [--out docs/images]

Each log is processed by ``dhlog process`` (its recording written to a temporary folder), the
recording drawn by the Rerun viewer at 1600×1000 under Xvfb with Mesa's software Vulkan
(``dhlog.present.render``), the picture judged (not blank, not one colour) and saved, halved to
1600×1000 pixels, as ``<out>/<log>.png`` for the README. Prints one line per log.

``camera_view`` is a camera's log instead, simulated (``dhlog simulate kr5 -o cam.mcap
--instrument camera --protocol random-poses --poses 30``, the default seed) and processed with
``--nominal kr5 --holdout 5``: its recording opens on the camera's tab (no residual plots),
judged as one (the image lit, corners drawn on it, the 3D part not empty).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image

from dhlog.present.render import judge, missing, screenshot

ROOT = Path(__file__).resolve().parents[1]
DHLOG = str(Path(sys.executable).with_name("dhlog"))
CAMERA = "camera_view"  # a simulated camera log, not a sample log


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--logs",
        nargs="+",
        default=[
            "kr5_0.01mm",
            "scara",
            "kr5_real",
            "kr5_phase",
            "puma560_step",
            "kr5_0.1mm",
            CAMERA,
        ],
    )
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    args = parser.parse_args()
    why = missing()
    if why:
        sys.exit(f"cannot render here: {why}")
    args.out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="dhlog-render-"))
    failed = False
    for stem in args.logs:
        log = ROOT / "sample_logs" / f"{stem}.mcap"
        nominal = ["--nominal", "kr5"] if stem.startswith("kr5") else []
        if stem == CAMERA:
            # named as in the README's commands (the recording shows the log's name)
            log, nominal = work / "cam.mcap", ["--nominal", "kr5", "--holdout", "5"]
            subprocess.run(
                [
                    *(DHLOG, "simulate", "kr5", "-o", str(log), "--instrument", "camera"),
                    *("--protocol", "random-poses", "--poses", "30", "--force"),
                ],
                check=True,
                capture_output=True,
            )
        subprocess.run(
            [DHLOG, "process", str(log), "--out", str(work), "--force", *nominal],
            check=True,
            capture_output=True,
        )
        shot = work / f"{stem}.png"
        screenshot(work / f"{log.stem}.rrd", shot)
        verdict = judge(shot, "camera" if stem == CAMERA else "3d")
        image = Image.open(shot)
        half = image.convert("RGB").resize(
            (image.width // 2, image.height // 2), Image.Resampling.LANCZOS
        )
        # 256 colours, small in the repo; by octree: the default median cut spends its palette
        # on the greys and turned the camera's red and green axes magenta and cyan (kr5's
        # orange J4 red), and is twice the size
        palette = half.quantize(256, method=Image.Quantize.FASTOCTREE)
        palette.save(args.out / f"{stem}.png", optimize=True)
        state = "; ".join(verdict.problems) or "ok"
        failed |= bool(verdict.problems)
        image_part = (
            f"; 2D view: {verdict.frame:.0%} lit, {verdict.marks:.2%} coloured"
            if verdict.frame is not None and verdict.marks is not None
            else ""
        )
        print(
            f"{stem}: {state} (3D view: {verdict.coloured:.2%} coloured pixels, the most "
            f"common colour {verdict.dominant:.0%} of them{image_part}) → "
            f"{args.out / f'{stem}.png'}"
        )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
