"""The committed sample logs: small, matching their truth files, and readable end to end."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dhlog.identify.segment.segment import segment_log
from dhlog.io.reader import read_log
from dhlog.io.writer import sha256_of

LOGS = sorted((Path(__file__).parents[1] / "sample_logs").glob("*.mcap"))


def test_the_six_sample_logs_exist() -> None:
    assert {p.stem for p in LOGS} == {
        "kr5_0.01mm",
        "kr5_0.1mm",
        "puma560_step",
        "scara",
        "kr5_phase",
        "kr5_real",
    }


@pytest.mark.parametrize("path", LOGS, ids=lambda p: p.stem)
def test_sample_log(path: Path) -> None:
    assert path.stat().st_size <= 2 * 1024 * 1024
    truth = json.loads(path.with_name(path.stem + ".truth.json").read_text())
    assert truth["format"] == "dhlog.result/1"
    assert truth["source"]["sha256"] == sha256_of(path)
    log = read_log(path)
    assert log.pipeline.name == truth["source"]["pipeline"]
    seg = segment_log(log)
    n = len(truth["standard_dh"])
    assert seg.segments["joint"].to_list() == list(range(1, n + 1))
    if seg.has_encoders:
        np.testing.assert_allclose(seg.reference_pose, truth["reference_pose"], atol=1e-9)
