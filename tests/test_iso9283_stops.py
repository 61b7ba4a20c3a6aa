"""ISO 9283 from stops (a tracker's static measurements, one point per stop), through the
commands a user runs: ``dhlog import`` of the export, then ``dhlog iso9283``.

* The real FANUC R-2000iC/165F set (../shared/realdata/fanuc_r2000ic: 24 configurations × 10
  measurements, three reflectors), imported with ``--targets mA,mB,mC``: each pose's RP, for
  each reflector, is ``pose_repeatability`` of the CSV's own points for that configuration
  (grouped here from the CSV's ``config_id``, not by dhlog), to 1e-12 relative; RD likewise.
  Skipped when the folder is not beside the checkout.
* A simulated test (``dhlog.simulate(protocol="iso9283")``) exported as a tracker does: one
  averaged point per visit, the truth's attained position in the tracker's frame plus 2 µm of
  noise per coordinate (a static point averages about a second of samples: 10 µm / √100 = 1 µm;
  2 µm is on the safe side). AP against the truth's within 3 × the barycentre's noise (2 µm
  / √5 per coordinate: about 3 µm) and RP within 12 µm (l̄ + 3 S_l of 5 noisy points against
  the noise-free ones: each l_j moves by about the noise along P_j − P̄, σ 2 µm, so 3 S_l by
  about 3 × 2 µm = 6 µm at one σ of that change: 12 µm is two), and exactly (1e-9) the formula
  on the noisy points themselves.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.iso9283.formulas import distance_accuracy, pose_accuracy, pose_repeatability

runner = CliRunner()
#: ../shared beside the checkout (a worktree's checkout is one folder further down)
CSV = next(
    (
        up / "shared" / "realdata" / "fanuc_r2000ic" / "calibration_dataset.csv"
        for up in Path(__file__).resolve().parents[1:4]
        if (up / "shared" / "realdata" / "fanuc_r2000ic").is_dir()
    ),
    Path("shared/realdata/fanuc_r2000ic/calibration_dataset.csv"),
)


def _ok(args: list[str]) -> str:
    got = runner.invoke(app, args)
    assert got.exit_code == 0, got.output
    return got.output


@pytest.fixture(scope="module")
def fanuc(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], np.ndarray, str]:
    """The FANUC export imported and tested as a user would: the report (``--out`` a folder
    that does not exist yet), the CSV's points (24, 10, 3 reflectors, 3) and the console."""
    if not CSV.exists():
        pytest.skip("shared/realdata/fanuc_r2000ic is not beside the checkout")
    tmp = tmp_path_factory.mktemp("fanuc")
    log = tmp / "fanuc.mcap"
    said = _ok(["import", str(CSV), "-o", str(log), "--targets", "mA,mB,mC"])
    assert "3 targets" in said
    out = tmp / "reports" / "iso"  # missing: created, as dhlog process does
    console = _ok(["iso9283", str(log), "--out", str(out), "--no-rrd"])
    doc = json.loads((out / "fanuc.iso9283.json").read_text())
    table = np.genfromtxt(CSV, delimiter=",", names=True)
    points = np.full((24, 10, 3, 3), np.nan)
    for row in table:
        points[int(row["config_id"]), int(row["repeat"])] = [
            [row[f"m{m}_{a}_m"] for a in "xyz"] for m in "ABC"
        ]
    assert np.all(np.isfinite(points))
    return doc, points, console


def test_fanuc_rp_per_pose_and_reflector_is_the_formulas(
    fanuc: tuple[dict[str, Any], np.ndarray, str],
) -> None:
    """Every pose of every reflector: RP, l̄ and S_l equal the formula on the CSV's 10 points of
    that configuration (matched by barycentre, not by dhlog's names); the stops detected, the
    24 poses of 10 cycles each, the stabilisation not determined (null, named)."""
    doc, points, console = fanuc
    blocks = [doc["iso9283"], *doc["iso9283"]["further_targets"]]
    assert [b["target"] for b in blocks] == [1, 2, 3]
    for r, block in enumerate(blocks):
        assert block["measured_as"] == "stops" and "detected" in block["stops"]
        assert block["visits"] == 240 and len(block["poses"]) == 24
        assert any("stabilisation" in n for n in block["not_determined"])
        assert block["paths"] == []
        bary = points[:, :, r].mean(axis=1)
        seen = set()
        for pose in block["poses"]:
            k = int(np.argmin(np.linalg.norm(bary - np.array(pose["barycentre"]), axis=1)))
            assert np.allclose(bary[k], pose["barycentre"], rtol=0, atol=1e-12)
            seen.add(k)
            want = pose_repeatability(points[k, :, r])
            assert pose["visits"] == 10
            assert pose["RP"] == pytest.approx(float(want.RP_l), rel=1e-12)
            assert pose["S_l"] == pytest.approx(float(want.S_l), rel=1e-12)
            assert pose["stabilisation_time"] is None and pose["overshoot"] is None
            assert pose["before"] is None  # no model: AP not computed
        assert seen == set(range(24))
        # RD between the poses named P2 and P4 (the 2nd and 4th configurations first measured)
        d = block["distance"]
        want_d = distance_accuracy(points[1, :, r], points[3, :, r], np.zeros(3), np.zeros(3))
        assert d["RD"] == pytest.approx(float(want_d.RD), rel=1e-9)
        assert block["drift"]["hours"] is None  # the import's stamps are no times
    assert "t_stab" not in console and "not determined" in console
    assert "RP 3" in console


def test_fanuc_orientation_rp_is_the_reflectors_frames(
    fanuc: tuple[dict[str, Any], np.ndarray, str],
) -> None:
    """RP_a, RP_b, RP_c of each pose: 3 S of the fixed-axis angles of the frame reflectors A, B,
    C make, written out in plain numpy in tests/test_iso9283_realdata.py (to 1e-9 relative)."""
    from test_iso9283_realdata import frames, rp_abc_by_hand

    doc, points, _ = fanuc
    block = doc["iso9283"]
    assert block["orientation"] is True
    assert any("frame targets 1, 2, 3 make" in n for n in block["notes"])
    bary = points[:, :, 0].mean(axis=1)
    for pose in block["poses"]:
        k = int(np.argmin(np.linalg.norm(bary - np.array(pose["barycentre"]), axis=1)))
        want = rp_abc_by_hand(frames(*(points[k, :, r] for r in range(3))))
        np.testing.assert_allclose(pose["RP_abc"], want, rtol=1e-9, err_msg=pose["pose"])


def test_fanuc_rp_figures(fanuc: tuple[dict[str, Any], np.ndarray, str]) -> None:
    """The real robot's RP (reflector A): 0.065 mm to 0.254 mm over the 24 poses, as
    docs/iso9283.md reports (a check that the figures the docs show are the command's)."""
    doc, _, _ = fanuc
    rp = sorted(p["RP"] for p in doc["iso9283"]["poses"])
    assert rp[0] == pytest.approx(0.0648e-3, abs=1e-7)
    assert rp[-1] == pytest.approx(0.2542e-3, abs=1e-7)


def test_out_folder_is_created_and_a_file_in_the_way_refused(tmp_path: Path) -> None:
    """``--out`` missing is created (the FANUC fixture too); a file where the folder would be is
    one line, exit 2, nothing written."""
    export = tmp_path / "stops.csv"
    rows = ["q1 [rad],q2 [rad],q3 [rad],q4 [rad],q5 [rad],q6 [rad],x [m],y [m],z [m]"]
    rng = np.random.default_rng(3)
    for _ in range(3):
        for k in range(3):
            q = [0.1 * k, -0.5, 0.8, 0.0, 0.3, 0.1]
            p = np.array([1.0 + 0.1 * k, 0.2, 0.5]) + rng.normal(0, 1e-5, 3)
            rows.append(",".join(f"{v:.9g}" for v in [*q, *p]))
    export.write_text("\n".join(rows) + "\n", encoding="utf-8")
    log = tmp_path / "stops.mcap"
    _ok(["import", str(export), "-o", str(log)])
    _ok(["iso9283", str(log), "--out", str(tmp_path / "a" / "b"), "--no-rrd"])
    assert (tmp_path / "a" / "b" / "stops.iso9283.json").exists()
    (tmp_path / "file").write_text("x", encoding="utf-8")
    got = runner.invoke(app, ["iso9283", str(log), "--out", str(tmp_path / "file" / "c")])
    assert got.exit_code == 2 and "is a file" in got.output
    assert not (tmp_path / "file" / "c").exists()


def test_stops_option_refuses_a_time_series(tmp_path: Path) -> None:
    """``--stops`` on a continuous 100 Hz stream is one line naming it (exit 2)."""
    import dhlog

    log = tmp_path / "sim.mcap"
    dhlog.simulate("kr5", log, protocol="iso9283", seed=2, iso_cycles=2, iso_path_cycles=0)
    got = runner.invoke(app, ["iso9283", str(log), "--stops", "--no-rrd"])
    assert got.exit_code == 2 and "without a gap" in got.output


@pytest.fixture(scope="module")
def simulated_stops(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, Path, dict[str, Any], np.ndarray]:
    """A simulated KR5 test (5 pose cycles, 0.2 mm / 0.2 mrad off its nominal) exported as a
    tracker exports static measurements: one row per visit, the commanded joints (rad) and the
    attained position in the tracker's frame with 2 µm noise; imported with ``dhlog import``.
    The truth, and the noisy points in the base frame (visits in order)."""
    import dhlog

    tmp = tmp_path_factory.mktemp("simstops")
    sim = dhlog.simulate(
        "kr5",
        tmp / "sim.mcap",
        protocol="iso9283",
        seed=11,
        iso_cycles=5,
        iso_path_cycles=0,
        perturb_length=2e-4,
        perturb_angle=2e-4,
    )
    truth = json.loads(Path(sim.truth).read_text())["iso9283"]
    rng = np.random.default_rng(5)
    noisy = np.array([np.array(v["attained"]) + rng.normal(0, 2e-6, 3) for v in truth["visits"]])
    log = tmp / "stops.mcap"
    _ok(["import", str(_export(truth, noisy, tmp / "stops.csv", timed=False)), "-o", str(log)])
    return log, Path(sim.truth), truth, noisy


def _export(truth: dict[str, Any], noisy: np.ndarray, path: Path, *, timed: bool) -> Path:
    """The visits as a tracker's export: point name, (the stop's time, s,) joints (rad) and the
    attained position ``noisy`` (base frame) carried into the tracker's frame (m)."""
    T = np.array(truth["T_measurement_base"])
    head = "point," + ("time," if timed else "") + ",".join(f"q{j} [rad]" for j in range(1, 7))
    rows = [head + ",x [m],y [m],z [m]"]
    for k, (v, p_base) in enumerate(zip(truth["visits"], noisy, strict=True)):
        p = T[:3, :3] @ p_base + T[:3, 3]
        t = [(v["t_arrival_ns"] + v["t_leave_ns"]) / 2e9] if timed else []
        rows.append(",".join([f"S{k + 1}", *(repr(float(x)) for x in [*t, *v["q"], *p])]))
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_simulated_stops_against_the_truth(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray],
) -> None:
    """With the nominal and the true model as the result (the tracker placed exactly): the
    five poses found and named as the simulator ran them; AP (before) and RP of each within the
    noise of the truth's; AD within the noise; the drift's dRP the formula's on the points."""
    import dhlog

    log, truth_path, truth, noisy = simulated_stops
    report = dhlog.acceptance_test(log, nominal="kr5", result=truth_path)
    assert report.stops is not None and report.visits == 25
    assert [p.name for p in report.poses] == ["P1", "P2", "P3", "P4", "P5"]
    names = [v["pose"] for v in truth["visits"]]
    for p in report.poses:
        rows = [v for v in truth["visits"] if v["pose"] == p.name]
        X = np.array([v["attained"] for v in rows])
        commanded = np.array(rows[0]["commanded"])
        assert p.before is not None and p.RP is not None and p.visits == 5
        assert p.before.AP == pytest.approx(pose_accuracy(X, commanded).AP_P, abs=3e-6)
        assert p.before.AP > 5e-5  # the robot is off its nominal: the check can fail
        assert p.RP == pytest.approx(pose_repeatability(X).RP_l, abs=12e-6)
        mine = noisy[[n == p.name for n in names]]
        assert p.RP == pytest.approx(pose_repeatability(mine).RP_l, abs=1e-9)
        assert p.stabilisation_time is None and p.overshoot is None
    d = report.distance
    assert d is not None and d.AD is not None
    P2 = np.array([v["attained"] for v in truth["visits"] if v["pose"] == "P2"])
    P4 = np.array([v["attained"] for v in truth["visits"] if v["pose"] == "P4"])
    c2 = np.array(next(v["commanded"] for v in truth["visits"] if v["pose"] == "P2"))
    c4 = np.array(next(v["commanded"] for v in truth["visits"] if v["pose"] == "P4"))
    assert d.AD == pytest.approx(float(distance_accuracy(P2, P4, c2, c4).AD_P), abs=4e-6)
    assert report.drift is not None and report.drift.dRP is not None
    assert not np.isfinite(report.drift.hours)  # dhlog import's stamps
    assert report.not_determined and not report.paths


def test_a_nominal_without_a_tool_carries_the_results(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray],
) -> None:
    """A nominal DH file to the flange (no tool point) with a result: AP before is the robot's
    error at the result's tool point, not the tool's length (it printed 209.75 mm on the
    FANUC set, whose tool is 210.6 mm); said in a note. The same as a nominal carrying that
    tool itself."""
    import dataclasses

    import dhlog
    from dhlog.io.dhfile import dh_model_from

    log, truth_path, _, _ = simulated_stops
    flange = dataclasses.replace(dh_model_from("kr5"), tool_point=np.zeros(3))
    report = dhlog.acceptance_test(log, nominal=flange, result=truth_path)
    tool = np.array(json.loads(truth_path.read_text())["tool"]["point"])
    carried = dataclasses.replace(flange, tool_point=tool)
    same = dhlog.acceptance_test(log, nominal=carried, result=truth_path)
    assert any("the nominal gives no tool point" in n for n in report.notes)
    for p, q in zip(report.poses, same.poses, strict=True):
        assert p.before is not None and q.before is not None
        assert p.before.AP == pytest.approx(q.before.AP, abs=1e-12)
        assert p.before.AP < 1e-3  # the tool alone is 0.12 m


def test_simulated_stops_without_a_result_register_the_nominal(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray],
) -> None:
    """With the nominal only, the footing is the dwells': the nominal registered on the
    barycentres (said); RP does not depend on it."""
    import dhlog

    log, _, truth, _ = simulated_stops
    report = dhlog.acceptance_test(log, nominal="kr5")
    assert report.frame == "base" and "registered" in report.registration
    for p in report.poses:
        X = np.array([v["attained"] for v in truth["visits"] if v["pose"] == p.name])
        assert p.before is not None
        assert p.RP == pytest.approx(pose_repeatability(X).RP_l, abs=12e-6)


def test_timed_stops_give_the_drift_its_hours(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray], tmp_path: Path
) -> None:
    """The same stops exported with each stop's time (``--time``): still stops (one sample
    every few seconds), and the drift's hours are the time between the first and last P1 groups
    (the truth's mid-stop times, to 1 ms); dRP the same as without times."""
    import dhlog

    log, truth_path, truth, noisy = simulated_stops
    timed = tmp_path / "timed.mcap"
    export = _export(truth, noisy, tmp_path / "timed.csv", timed=True)
    _ok(["import", str(export), "-o", str(timed), "--time", "time"])
    report = dhlog.acceptance_test(timed, nominal="kr5", result=truth_path)
    untimed = dhlog.acceptance_test(log, nominal="kr5", result=truth_path)
    assert report.stops is not None and report.drift is not None and untimed.drift is not None
    t = [(v["t_arrival_ns"] + v["t_leave_ns"]) / 2e9 for v in truth["visits"] if v["pose"] == "P1"]
    g = report.drift.group
    assert report.drift.hours * 3600 == pytest.approx(np.mean(t[-g:]) - np.mean(t[:g]), abs=1e-3)
    assert report.drift.dRP == pytest.approx(untimed.drift.dRP, abs=1e-12)


def test_a_second_reflector_has_its_own_accuracy_with_the_results_point(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray], tmp_path: Path
) -> None:
    """Two reflectors per stop (``--targets smr1,smr2``), the second 80 mm off the first on the
    flange; the result (the true model) gives its point in ``tool.further_targets``. Target 2's
    AP (before: the nominal's FK of the commanded joints with that point) equals the formula on
    the truth's positions of that reflector within the noise (3 µm), after (the calibrated
    model's prediction) likewise; its RP is the formula's on its own points. Without the point
    in the result, target 2's AP is not computed (said)."""
    import dhlog
    from dhlog.io.dhfile import dh_model_from
    from dhlog.model.fk import fk_frames, fk_point

    _, truth_path, truth, noisy = simulated_stops
    true = dhlog.load(truth_path).model
    second = true.tool_point + np.array([0.08, 0.0, -0.02])
    rng = np.random.default_rng(9)
    T = np.array(truth["T_measurement_base"])
    head = ",".join(f"q{j} [rad]" for j in range(1, 7))
    rows = [f"{head},smr1 x [m],smr1 y [m],smr1 z [m],smr2 x [m],smr2 y [m],smr2 z [m]"]
    attained2, noisy2 = [], []
    for v, p1 in zip(truth["visits"], noisy, strict=True):
        a2 = np.array(v["attained"]) + np.array(v["attained_R"]) @ (second - true.tool_point)
        attained2.append(a2)
        p2 = a2 + rng.normal(0, 2e-6, 3)
        noisy2.append(p2)
        cols = [*v["q"], *(T[:3, :3] @ p1 + T[:3, 3]), *(T[:3, :3] @ p2 + T[:3, 3])]
        rows.append(",".join(repr(float(x)) for x in cols))
    export = tmp_path / "two.csv"
    export.write_text("\n".join(rows) + "\n", encoding="utf-8")
    log = tmp_path / "two.mcap"
    _ok(["import", str(export), "-o", str(log), "--targets", "smr1,smr2"])
    doc = json.loads(truth_path.read_text())
    doc["tool"]["further_targets"] = [
        {"target": 2, "topic": "/tracker/point_2", "point": list(second), "std": [0.0] * 3}
    ]
    result = tmp_path / "with_second.dh.json"
    result.write_text(json.dumps(doc), encoding="utf-8")
    report = dhlog.acceptance_test(log, nominal="kr5", result=result)
    assert len(report.further) == 1 and report.further[0].target == 2
    nominal = dh_model_from("kr5")
    A2 = np.array(attained2)
    names = np.array([v["pose"] for v in truth["visits"]])
    for p in report.further[0].poses:
        at = names == p.name
        q = np.array(truth["visits"][int(np.flatnonzero(at)[0])]["q"])
        commanded = fk_point(nominal.table, q, second, T_base=nominal.T_base)
        assert p.before is not None and p.after is not None
        assert p.before.AP == pytest.approx(pose_accuracy(A2[at], commanded).AP_P, abs=3e-6)
        flange = fk_frames(true.table, q[None], T_base=np.eye(4))[0, -1]
        true_fk = flange[:3, :3] @ second + flange[:3, 3]
        assert p.after.AP == pytest.approx(
            float(np.linalg.norm(A2[at].mean(axis=0) - true_fk)), abs=3e-6
        )
        assert p.RP == pytest.approx(pose_repeatability(A2[at]).RP_l, abs=12e-6)
        assert p.RP == pytest.approx(pose_repeatability(np.array(noisy2)[at]).RP_l, rel=1e-9)
    without = dhlog.acceptance_test(log, nominal="kr5", result=truth_path)
    assert all(p.before is None for p in without.further[0].poses)
    assert any("not determined" in n and "further_targets" in n for n in without.notes)


def test_the_stops_report_validates_and_the_certificate_reads_it(
    simulated_stops: tuple[Path, Path, dict[str, Any], np.ndarray], tmp_path: Path
) -> None:
    """``dhlog iso9283`` on the stops with the nominal and the result: the JSON validates
    against the schema (stabilisation null, drift hours null), and the certificate's reader
    takes it, the not-determined lines among its notes."""
    import jsonschema  # type: ignore[import-untyped]

    from dhlog.present.certificate.iso9283 import load_iso9283

    log, truth_path, _, _ = simulated_stops
    args = ["iso9283", str(log), "--nominal", "kr5", "--result", str(truth_path)]
    console = _ok([*args, "--out", str(tmp_path), "--no-rrd"])
    assert "AP after" in console and "not determined" in console
    report = tmp_path / "stops.iso9283.json"
    doc = json.loads(report.read_text())
    schema = Path(__file__).parents[1] / "src" / "dhlog" / "schemas" / "iso9283.schema.json"
    jsonschema.validate(doc, json.loads(schema.read_text()))
    block = doc["iso9283"]
    assert block["measured_as"] == "stops" and block["drift"]["hours"] is None
    assert all(p["stabilisation_time"] is None for p in block["poses"])
    shown = load_iso9283(report)
    assert shown.drift is not None and shown.drift.hours is None
    assert any(n.startswith("Not determined: stabilisation") for n in shown.notes)


def test_import_targets_refuses_what_it_cannot_read(tmp_path: Path) -> None:
    """``--targets`` naming a prefix the header lacks, a prefix twice, or given with ``--x``:
    one line each naming the fix (exit 2), nothing written; the header's triples in a unit each
    (mm and m) are read in their own units."""
    export = tmp_path / "two.csv"
    export.write_text(
        "q1,q2,q3,q4,q5,q6,A x [mm],A y [mm],A z [mm],B x [m],B y [m],B z [m]\n"
        "1,2,3,4,5,6,1000,2000,3000,1.1,2.1,3.1\n"
        "2,3,4,5,6,7,1001,2001,3001,1.2,2.2,3.2\n",
        encoding="utf-8",
    )
    out = tmp_path / "two.mcap"
    for extra, said in (
        (["--targets", "A,C"], "no columns C x, y, z"),
        (["--targets", "A,a"], "twice"),
        (["--targets", "A,B", "--x", "A x"], "leave --x"),
    ):
        got = runner.invoke(app, ["import", str(export), "-o", str(out), *extra])
        assert got.exit_code == 2 and said in got.output, got.output
        assert len([line for line in got.output.splitlines() if line.strip()]) <= 2
        assert not out.exists()
    _ok(["import", str(export), "-o", str(out), "--targets", "A,B"])
    from dhlog.io.reader import read_log

    points = read_log(out).points
    assert sorted(set(points["target"].to_list())) == [0, 1]
    a = points.filter(points["target"] == 0)
    b = points.filter(points["target"] == 1)
    assert a["x"].to_list() == pytest.approx([1.0, 1.001]) and b["x"].to_list() == [1.1, 1.2]


def test_a_log_of_poses_never_repeated_is_not_an_iso9283_test(tmp_path: Path) -> None:
    """A calibration session's 20 random poses, each visited once: no repeatability and no
    test poses to speak of — one line and exit 2, not P1 … P5 made of five random poses."""
    import dhlog

    sim = dhlog.simulate("kr5", tmp_path / "rp.mcap", protocol="random-poses", poses=20, seed=3)
    run = CliRunner().invoke(
        app, ["iso9283", str(sim.log), "--nominal", "kr5", "--no-rrd", "--out", str(tmp_path)]
    )
    assert run.exit_code == 2, run.output
    assert "none of its 20 distinct targets is visited twice" in run.output
    assert "Traceback" not in run.output
    assert not list(tmp_path.glob("*.iso9283.json"))
