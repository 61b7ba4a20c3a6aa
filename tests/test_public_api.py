"""The public API (``import dhlog``): the names it promises, each documented, and what a user's
script does with them — process the bundled sample, print the held-out table, export a URDF,
compensate ten targets — checked against independent ground truth (the simulator's truth file,
yourdfpy's forward kinematics, the library's FK)."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dhlog

ROOT = Path(__file__).parents[1]
SAMPLE = ROOT / "sample_logs" / "kr5_0.01mm.mcap"

#: The public names of 0.2.0. A name leaving this list is a breaking change: it goes through a
#: deprecation (CHANGELOG.md) first, and this list changes with it.
PUBLIC = {
    "Calibration",
    "Compensation",
    "DhlogError",
    "InputError",
    "Iso9283Report",
    "JointType",
    "ModifiedDH",
    "Plan",
    "Robot",
    "Simulation",
    "StandardDH",
    "Tracker",
    "UsageError",
    "__version__",
    "acceptance_test",
    "extract_dh",
    "fit_circle",
    "fk_frames",
    "fk_point",
    "load",
    "plan",
    "process",
    "robot",
    "simulate",
}


def test_every_public_name_is_exported_and_documented() -> None:
    assert set(dhlog.__all__) >= PUBLIC, f"gone: {PUBLIC - set(dhlog.__all__)}"
    for name in dhlog.__all__:
        value = getattr(dhlog, name)
        if name != "__version__":
            assert inspect.getdoc(value), f"dhlog.{name} has no docstring"
    # the one list: every name __all__ promises resolves through the lazy table, and no more
    assert set(dhlog._PUBLIC) | {"__version__"} == set(dhlog.__all__)
    with pytest.raises(AttributeError, match="no attribute 'identify_now'"):
        _ = dhlog.identify_now  # type: ignore[attr-defined]


def test_import_dhlog_loads_nothing_heavy() -> None:
    """The console entry point imports dhlog first: names resolve on first use."""
    code = (
        "import sys, dhlog; "
        "print(sorted(m for m in ('numpy', 'polars', 'rerun') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_trackers_run_does_not_load_opencv() -> None:
    """The identification loads OpenCV only for a camera's log: the result's camera blocks are
    typed without importing it (OpenCV is ~20 MiB of a 1.1 M-sample run's peak)."""
    code = (
        "import sys, dhlog.identify.run, dhlog.result.document, dhlog.present.console; "
        "print('cv2' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_the_identification_loads_scipy_optimize_only_where_it_fits() -> None:
    """Importing the identification (and the console) leaves ``scipy.optimize`` unloaded: its
    import costs 0.35 s, a tenth of a 1.1 M-sample sweeps run that never calls it (the clock
    search of a held-out log imported it at the module's top, 3.55 → 3.96 s), and
    ``scipy.ndimage`` likewise."""
    code = (
        "import sys, dhlog.identify.run, dhlog.result.document, dhlog.present.console; "
        "print(sorted(m for m in ('scipy.optimize', 'scipy.ndimage') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.fixture(scope="module")
def calibration() -> dhlog.Calibration:
    return dhlog.process(SAMPLE, nominal="kr5", holdout=5)


def test_process_gives_the_truth_within_its_sigma(calibration: dhlog.Calibration) -> None:
    """FK of the result against the simulator's truth at random joint vectors within the limits:
    within the propagated noise (σ 0.01 mm tracker noise; 3σ of the FK's own uncertainty is a
    few µm, so 20 µm is far above it and far below a wrong model)."""
    truth = dhlog.load(ROOT / "sample_logs" / "kr5_0.01mm.truth.json")
    limits = dhlog.robot("kr5").limits
    Q = np.random.default_rng(3).uniform(limits[:, 0], limits[:, 1], (500, 6))
    error = np.linalg.norm(calibration.fk(Q) - truth.fk(Q), axis=1)
    assert np.sqrt(np.mean(error**2)) < 20e-6
    assert calibration.complete and calibration.n == 6
    assert calibration.version == dhlog.__version__


def test_the_holdout_table_and_parameters_are_frames(calibration: dhlog.Calibration) -> None:
    held = calibration.holdout
    assert held["model"].to_list() == ["nominal", "calibrated"]
    assert held["check"].to_list() == ["5-fold", "5-fold"]
    assert 5e-6 < held.filter(model="calibrated")["rms"][0] < 20e-6  # σ 0.01 mm, 3-D
    params = calibration.parameters
    assert params.height == 4 * 6
    assert set(params["form"]) == {"dh"}  # the KR5's pairs are perpendicular or well apart
    fixed = params.filter(fixed=True)
    assert fixed["sigma"].null_count() == fixed.height  # fixed: never a measured σ
    assert params.filter(fixed=False)["sigma"].null_count() == 0
    assert calibration.covariance is not None
    assert calibration.covariance.shape == (len(calibration.covariance_names),) * 2


def test_export_urdf_is_the_same_robot_in_yourdfpy(
    calibration: dhlog.Calibration, tmp_path: Path
) -> None:
    """The URDF, loaded by yourdfpy (a real consumer), places ``tool0`` (the measured target) in
    its ``measurement`` frame where the calibration's FK puts it in M."""
    import yourdfpy

    path = tmp_path / "kr5.urdf"
    text = calibration.export("urdf", path)
    assert path.read_text() == text
    robot = yourdfpy.URDF.load(str(path))
    q = np.array([0.3, -0.4, 0.5, 0.2, -0.6, 0.7])
    robot.update_cfg(dict(zip(robot.actuated_joint_names, q, strict=True)))
    tool0 = robot.get_transform("tool0", "measurement")
    assert np.allclose(tool0[:3, 3], calibration.fk(q), atol=1e-9)
    with pytest.raises(dhlog.UsageError, match="exists; pass overwrite=True"):
        calibration.export("urdf", path)
    with pytest.raises(dhlog.UsageError, match="format must be one of"):
        calibration.export("step", tmp_path / "x")  # type: ignore[arg-type]


def test_compensate_ten_targets_reaches_the_nominal_poses(calibration: dhlog.Calibration) -> None:
    """The corrected targets put the calibrated robot where the nominal meant the originals."""
    kr5 = dhlog.robot("kr5")
    Q = np.random.default_rng(1).uniform(kr5.limits[:, 0] / 2, kr5.limits[:, 1] / 2, (10, 6))
    done = calibration.compensate(Q)
    good = np.isfinite(done.targets[:, 0])
    assert good.sum() >= 9
    meant = dhlog.fk_point(kr5.table, Q, calibration.tool_point, T_base=kr5.T_base)
    reached = calibration.fk(done.targets[good])
    # both in the nominal's base frame: the calibrated FK is in M, mapped back by its T_base
    T = kr5.T_base @ np.linalg.inv(calibration.T_base)
    reached_base = reached @ T[:3, :3].T + T[:3, 3]
    assert np.max(np.linalg.norm(reached_base - meant[good], axis=1)) < 1e-6


def test_save_and_load_round_trip(calibration: dhlog.Calibration, tmp_path: Path) -> None:
    written = calibration.save(tmp_path / "kr5.dh.json")
    assert [p.name for p in written] == [
        "kr5.dh.json",
        "kr5.dh.csv",
        "kr5.holdout.csv",
        "kr5.terms.csv",
    ]
    again = dhlog.load(written[0], nominal="kr5")
    Q = np.random.default_rng(2).uniform(-1, 1, (20, 6))
    assert np.array_equal(again.fk(Q), calibration.fk(Q))
    assert again.holdout.equals(calibration.holdout)
    assert json.loads(written[0].read_text())["dhlog_version"] == dhlog.__version__
    with pytest.raises(dhlog.UsageError, match="exists"):
        calibration.save(tmp_path / "kr5.dh.json")
    with pytest.raises(dhlog.UsageError, match="names no nominal"):
        dhlog.load(written[0]).compensate(Q)


def test_log_to_rerun_writes_a_recording_rerun_verifies(
    calibration: dhlog.Calibration, tmp_path: Path
) -> None:
    path = tmp_path / "run.rrd"
    calibration.log_to_rerun(path)
    rerun = Path(sys.executable).with_name("rerun")
    out = subprocess.run([str(rerun), "rrd", "verify", str(path)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    rec = calibration.log_to_rerun()  # into a stream: a notebook's viewer — kept in memory
    assert rec is not None
    streamed = tmp_path / "streamed.rrd"
    rec.save(str(streamed))  # what the stream holds, flushed to a file and verified
    rec.flush()
    rec.disconnect()
    out = subprocess.run([str(rerun), "rrd", "verify", str(streamed)], capture_output=True)
    assert out.returncode == 0 and streamed.stat().st_size > path.stat().st_size // 4
    with pytest.raises(dhlog.UsageError, match="exists; pass overwrite=True"):
        calibration.log_to_rerun(path)


def test_a_dh_file_in_mm_and_degrees_is_read_in_si(tmp_path: Path) -> None:
    """A user's DH file in mm and degrees: the parameters frame and FK in SI (m, rad), as the
    model reads the file — never the file's numbers under SI labels."""
    path = tmp_path / "arm.json"
    rows = [
        {"type": "revolute", "theta": 0.0, "d": 400.0, "a": 180.0, "alpha": 90.0},
        {"type": "revolute", "theta": 0.0, "d": 0.0, "a": 600.0, "alpha": 0.0},
    ]
    path.write_text(json.dumps({"units": {"length": "mm", "angle": "deg"}, "standard_dh": rows}))
    arm = dhlog.load(path)
    params = arm.parameters
    assert params.filter(joint=1, parameter="d")["value"][0] == pytest.approx(0.4)
    assert params.filter(joint=1, parameter="alpha")["value"][0] == pytest.approx(np.pi / 2)
    assert params["unit"].to_list()[:4] == ["rad", "m", "m", "rad"]
    assert params["sigma"].null_count() == params.height
    assert np.allclose(arm.fk(np.zeros(2)), [0.78, 0.0, 0.4])


def test_outputs_never_overwrite_inputs(calibration: dhlog.Calibration, tmp_path: Path) -> None:
    """The inputs a call reads are never its outputs, overwrite or not: a URDF template, the
    robot's own DH file for a simulated session; a loaded result saves as JSON only."""
    template = tmp_path / "robot.urdf"
    calibration.export("urdf", template)
    with pytest.raises(dhlog.UsageError, match=r"robot\.urdf"):
        calibration.export("urdf", template, template=template, overwrite=True)
    truth = tmp_path / "arm.json"
    dhlog.load(ROOT / "sample_logs" / "kr5_0.01mm.truth.json").save(truth)
    with pytest.raises(dhlog.DhlogError, match="DH file is also an output"):
        dhlog.simulate(truth, truth, overwrite=True)
    assert dhlog.load(truth).n == 6  # still the DH file
    with pytest.raises(dhlog.UsageError, match=r"must be a \.json path"):
        dhlog.load(truth).save(tmp_path / "arm.toml")


def test_a_log_with_no_joint_identified_is_a_partial_result(tmp_path: Path) -> None:
    """Random poses without a nominal: no joint is identified (nothing swept, no start). The
    command writes what it has and exits 3 naming the joints, as before the API; the API gives
    the calibration, whose model raises naming why."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app

    sim = dhlog.simulate("kr5", tmp_path / "rp.mcap", protocol="random-poses", poses=12)
    cal = dhlog.process(sim.log)
    assert not cal.complete and cal.model is None
    with pytest.raises(dhlog.UsageError, match="no joint was identified"):
        cal.fk(np.zeros(6))
    done = CliRunner().invoke(app, ["process", str(sim.log), "--no-rrd", "--model", "geometric"])
    assert done.exit_code == 3, done.output
    assert "partial result" in done.output and (tmp_path / "rp.dh.json").is_file()


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: dhlog.process(SAMPLE, holdout=1), "holdout must be 0"),
        (lambda: dhlog.process(SAMPLE, model="magic"), "model must be one of"),  # type: ignore[arg-type]
        (lambda: dhlog.process(SAMPLE, gravity=(0, 0, 0)), "gravity takes three"),
        (lambda: dhlog.process("no/such.mcap"), "no/such.mcap"),
        (lambda: dhlog.robot("kr6"), "kr6"),
        (lambda: dhlog.process(SAMPLE, reference_pose=[0, -90, 90, 0, 45, 0]), "degrees"),
        (
            lambda: dhlog.load(SAMPLE.with_suffix(".truth.json"), nominal="kr5").compensate_poses(
                np.eye(4)[None].repeat(2, 0), configuration=np.zeros((1, 6))
            ),
            "one per pose",
        ),
        (lambda: dhlog.simulate("kr5", "x.mcap", warp=3), "no setting warp"),
    ],
)
def test_bad_arguments_are_one_clear_error(call: object, match: str) -> None:
    with pytest.raises(dhlog.DhlogError, match=match):
        call()  # type: ignore[operator]


def test_simulate_then_process_recovers_the_truth(tmp_path: Path) -> None:
    """dhlog.simulate writes a real MCAP and its truth; processing it gives the truth back."""
    sim = dhlog.simulate(
        "puma560",
        tmp_path / "s.mcap",
        noise=2e-5,
        perturb_length=2e-4,
        perturb_angle=1e-3,
        seed=4,
        steps=8,
    )
    assert sim.log.is_file() and sim.truth.is_file() and sim.samples > 0
    cal = dhlog.process(sim.log, nominal="puma560", model="geometric")
    # axes 2 and 3 nearly parallel (0.06° off): row 2 in the Hayati form, beta with its sigma
    hayati = cal.parameters.filter(form="hayati")
    assert set(hayati["joint"]) == {2} and "beta" in set(hayati["parameter"])
    truth = sim.truth_model()
    limits = dhlog.robot("puma560").limits
    Q = np.random.default_rng(5).uniform(limits[:, 0], limits[:, 1], (300, 6))
    error = np.linalg.norm(cal.fk(Q) - truth.fk(Q), axis=1)
    assert np.sqrt(np.mean(error**2)) < 1e-4  # 20 µm noise; the nominal is 200 µm off
