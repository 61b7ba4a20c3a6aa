"""Render the sample logs' recordings as a reviewer first sees them, and check the pictures.

    .venv/bin/python benchmarks/render.py [--logs kr5_0.01mm scara …] [--out docs/images]

Each log is processed by ``dhlog process`` (its recording written to a temporary folder), the
recording drawn by the Rerun viewer at 1600×1000 under Xvfb with Mesa's software Vulkan
(``dhlog.present.render``), the picture judged (not blank, not one colour) and saved, halved to
1600×1000 pixels, as ``<out>/<log>.png`` for the README. Prints one line per log.
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--logs",
        nargs="+",
        default=["kr5_0.01mm", "scara", "kr5_real", "kr5_phase", "puma560_step", "kr5_0.1mm"],
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
        nominal = ["--nominal", "kr5"] if stem.startswith("kr5") else []
        subprocess.run(
            [
                DHLOG,
                "process",
                str(ROOT / "sample_logs" / f"{stem}.mcap"),
                "--out",
                str(work),
                "--force",
                *nominal,
            ],
            check=True,
            capture_output=True,
        )
        shot = work / f"{stem}.png"
        screenshot(work / f"{stem}.rrd", shot)
        verdict = judge(shot)
        image = Image.open(shot)
        half = image.convert("RGB").resize(
            (image.width // 2, image.height // 2), Image.Resampling.LANCZOS
        )
        half.quantize(256).save(args.out / f"{stem}.png", optimize=True)  # small in the repo
        state = "; ".join(verdict.problems) or "ok"
        failed |= bool(verdict.problems)
        print(
            f"{stem}: {state} (3D view: {verdict.coloured:.2%} coloured pixels, the most "
            f"common colour {verdict.dominant:.0%} of them) → {args.out / f'{stem}.png'}"
        )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
