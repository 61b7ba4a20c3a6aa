"""The export's point ids travel: ``dhlog import`` writes them into the log (``dhlog.point_ids``),
and ``dhlog process`` names by them the samples its whole-model fit sets aside, the held-out
poses (``<stem>.holdout.csv``'s ``point_id``) and the recording's outliers and held-out poses.

The export: a KR5 off its nominal (lengths up to 0.3 mm, angles up to 0.03° off) measured at 60
random joint vectors within its limits, 20 µm of tracker noise, the points named ``PT-101 …``;
pose 14 (``PT-114``) moved 20.8 mm, as a beam break or a bumped reflector does."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.check.named import name_outliers, sample_names
from dhlog.io.reader import read_log
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot

runner = CliRunner()
POSES, MOVED = 60, 13
IDS = [f"PT-{101 + k}" for k in range(POSES)]


def _write(path: Path, ids: list[str], seed: int, moved: int | None) -> np.ndarray:
    """An export of the KR5 off its nominal (the same robot whatever ``seed``: the poses and
    the noise are drawn after it) at ``len(ids)`` poses, pose ``moved`` 20.8 mm off; its
    points (mm)."""
    rob = load_robot("kr5")
    rng = np.random.default_rng(114)
    t = rob.table
    true = StandardDH(
        t.joint_types,
        t.theta_offset + rng.normal(scale=np.radians(0.03), size=t.n),
        t.d_offset + rng.normal(scale=3e-4, size=t.n),
        t.a + rng.normal(scale=3e-4, size=t.n),
        t.alpha + rng.normal(scale=np.radians(0.03), size=t.n),
    )
    rng = np.random.default_rng(seed)
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (len(ids), rob.n))
    T = fk_frames(true, Q, T_base=rob.T_base)[:, -1]
    xyz = T[:, :3, :3] @ np.array([0.02, 0.01, 0.1]) + T[:, :3, 3]
    xyz += rng.normal(scale=2e-5, size=xyz.shape)
    if moved is not None:
        xyz[moved] += 0.012  # 20.8 mm
    mm = np.round(xyz * 1e3, 4)
    lines = ["Point ID,X [mm],Y [mm],Z [mm]," + ",".join(f"A{k + 1}" for k in range(6))]
    for k in range(len(ids)):
        cells = [ids[k], *(f"{v:.4f}" for v in mm[k]), *(f"{v:.5f}" for v in np.degrees(Q[k]))]
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return np.asarray(mm)


@pytest.fixture(scope="module")
def export(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    """The export (a CSV) and its points (mm)."""
    path = tmp_path_factory.mktemp("ids") / "export.csv"
    return path, _write(path, IDS, 1, MOVED)


def test_the_ids_travel_into_the_log(export: tuple[Path, np.ndarray], tmp_path: Path) -> None:
    path, mm = export
    out = tmp_path / "run.mcap"
    assert runner.invoke(app, ["import", str(path), "-o", str(out)]).exit_code == 0
    data = read_log(out)
    assert data.point_ids is not None
    stamps = data.points["t_ns"].to_list()
    assert [data.point_ids[t] for t in stamps] == IDS
    np.testing.assert_allclose(data.points.select(["x", "y", "z"]).to_numpy() * 1e3, mm)


@pytest.mark.parametrize("model", ["auto", "geometric"])
def test_outliers_and_held_out_poses_are_named_by_the_ids(
    export: tuple[Path, np.ndarray], tmp_path: Path, model: str
) -> None:
    path, mm = export
    log = tmp_path / "run.mcap"
    assert runner.invoke(app, ["import", str(path), "-o", str(log)]).exit_code == 0
    out = tmp_path / "out"
    args = ["process", str(log), "--nominal", "kr5", "--out", str(out), "--holdout", "5"]
    result = runner.invoke(app, [*args, "--model", model])
    assert result.exit_code == 0, result.output
    printed = " ".join(result.output.split())
    assert "set aside 1 sample(s) as gross outliers" in printed, printed
    assert "PT-114 (20.8 mm)" in printed
    doc = json.loads((out / "run.dh.json").read_text())
    assert doc["whole_fit"]["outliers"] == ["PT-114"]
    # each held-out row carries the id of the point it scores: its position is that point's
    rows = list(csv.DictReader(io.StringIO((out / "run.holdout.csv").read_text())))
    assert len(rows) >= POSES - 1
    for row in rows:
        k = IDS.index(row["point_id"])
        got = [float(row[f"{a}_mm"]) for a in "xyz"]
        np.testing.assert_allclose(got, mm[k], atol=1e-6)
    # the recording names the outlier and the held-out poses
    labels: dict[str, list[object]] = {}
    for chunk in RrdReader(out / "run.rrd").stream():
        batch = chunk.to_record_batch()
        if "Points3D:labels" in batch.schema.names:
            column = batch.column("Points3D:labels")
            labels.setdefault(chunk.entity_path, []).extend(column.to_pylist())
    assert labels["/world/m/samples/fit_outliers"] == [["PT-114"]]
    assert labels["/world/m/samples/set_aside"] == [IDS]  # every stop, by its id
    # the certificate names the outlier
    page = tmp_path / "certificate.html"
    done = runner.invoke(app, ["report", str(out / "run.dh.json"), "-o", str(page)])
    assert done.exit_code == 0, done.output
    assert "held out as outliers: PT-114" in page.read_text()
    held = labels["/world/m/holdout/cross_validation/poses"][0]
    assert isinstance(held, list) and sorted(held) == sorted(r["point_id"] for r in rows)


def test_a_far_sample_the_fit_kept_is_named() -> None:
    """A sample 20 RMS off the fit that the fit kept (its outlier limit on a scale the model
    error widened) is named in a warning; one that is set aside in a note."""
    norms = np.full(50, 1e-4)
    norms[7], norms[20] = 2e-3, 3e-2
    inliers = np.ones(50, dtype=bool)
    inliers[20] = False
    names = sample_names(np.arange(50, dtype=np.int64), np.arange(50), {7: "P-8", 20: "P-21"})
    assert names[:2] == ["#1", "#2"] and names[7] == "P-8"
    out, notes = name_outliers(names, norms, inliers)
    assert out.tolist() == [20]
    info = [n.text for n in notes if n.level == "info"]
    warnings = [n.text for n in notes if n.level == "warning"]
    assert [n.code for n in notes] == ["outliers", "far-samples"]
    assert len(info) == 1 and "P-21 (30 mm)" in info[0]
    assert len(warnings) == 1 and "P-8 (2 mm)" in warnings[0] and "#" not in warnings[0]
    # without ids: the samples' numbers
    assert list(sample_names(np.arange(3, dtype=np.int64), np.arange(3), None)) == [
        "#1",
        "#2",
        "#3",
    ]


def test_a_validation_session_s_poses_are_named_by_its_ids(
    export: tuple[Path, np.ndarray], tmp_path: Path
) -> None:
    """``--validate`` another export of the same robot (25 poses ``V-1 …``): its rows of the
    held-out CSV carry its own ids, each at the position of its point."""
    path, _ = export
    other = tmp_path / "validation.csv"
    ids = [f"V-{k + 1}" for k in range(25)]
    mm = _write(other, ids, 2, None)
    for src in (path, other):
        done = runner.invoke(app, ["import", str(src), "-o", str(src.with_suffix(".mcap"))])
        assert done.exit_code == 0, done.output
    out = tmp_path / "out"
    args = ["process", str(path.with_suffix(".mcap")), "--nominal", "kr5", "--out", str(out)]
    result = runner.invoke(app, [*args, "--validate", str(other.with_suffix(".mcap")), "--no-rrd"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader(io.StringIO((out / "export.holdout.csv").read_text())))
    assert len(rows) >= 16  # every pose, or the poses left after placing the base on a third
    for row in rows:
        assert row["check"] == "validation.mcap"
        k = ids.index(row["point_id"])
        got = [float(row[f"{a}_mm"]) for a in "xyz"]
        np.testing.assert_allclose(got, mm[k], atol=1e-6)
