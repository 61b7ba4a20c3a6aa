"""Damaged vision logs: every frame read, counted as a fault or refused in one line.

Seeded mutations (``tests/fuzz_images.py``) of a small simulated vision log (the KR5, four
still poses, 640×400 JPEG, PNG and raw mono8 frames of the simulator's ChArUco board) — the log
fuzzer's byte, record and payload families and the image family (an Image's header fields and
data, a JPEG's bytes, frame header and format, a CameraInfo's size and coefficients) — read by
``ImageStream`` and ``detect`` and run through ``dhlog process``. The long run is
``benchmarks/fuzz.py --kind images``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import fuzz_images
from fuzz_images import FAMILIES, Base, cases, make_base, run_cli, run_library

LIBRARY_CASES = 32  # 8 a family, about 0.1 s each
CLI_CASES = 40  # 10 a family, about 0.05 s each


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Base:
    return make_base(tmp_path_factory.mktemp("vision-base"))


def test_mutated_vision_logs_read_frame_by_frame(base: Base, tmp_path: Path) -> None:
    outcomes = [run_library(c, tmp_path, base.board) for c in cases(LIBRARY_CASES, 32, base)]
    failures = [f"{o.case}: {', '.join(o.problems)}: {o.stderr}" for o in outcomes if o.problems]
    assert not failures, "\n".join(failures[:10])
    assert len(outcomes) == LIBRARY_CASES
    # the mutations reach every outcome: logs refused in one line, frames counted as faults
    assert any(o.exit_code == 2 for o in outcomes)
    image = [o for o in outcomes if o.family == "image"]
    assert any("not decoded" in o.stderr for o in image), [o.case for o in image]


def test_mutated_vision_logs_through_the_cli(base: Base, tmp_path: Path) -> None:
    outcomes = [run_cli(c, tmp_path) for c in cases(CLI_CASES, 33, base)]
    failures = [f"{o.case}: {', '.join(o.problems)}: {o.stderr}" for o in outcomes if o.problems]
    assert not failures, "\n".join(failures[:10])
    assert {o.family for o in outcomes} == set(FAMILIES)


def test_the_base_logs_read_whole(base: Base, tmp_path: Path) -> None:
    """The unmutated logs: every frame decoded, the board found in some (the fuzz starts from
    logs that exercise the detector, not from frames it rejects outright)."""
    from dhlog.identify.camera.frames.detect import Detection, detect
    from dhlog.identify.camera.frames.images import ImageStream

    found: list[Any] = []
    for fmt, data in base.logs.items():
        log = tmp_path / f"{fmt}.mcap"
        log.write_bytes(data)
        stream = ImageStream(log, fuzz_images.IMAGE_TOPICS[fmt], fuzz_images.INFO_TOPIC)
        frames = list(stream)
        assert len(frames) == fuzz_images.POSES and not stream.faults
        assert len(stream.infos) == fuzz_images.POSES
        found += [detect(f.pixels, base.board) for f in frames]
    assert sum(isinstance(d, Detection) for d in found) >= 2
