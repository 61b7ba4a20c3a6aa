"""Terms beyond the geometric model (issue 18): gravity compliance and transmission harmonics in
the whole-model fit, the model selection (``--model``), their result, export and FK."""

from __future__ import annotations

import dataclasses
import json
from importlib import resources
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.errors import InputError
from dhlog.identify.fit.axismodel import ParameterLayout
from dhlog.identify.fit.prediction import predict
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel, load_dh
from dhlog.io.memory import log_data_from_session
from dhlog.model import terms as ng
from dhlog.model.fk import fk_frames, fk_point
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document, terms_csv
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.robot import masses_urdf
from dhlog.simulator.session import Session, simulate_session
from test_identify import truth_model

runner = CliRunner()
SCHEMA = json.loads(
    resources.files("dhlog.schemas").joinpath("result.schema.json").read_text(encoding="utf-8")
)
#: The KR210-like truth of the issue: ≈ 0.3 mm of gravity deflection at full reach.
COMPLIANCE = ((2, 2e-8), (3, 3e-8), (5, 1e-7))


def _design(model: object, families: tuple[str, ...]) -> ng.Terms:
    axes = model.axes  # type: ignore[attr-defined]
    return ng.design(
        families,
        [a.point for a in axes],
        [a.direction for a in axes],
        model.target,  # type: ignore[attr-defined]
        [True] * len(axes),
        -axes[0].direction,  # the robot stands on the floor
    )


def test_term_columns_are_the_derivative_and_the_table_reproduces_the_model() -> None:
    """A step in the term coefficients alone moves the prediction by its columns to second order
    (the joints turn by δq ≈ 1e-6 x a lever of up to 2 m: reach x δq² ≈ 1e-11 m); a step in
    every parameter likewise (the torque's dependence on the geometry is left out of the
    Jacobian: θ·δ ≈ 1e-10 m).
    The same terms carried into the DH frames (``to_table``) deflect the table's joints so that
    its FK equals the axes model's to rounding."""
    rob = load_robot("kr5")
    session = simulate_session(rob, SimulationConfig(seed=1))
    model = truth_model(session, session.reference_pose)
    rng = np.random.default_rng(3)
    terms = _design(model, ("compliance", "harmonic"))
    assert {t.kind for t in terms.terms} == {"compliance", "harmonic_sin", "harmonic_cos"}
    assert all(t.joint != 0 for t in terms.terms if t.kind == "compliance")  # joint 1 vertical
    terms = terms.with_coefficients(rng.normal(size=terms.size) * 1e-4)
    model = dataclasses.replace(model, terms=terms, tool_rotation=np.eye(3))
    layout = ParameterLayout.of(model.types, fit_scales=True, rotation=True, terms=terms.names())
    bases = model.bases()
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (40, rob.n))
    p0, J = predict(model, Q, layout, bases)
    assert J is not None
    step = np.zeros(layout.size)
    assert layout.terms_at is not None
    step[layout.terms_at :] = rng.normal(size=terms.size) * 1e-6
    p1, _ = predict(model.moved(step, layout, bases), Q)
    assert np.abs(p1 - p0 - J @ step).max() < 1e-11 < np.abs(J @ step).max() / 1e4
    full = rng.normal(size=layout.size) * 1e-6
    p2, _ = predict(model.moved(full, layout, bases), Q)
    assert np.abs(p2 - p0 - J @ full).max() < 2e-9 < np.abs(J @ full).max() / 100
    frames = fk_frames(session.table, session.reference_pose, T_base=session.T_measurement_base)
    on_table = ng.to_table(terms, frames)
    dq = ng.table_deflection(session.table, on_table, Q, Q)
    assert np.abs(dq).max() > 1e-5
    T = session.T_measurement_base
    table_fk = fk_point(session.table, Q + dq, session.tool_point, T_base=T)
    assert np.abs(table_fk - p0).max() < 1e-12


def _compliant_session(seed: int, robot: str = "kr210", **extra: object) -> Session:
    options: dict[str, object] = {
        "protocol": "random-poses",
        "poses": 60,
        "perturb_length": 2e-4,
        "perturb_angle": np.radians(0.05),
        "seed": seed,
        **extra,
    }
    cfg = SimulationConfig(**options)  # type: ignore[arg-type]
    return simulate_session(load_robot(robot), cfg)


def _nominal(robot: str) -> DHModel:
    rob = load_robot(robot)
    names = tuple(f"joint_{i + 1}" for i in range(rob.n))
    return DHModel(rob.table, rob.T_base, rob.tool_point, names, robot)


def _fk_truth(session: Session, Q: np.ndarray) -> np.ndarray:
    """The truth's FK at encoder values Q: its joints deflected by its own terms."""
    q = Q
    if session.terms is not None:
        q = Q + ng.table_deflection(session.table, session.terms, Q, Q)
    return fk_point(session.table, q, session.tool_point, T_base=session.T_measurement_base)


def _fk_result(result: Identification, Q: np.ndarray) -> np.ndarray:
    """The result's FK through its JSON, as a user's stack loads it (DHModel.joint_values)."""
    doc = json.loads(json.dumps(result_document(result)))
    from dhlog.io.dhfile import parse_dh

    model = parse_dh(doc, "result.json")
    return fk_point(model.table, model.joint_values(Q), model.tool_point, T_base=model.T_base)


@pytest.fixture(scope="module")
def compliant() -> tuple[Session, Identification, Identification]:
    session = _compliant_session(4, compliance=COMPLIANCE)
    log = log_data_from_session(session)
    nominal = _nominal("kr210")
    auto = process_data(log, ProcessOptions(nominal=nominal))
    geometric = process_data(log, ProcessOptions(nominal=nominal, model=ModelRequest("geometric")))
    return session, auto, geometric


def test_auto_keeps_compliance_where_the_robot_bends(
    compliant: tuple[Session, Identification, Identification],
) -> None:
    """A KR210-like robot bending ≈ 0.3 mm under gravity (σ 10 µm, 60 random poses): auto
    chooses compliance (its BIC and held-out error both lower) and not the harmonics; at 300
    random joint vectors within the limits the FK error against the truth (deflection included)
    is a few µm (σ·√(p/N) ≈ 2.5 µm for 40 parameters over 1800 samples; 15 µm allows 6x),
    while the geometric model's is over 40 µm."""
    session, auto, geometric = compliant
    assert auto.selection is not None and auto.selection.chosen.families == ("compliance",)
    tried = [c.families for c in auto.selection.candidates]
    assert tried == [(), ("compliance",), ("harmonic",), ("compliance", "harmonic")]
    base, chosen = auto.selection.candidates[:2]
    assert base.holdout_rms is not None and chosen.holdout_rms is not None
    assert chosen.holdout_rms < base.holdout_rms / 5 and chosen.bic < base.bic
    assert geometric.selection is None and geometric.terms is None
    rob = load_robot("kr210")
    Q = np.random.default_rng(9).uniform(rob.limits[:, 0], rob.limits[:, 1], (300, rob.n))
    want = _fk_truth(session, Q)
    err_auto = np.sqrt(np.mean(np.sum((_fk_result(auto, Q) - want) ** 2, axis=1)))
    err_geo = np.sqrt(np.mean(np.sum((_fk_result(geometric, Q) - want) ** 2, axis=1)))
    assert err_auto < 15e-6 and err_geo > 40e-6, (err_auto, err_geo)
    # the terms move the target by about what the truth's deflection does
    assert 0.2e-3 < auto.deflection_target < 0.6e-3
    assert auto.validation is not None and auto.validation.rms < 2.5e-5  # √3 σ = 17 µm


def test_the_result_carries_the_terms(
    compliant: tuple[Session, Identification, Identification], tmp_path: Path
) -> None:
    """The JSON's nongeometric block validates and names what was tried; the CSV lists each
    term with σ; a result read back (load_dh) deflects the joints as the result did."""
    _, auto, _ = compliant
    doc = result_document(auto)
    jsonschema.validate(doc, SCHEMA)
    block = doc["nongeometric"]
    assert block["selection"]["chosen"].startswith("compliance")
    assert block["selection"]["candidates"][0]["model"] == "geometric"
    assert all(t["kind"] == "compliance" and t["std"] > 0 for t in block["terms"])
    rows = terms_csv(auto).splitlines()
    assert rows[0] == "name,kind,joint,lump,value,std,unit" and len(rows) == len(block["terms"]) + 1
    path = tmp_path / "r.dh.json"
    path.write_text(json.dumps(doc))
    model = load_dh(path)
    assert model.terms is not None and model.terms.size == len(block["terms"])
    assert auto.validation is not None
    # the FK of the JSON at the fitted samples gives the validation's own residual RMS
    seg = auto.segmentation
    ok = auto.validation.rows
    Q = seg.table.select([f"q_{i + 1}" for i in range(6)]).to_numpy()[ok]
    P = seg.table.select(["x", "y", "z"]).to_numpy()[ok]
    fk = fk_point(model.table, model.joint_values(Q), model.tool_point, T_base=model.T_base)
    rms = float(np.sqrt(np.mean(np.sum((fk - P) ** 2, axis=1))))
    assert abs(rms - auto.validation.rms) < 1e-9


def test_the_selection_is_a_value_built_from_what_was_scored(
    compliant: tuple[Session, Identification, Identification],
) -> None:
    """The selection and its candidates are frozen (assigning raises), and the candidates shown
    carry what every later step of the choice added to them: the geometric one, cross-validated
    only as the model compliance was judged against, keeps its held-out error; each held-out RMS
    is that of its own per-pose errors and is the one its ``why`` quotes; the last family is
    judged against the candidate kept before it; only the chosen one is marked, with the fit of
    the terms it keeps (the others' fits their families' own, none where joints were dropped).
    The run's document (``--model auto``) is the one the candidates give."""
    _, auto, _ = compliant
    sel = auto.selection
    assert sel is not None
    with pytest.raises(dataclasses.FrozenInstanceError):
        sel.fold_choices = ("harmonic",)  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        sel.candidates[0].why = "changed"  # type: ignore[misc]
    assert isinstance(sel.candidates, tuple) and sel.fold_choices == () == sel.fold_starts
    doc = sel.document()
    assert result_document(auto)["nongeometric"]["selection"] == doc
    models = ["geometric", "compliance (not 6)", "harmonic", "compliance+harmonic"]
    assert [c["model"] for c in doc["candidates"]] == models
    assert [c["chosen"] for c in doc["candidates"]] == [False, True, False, False]
    assert (doc["mode"], doc["chosen"], doc["folds"], doc["n_samples"]) == (
        "auto",
        "compliance (not 6)",
        5,
        1800,  # 60 poses x 30 samples
    )
    base, chosen, harmonic, both = sel.candidates
    assert len({c.key for c in sel.candidates}) == 4
    for c in (base, chosen, harmonic):  # cross-validated over the 60 poses
        assert c.squared is not None and c.squared.shape == (60,) and c.holdout_rms is not None
        assert c.holdout_rms == np.sqrt(np.mean(c.squared))
    assert base.why == "" and both.holdout_rms is None and both.squared is None
    for c in (chosen, harmonic):
        assert base.holdout_rms is not None and c.holdout_rms is not None
        assert c.why.startswith("BIC -") and c.why.endswith("mm² a pose)"), c.why
        assert f"held-out RMS {base.holdout_rms * 1e3:.4f} → {c.holdout_rms * 1e3:.4f} mm" in c.why
    assert both.why.startswith("BIC +") and both.why.endswith(" against compliance (not 6)")
    assert chosen.dropped == frozenset({("compliance", 5)})
    assert chosen.fit is not None and chosen.fit.model.terms is not None
    kept = {(t.kind, t.joint) for t in chosen.fit.model.terms.terms}
    assert ("compliance", 5) not in kept and ("compliance", 4) in kept
    assert sel.chosen is chosen and auto.terms is not None
    assert auto.terms.names() == chosen.fit.model.terms.names()
    assert all(c.fit is not None and c.fit.model.terms is not None for c in (harmonic, both))
    assert base.fit is not None and base.fit.model.terms is None


def test_auto_adds_nothing_to_a_rigid_robot() -> None:
    """A robot without compliance or gear errors (KR5 off its nominal, σ 10 µm): auto keeps
    the geometric model, rejected by the BIC without a cross-validation."""
    for seed in (1, 2):
        session = _compliant_session(seed, robot="kr5")
        result = process_data(
            log_data_from_session(session), ProcessOptions(nominal=_nominal("kr5"))
        )
        assert result.selection is not None
        assert result.selection.chosen.families == (), result.selection.document()
        assert result.terms is None and "nongeometric" in result_document(result)


def test_harmonics_are_found_where_the_gears_err() -> None:
    """A transmission error of 100 µrad on joint 2 (and 60 µrad on joint 3): auto keeps the
    harmonics, and their coefficients agree with the truth within 4σ."""
    truth = ((2, 1e-4, -5e-5), (3, 0.0, 6e-5))
    session = _compliant_session(5, robot="kr5", harmonic=truth, poses=80)
    result = process_data(
        log_data_from_session(session),
        ProcessOptions(nominal=_nominal("kr5"), model=ModelRequest("auto", harmonic_joints=(1, 2))),
    )
    assert result.selection is not None and result.selection.chosen.families == ("harmonic",)
    assert result.terms is not None
    got = {t.name(result.terms.lumps): k for k, t in enumerate(result.terms.terms)}
    for joint, a, b in truth:
        for kind, want in (("harmonic_sin", a), ("harmonic_cos", b)):
            k = got[f"{kind}_{joint}"]
            value, sd = result.terms.coefficients[k], result.terms_std[k]
            assert abs(value - want) < 4 * sd, (kind, joint, value, want, sd)


def test_the_nongeometric_block_is_untrusted() -> None:
    """Each malformed field is one InputError naming it."""
    good = {
        "gravity": [0, 0, -1],
        "lumps": [{"on": "target", "point": [0, 0, 0.1]}],
        "terms": [{"kind": "compliance", "joint": 2, "lump": 0, "value": 1e-5}],
    }
    assert ng.from_document(good, 6, "r.json").size == 1
    bad = [
        ({"gravity": [0, 0, 0]}, "gravity"),
        ({"gravity": "down"}, "gravity"),
        ({"lumps": [{"on": "axis 9", "point": [0, 0, 0]}]}, "lumps[0].on"),
        ({"lumps": [{"on": "target", "point": [0, "x", 0]}]}, "lumps[0]"),
        ({"terms": [{"kind": "wobble", "joint": 2, "value": 1}]}, "terms[0]"),
        ({"terms": [{"kind": "compliance", "joint": 2, "value": 1, "lump": 3}]}, "terms[0].lump"),
        ({"terms": [{"kind": "harmonic_sin", "joint": 7, "value": 1}]}, "terms[0]"),
        ({"terms": [{"kind": "harmonic_sin", "joint": 2, "value": "nan"}]}, "terms[0]"),
    ]
    for change, field in bad:
        with pytest.raises(InputError, match=rf"r\.json: nongeometric\.{field.replace('[', '.')}"):
            ng.from_document({**good, **change}, 6, "r.json")


def test_the_command_line(tmp_path: Path) -> None:
    """simulate --compliance/--harmonic, process --model, the terms CSV, export's note and fk's
    deflection; wrong values are one line naming the option."""
    log = tmp_path / "c.mcap"
    made = runner.invoke(
        app,
        [
            "simulate", "kr210", "-o", str(log), "--protocol", "random-poses", "--poses", "40",
            "--compliance", "2:2e-8,3:3e-8", "--harmonic", "2:1e-4:0", "--perturb-mm", "0.2",
        ],
    )  # fmt: skip
    assert made.exit_code == 0, made.output
    truth = json.loads((tmp_path / "c.truth.json").read_text())
    assert (tmp_path / "c.urdf").read_text().count("<mass ") == 5  # for --masses
    assert {t["kind"] for t in truth["nongeometric"]["terms"]} == {
        "compliance",
        "harmonic_sin",
        "harmonic_cos",
    }
    out = tmp_path / "out"
    done = runner.invoke(
        app, ["process", str(log), "--out", str(out), "--nominal", "kr210", "--model", "full"]
    )
    assert done.exit_code == 0, done.output
    assert "Model beyond the geometry (--model full)" in done.output
    terms = (out / "c.terms.csv").read_text().splitlines()
    assert len(terms) > 3 and any(",harmonic_sin," in row for row in terms)
    urdf = runner.invoke(
        app, ["export", str(out / "c.dh.json"), "--format", "urdf", "-o", str(out / "c.urdf")]
    )
    assert urdf.exit_code == 0 and "cannot carry them" in urdf.output
    fk = runner.invoke(app, ["fk", str(out / "c.dh.json"), "--q", "0,-1,0.5,0,0.3,0"])
    assert fk.exit_code == 0 and "joint deflection by the nongeometric terms" in fk.output
    x = str(tmp_path / "x.mcap")
    for args, what in (
        (["simulate", "kr210", "-o", x, "--compliance", "2"], "--compliance"),
        (["simulate", "ur5", "-o", str(tmp_path / "y.mcap"), "--compliance", "2:1e-8"], "masses"),
        (["simulate", "kr5", "-o", str(tmp_path / "z.mcap"), "--harmonic", "2:1:0"], "harmonic"),
        (["process", str(log), "--out", str(tmp_path / "o2"), "--model", "cubic"], "--model"),
        (["process", str(log), "--out", str(tmp_path / "o3"), "--gravity", "0,0"], "--gravity"),
    ):
        bad = runner.invoke(app, args)
        assert bad.exit_code == 1 and what in bad.output and "Traceback" not in bad.output, (
            args,
            bad.output,
        )


def test_the_readme_gravity_walkthrough(tmp_path: Path) -> None:
    """docs/gravity-and-gears.md: its two commands give the model table it shows."""
    section = (Path(__file__).parents[1] / "docs" / "gravity-and-gears.md").read_text()
    blocks = section.split("```")
    commands = blocks[1].removeprefix("sh\n").split("\n")
    simulate, process = (c.split()[1:] for c in commands if c.strip())
    made = runner.invoke(
        app, [a.replace("kr210.mcap", str(tmp_path / "kr210.mcap")) for a in simulate]
    )
    assert made.exit_code == 0, made.output
    args = [a.replace("kr210.mcap", str(tmp_path / "kr210.mcap")) for a in process]
    args[args.index("results")] = str(tmp_path / "results")
    done = runner.invoke(app, [*args, "--no-rrd"])
    assert done.exit_code == 0, done.output
    printed = {line.rstrip() for line in done.output.splitlines()}
    (table,) = [b for b in blocks if "Model beyond the geometry" in b]
    for line in table.strip("\n").splitlines():
        assert line.rstrip() in printed, line


def test_masses_from_a_urdf_give_each_joint_its_compliance(tmp_path: Path) -> None:
    """With the links' masses from a URDF (the truth's own), compliance is one term per joint
    (its c·g) and the payload's: the fitted compliances of joints 2, 3 and 5 agree with the
    truth within 4σ, and the others within 4σ of zero; FK at random joint vectors within 15 µm
    of the truth (as the lumped terms)."""
    urdf = tmp_path / "kr210.urdf"
    urdf.write_text(masses_urdf(load_robot("kr210")))
    session = _compliant_session(4, compliance=COMPLIANCE)
    result = process_data(
        log_data_from_session(session),
        ProcessOptions(
            nominal=_nominal("kr210"), model=ModelRequest("compliance", masses=str(urdf))
        ),
    )
    assert result.terms is not None and any("--masses: 5 link masses" in n for n in result.info)
    assert not any("--masses" in w for w in result.warnings), result.warnings
    got = {t.name(result.terms.lumps): k for k, t in enumerate(result.terms.terms)}
    truth = dict(COMPLIANCE)
    for joint in range(2, 7):
        k = got[f"compliance_{joint}_masses"]
        value = result.terms.coefficients[k] / 9.80665  # c·g → c, rad/(N·m)
        sd = result.terms_std[k] / 9.80665
        assert abs(value - truth.get(joint, 0.0)) < 4 * sd, (joint, value, sd)
    rob = load_robot("kr210")
    Q = np.random.default_rng(9).uniform(rob.limits[:, 0], rob.limits[:, 1], (300, rob.n))
    err = np.sqrt(np.mean(np.sum((_fk_result(result, Q) - _fk_truth(session, Q)) ** 2, axis=1)))
    assert err < 15e-6, err
    doc = result_document(result)
    jsonschema.validate(doc, SCHEMA)
    assert sum(1 for lump in doc["nongeometric"]["lumps"] if "mass" in lump) == 5


def test_a_bad_masses_urdf_is_one_line(tmp_path: Path) -> None:
    """--masses: a missing file (exit 1), a file that is no URDF, one without link masses and
    one whose joints are not the robot's (exit 2): one line naming the file, no traceback."""
    log = tmp_path / "kr5.mcap"
    made = runner.invoke(app, ["simulate", "kr5", "-o", str(log), "--protocol", "random-poses"])
    assert made.exit_code == 0, made.output
    no_masses = masses_urdf(load_robot("kr5")).replace("<mass ", "<massless ")
    other = masses_urdf(load_robot("scara"))
    cases = {
        "missing.urdf": None,
        "garbage.urdf": "<robot><link",
        "light.urdf": no_masses,
        "scara.urdf": other,
    }
    for name, text in cases.items():
        path = tmp_path / name
        if text is not None:
            path.write_text(text)
        args = ["process", str(log), "--nominal", "kr5", "--masses", str(path), "--no-rrd"]
        done = runner.invoke(app, [*args, "--out", str(tmp_path / f"out_{name}")])
        lines = [line for line in done.output.splitlines() if line.strip()]
        assert done.exit_code == (1 if text is None else 2), (name, done.output)
        assert name in done.output and "Traceback" not in done.output, done.output
        assert len(lines) <= 3, done.output  # one message, wrapped by the console
