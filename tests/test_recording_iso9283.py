"""The ISO 9283 test's recording (issue 34, item 4: ``present.recording.iso9283``): written with
the real Rerun SDK, checked by ``rerun rrd verify`` and read back: the cube's 12 edges, each
pose's commanded point, magnified AP vector, attained positions and RP sphere about the magnified
barycentre, each path's commanded line, passes and magnified normal-plane deviations, the text
panel's tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from dhlog.iso9283.formulas import pose_accuracy, pose_repeatability
from dhlog.iso9283.report import Accuracy, Iso9283Report, PathReport, PoseReport
from dhlog.present.recording.iso9283 import magnifications, write_iso9283_recording
from test_process import rrd_verify

#: The KR5's test cube (docs/iso9283.md), m.
EDGE, CENTRE = 0.241, np.array([1.303, 0.0, 0.286])


def _commanded() -> dict[str, np.ndarray]:
    h = EDGE / 2
    corners = {
        "P2": CENTRE + np.array([-h, -h, -h]),
        "P3": CENTRE + np.array([h, -h, -h]),
        "P4": CENTRE + np.array([h, h, h]),
        "P5": CENTRE + np.array([-h, h, h]),
    }
    return {"P1": CENTRE.copy(), **{n: CENTRE + 0.8 * (c - CENTRE) for n, c in corners.items()}}


def _report(frame: str = "base") -> tuple[Iso9283Report, dict[str, np.ndarray], dict]:
    """Five poses, 6 cycles each (AP 0.3–0.7 mm, RP about 60 µm) and a 101-point line through
    P2, P1, P4 run 3 times, each pass offset across the path by 0.1, 0.2, 0.3 mm."""
    rng = np.random.default_rng(3)
    poses, attained = [], {}
    for k, (name, c) in enumerate(_commanded().items()):
        offset = rng.normal(0, 1, 3)
        offset *= (3e-4 + 1e-4 * k) / np.linalg.norm(offset)
        X = c + offset + rng.normal(0, 2e-5, (6, 3))
        attained[name] = X
        acc = pose_accuracy(X, c)
        rp = pose_repeatability(X)
        poses.append(
            PoseReport(
                name,
                6,
                X.mean(axis=0),
                c if frame == "base" else None,
                Accuracy(float(acc.AP_P), np.asarray(acc.AP_xyz)) if frame == "base" else None,
                None,
                float(rp.RP_l),
                float(rp.l_mean),
                float(rp.S_l),
                None,
                0.08,
                0.1,
                1e-4,
                1.2e-4,
                0,
                None,
                1,
            )
        )
    cmd = _commanded()
    line = np.linspace(cmd["P2"], cmd["P4"], 101)
    across = np.cross(cmd["P4"] - cmd["P2"], [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    run = np.linspace(
        line[0] - 0.01 * (line[1] - line[0]) / np.linalg.norm(line[1] - line[0]),
        line[-1] + 0.01 * (line[1] - line[0]) / np.linalg.norm(line[1] - line[0]),
        137,
    )
    passes = [run + off * across for off in (1e-4, 2e-4, 3e-4)]  # 1 cm beyond each end
    paths = [PathReport("line", 3, 101, 0, 3e-4, None, 3e-4, 0, 0)] if frame == "base" else []
    report = Iso9283Report(
        ["test.mcap"], frame, "the result's T_measurement_base", "/joint_command", None, 100.0,
        30, 6, poses, None, None, False, ["6 cycle(s) per pose: the standard asks 30."], paths,
    )  # fmt: skip
    return report, attained, {"line": (line, passes)}


def _rows(path: Path) -> dict[tuple[str, str], list[object]]:
    """Every component column: (entity, column) → its rows."""
    out: dict[tuple[str, str], list[object]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if ":" not in name:
                continue
            column = batch.column(name)
            if pa.types.is_timestamp(column.type):
                continue
            out.setdefault((chunk.entity_path, name.split(":")[-1]), []).extend(column.to_pylist())
    return out


def _get(rows: dict[tuple[str, str], list[object]], entity: str, column: str) -> np.ndarray:
    keys = [k for k in rows if k[0] == entity and k[1].lower().endswith(column.lower())]
    assert keys, (entity, column, sorted(k for k in rows if k[0] == entity))
    got = rows[keys[0]][0]
    return np.asarray(got, dtype=np.float64)


def test_the_recording_shows_the_test(tmp_path: Path) -> None:
    report, attained, paths = _report()
    path = tmp_path / "test.iso9283.rrd"
    write_iso9283_recording(report, path, attained=attained, paths=paths)
    rrd_verify(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["test.iso9283.rrd"]  # no part left
    rows = _rows(path)
    k, k_rp = magnifications(report, EDGE)
    assert k == 20.0  # 0.1 × 241 mm / 0.7 mm = 34 → the 1-2-5 number below: 20
    rp = max(p.RP for p in report.poses if p.RP is not None)
    nice = [m * 10.0**e for e in range(-1, 6) for m in (1, 2, 5)]
    assert k_rp == max(v for v in nice if v <= 0.03 * EDGE / rp)
    edges = rows[("/world/cube/edges", "strips")][0]
    assert len(edges) == 12
    lengths = [np.linalg.norm(np.subtract(e[1], e[0])) for e in edges]  # type: ignore[index]
    assert np.allclose(lengths, EDGE, atol=1e-9)
    for p in report.poses:
        c = np.asarray(p.commanded)
        base = f"/world/poses/{p.name}"
        assert np.allclose(_get(rows, f"{base}/commanded", "positions"), [c])
        assert p.before is not None
        vector = _get(rows, f"{base}/AP_before", "vectors")
        assert np.allclose(vector, [k * p.before.components], atol=1e-7)
        centre = c + k * (p.barycentre - c)
        sphere = _get(rows, f"{base}/RP", "centers")
        assert np.allclose(sphere, [centre], atol=1e-6)
        assert p.RP is not None
        assert np.allclose(_get(rows, f"{base}/RP", "half_sizes"), [[k_rp * p.RP] * 3], rtol=1e-6)
        X = attained[p.name]
        shown = _get(rows, f"{base}/attained", "positions")
        assert np.allclose(shown, centre + k_rp * (X - X.mean(axis=0)), atol=1e-6)
        assert (f"{base}/AP_after", "vectors") not in rows  # no after without a result
    line, _ = paths["line"]
    assert np.allclose(rows[("/world/paths/line/commanded", "strips")][0][0], line, atol=1e-7)
    assert len(rows[("/world/paths/line/passes", "strips")][0]) == 3
    deviation = rows[("/world/paths/line/deviation", "strips")][0]
    assert len(deviation) == 101 * 3
    # each pass's crossing is 0.1, 0.2, 0.3 mm across the straight line: magnified × k
    lengths = np.array([np.linalg.norm(np.subtract(s[1], s[0])) for s in deviation])
    for off in (1e-4, 2e-4, 3e-4):  # float32 in the recording: 0.1 µm at 1.3 m
        assert np.sum(np.abs(lengths - k * off) < 1e-6) == 101
    text = str(rows[("/report/iso9283", "text")][0])
    for p in report.poses:
        assert p.before is not None and p.RP is not None
        assert f"| {p.name} | 6 | {p.before.AP * 1e3:.4f} | — | {p.RP * 1e3:.4f} |" in text
    assert "| line | 3 | 101 | 0.3000 | — | 0.3000 |" in text
    assert "6 cycle(s) per pose: the standard asks 30." in text


def test_without_points_or_model_the_figures_only(tmp_path: Path) -> None:
    """Without the attained positions and passes: the RP spheres at the barycentres, no
    cluster, no path geometry; in the tracker's frame (no model): no cube, no AP."""
    report, _, _ = _report(frame="measurement")
    path = tmp_path / "m.rrd"
    write_iso9283_recording(report, path)
    rrd_verify(path)
    entities = {e for e, _ in _rows(path)}
    assert not any(e.startswith(("/world/cube", "/world/paths")) for e in entities)
    assert not any(e.endswith(("/attained", "/AP_before", "/commanded")) for e in entities)
    assert {f"/world/poses/P{i}/RP" for i in range(1, 6)} <= entities
    assert "/report/iso9283" in entities


def test_a_failed_write_leaves_nothing(tmp_path: Path) -> None:
    report, attained, _ = _report()
    path = tmp_path / "x.rrd"
    bad = dict(attained, P3=np.zeros((2, 2)))  # not (n, 3)
    with pytest.raises(ValueError):
        write_iso9283_recording(report, path, attained=bad)
    assert list(tmp_path.iterdir()) == []


def test_the_reports_own_positions_and_passes_are_drawn(tmp_path: Path) -> None:
    """What ``dhlog iso9283`` hands over: the positions and passes kept on the report (its
    poses' ``attained``, its paths' ``commanded`` and ``passes``) draw as the arguments do."""
    import dataclasses

    report, attained, paths = _report()
    line, passes = paths["line"]
    kept = dataclasses.replace(
        report,
        poses=[dataclasses.replace(p, attained=attained[p.name]) for p in report.poses],
        paths=[dataclasses.replace(report.paths[0], commanded=line, passes=passes)],
    )
    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    write_iso9283_recording(kept, a)
    write_iso9283_recording(report, b, attained=attained, paths=paths)
    rrd_verify(a)
    got, want = _rows(a), _rows(b)
    assert got.keys() == want.keys()
    for key in want:
        if key[0].startswith("/world"):
            assert got[key] == want[key], key
    assert ("/world/poses/P3/attained", "positions") in got
    assert len(got[("/world/paths/line/deviation", "strips")][0]) == 303
