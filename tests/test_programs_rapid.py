"""``dhlog compensate --program`` on ABB RAPID modules: robtargets (mm, quaternion q1 first,
confdata) and jointtargets (degrees) corrected with only their numbers changed, the confdata
kept the corrected joints' quadrants (⌊angle / 90°⌋ of axes 1, 4, 6: ABB's RAPID Reference
Manual, confdata), a robtarget whose confdata names another turn of axis 6 solved in that
turn, and what cannot be corrected named.

The syntax follows the RAPID Reference Manual's robtarget example (``CONST robtarget p15 :=
[[600, 500, 225.3], [1, 0, 0, 0], [1, 1, 0, 0], [11, 12.3, 9E9, 9E9, 9E9, 9E9]];``). Checked
independently of the reader: the output's literals parsed with a regular expression of this
test, the controller's joints for each pose solved from the previous joints in the confdata's
quadrants, the calibrated model's FK there compared with the original target."""

from __future__ import annotations

import difflib
import functools
import json
import math
import re
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel, parse_dh
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_frames
from dhlog.model.ik import solve
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

runner = CliRunner()
EXTAX = "[9E9,9E9,9E9,9E9,9E9,9E9]"
TCP = np.eye(4)
TCP[2, 3] = 0.1  # tGripper: 100 mm along the flange's z
ROBOT = "irb1200"
#: joint vectors (degrees) of the module's targets: approach and pick 20 mm apart, a place
JOINTS: list[list[float]] = [
    [10, 20, 10, 30, 50, -40],
    [10, 22, 8, 30, 52, -40],
    [10, 20, 10, 30, 50, -40],
    [-30, 15, 15, -20, 60, 100],
]


def _nominal() -> DHModel:
    rob = load_robot(ROBOT)
    return DHModel(rob.table, rob.T_base, rob.tool_point, rob.joint_names, ROBOT)


@functools.cache
def _calibrated(tmp: str) -> tuple[DHModel, Path]:
    cfg = SimulationConfig(perturb_length=5e-4, perturb_angle=math.radians(0.05), seed=5)
    session = simulate_session(load_robot(ROBOT), cfg)
    doc = json.loads(
        json.dumps(
            result_document(
                process_data(log_data_from_session(session), ProcessOptions(nominal=_nominal()))
            )
        )
    )
    path = Path(tmp) / "irb.dh.json"
    path.write_text(json.dumps(doc))
    return parse_dh(doc, str(path)), path


def _robtarget(q_deg: list[float], cf6: int | None = None) -> str:
    q = np.radians(q_deg)
    nominal = _nominal()
    T = fk_frames(nominal.table, q, T_base=nominal.T_base)[-1] @ TCP
    p = T[:3, 3] * 1e3
    w = Rotation.from_matrix(T[:3, :3]).as_quat(scalar_first=True)
    conf = [math.floor(q_deg[i] / 90) for i in (0, 3, 5)]
    if cf6 is not None:
        conf[2] = cf6
    return (
        f"[[{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}],[{w[0]:.7f},{w[1]:.7f},{w[2]:.7f},{w[3]:.7f}],"
        f"[{conf[0]},{conf[1]},{conf[2]},0],[9E9,9E9,9E9,9E9,9E9,9E9]]"
    )


def _module() -> str:
    """A module: a tooldata, a jointtarget, robtargets (one whose confdata puts axis 6 a turn
    lower: −260° for +100°), MoveAbsJ, MoveJ, MoveL (one inline), an Offs target, a work
    object, comments."""
    return "\n".join(
        [
            "MODULE Cell",
            "  ! pick at the conveyor, place on the tray",
            "  PERS tooldata tGripper:=[TRUE,[[0,0,100],[1,0,0,0]],[1,[0,0,50],[1,0,0,0],0,0,0]];",
            "  CONST jointtarget jHome:=[[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];",
            f"  CONST robtarget pAbove:={_robtarget(JOINTS[0])};",
            f"  CONST robtarget pPick:={_robtarget(JOINTS[1])};",
            f"  CONST robtarget pPlace:={_robtarget(JOINTS[3], cf6=-3)};",
            "  PROC main()",
            "    MoveAbsJ jHome, v1000, fine, tool0;",
            "    MoveJ pAbove, v1000, z50, tGripper;",
            "    MoveL pPick, v200, fine, tGripper;  ! pick",
            f"    MoveL {_robtarget(JOINTS[2])}, v200, z10, tGripper;",
            "    MoveL Offs(pPick,0,0,50), v200, z10, tGripper;",
            "    MoveJ pPlace, v1000, fine, tGripper\\WObj:=wobj0;",
            "    MoveL pPick, v200, fine, tGripper\\WObj:=wTable;",
            "  ENDPROC",
            "ENDMODULE",
            "",
        ]
    )


def _parse(text: str) -> dict[str, list[float]]:
    """name → numbers of each declared target; ``inline`` for the inline one."""
    out = {}
    for m in re.finditer(r"(?:robtarget|jointtarget) (\w+):=(\[.*\]);", text):
        out[m.group(1)] = [float(v) for v in re.findall(r"[-+]?[\d.]+(?:E\d+)?", m.group(2))]
    inline = re.search(r"MoveL (\[\[.*\]\]), v200, z10", text)
    assert inline is not None
    out["inline"] = [float(v) for v in re.findall(r"[-+]?[\d.]+(?:E\d+)?", inline.group(1))]
    return out


def test_a_rapid_module_is_filtered(tmp_path: Path) -> None:
    model, result = _calibrated(str(tmp_path))
    nominal = _nominal()
    source = tmp_path / "cell.mod"
    source.write_text(_module())
    out = tmp_path / "corrected.mod"
    run = runner.invoke(
        app,
        ["compensate", str(result), "--nominal", ROBOT, "--program", str(source), "-o", str(out)],
    )
    said = " ".join(run.output.split())
    # the Offs target and the one relative to wTable are named; the rest is corrected
    assert run.exit_code == 3, run.output
    assert "cell.mod line 13: not corrected: its target 'Offs(pPick,0,0,50)' is computed" in said
    assert (
        "cell.mod line 15: not corrected: its target is relative to the work object wTable" in said
    )
    before, after = source.read_text(), out.read_text()
    literals = [m.span() for m in re.finditer(r"\[\[.*?\]\]", before)]
    for op, i1, i2, _, _ in difflib.SequenceMatcher(
        None, before, after, autojunk=False
    ).get_opcodes():
        if op != "equal":
            assert any(a <= i1 and i2 <= b for a, b in literals), before[i1 - 20 : i2 + 20]
    assert "9E9,9E9,9E9,9E9,9E9,9E9" in after and "! pick at the conveyor" in after
    old, new = _parse(before), _parse(after)
    # the joint target: the calibrated flange at the corrected axes is the nominal's at the old
    q_home = np.radians(new["jHome"][:6])
    want = fk_frames(nominal.table, np.radians(old["jHome"][:6]), T_base=nominal.T_base)[-1]
    got = fk_frames(model.table, model.joint_values(q_home))[-1]
    assert (
        np.abs(got - want).max() < 1e-9
        and np.abs(q_home - np.radians(old["jHome"][:6])).max() > 1e-6
    )
    # each robtarget: the controller's joints in its confdata's quadrants, from the previous
    q = q_home
    for name in ("pAbove", "pPick", "inline", "pPlace"):
        values, goal_values = new[name], old[name]
        T = np.eye(4)
        T[:3, 3] = np.array(values[:3]) * 1e-3
        T[:3, :3] = Rotation.from_quat(values[3:7], scalar_first=True).as_matrix()
        start = q.copy()
        for axis, cf in ((0, values[7]), (3, values[8]), (5, values[9])):
            if math.floor(math.degrees(start[axis]) / 90) != cf:
                start[axis] = math.radians((cf + 0.5) * 90)
        found = solve(nominal.table, (T @ np.linalg.inv(TCP))[None], start[None], np.zeros(3))
        assert bool(found.converged[0])
        q = found.q[0]
        quadrants = [math.floor(math.degrees(q[i]) / 90 + 1e-12) for i in (0, 3, 5)]
        assert quadrants == values[7:10], (name, quadrants, values[7:10])
        goal = np.eye(4)
        goal[:3, 3] = np.array(goal_values[:3]) * 1e-3
        goal[:3, :3] = Rotation.from_quat(goal_values[3:7], scalar_first=True).as_matrix()
        reached = fk_frames(model.table, model.joint_values(q))[-1] @ TCP
        dp = np.linalg.norm(reached[:3, 3] - goal[:3, 3])
        dr = Rotation.from_matrix(reached[:3, :3] @ goal[:3, :3].T).magnitude()
        assert dp < 1e-6 and dr < 1e-6, (name, dp, dr)  # rounding: 0.1 µm, 1e-9
        assert np.abs(np.array(values[:3]) - goal_values[:3]).max() > 1e-3  # corrected
    assert new["pPlace"][9] == -3 and abs(math.degrees(q[5]) + 260) < 2  # axis 6 a turn lower


def test_rapid_errors(tmp_path: Path) -> None:
    """A robtarget of the wrong shape, a quaternion not of norm 1, an instruction without ';':
    one line naming the file and line, exit 2; a tool not declared: named, exit 3."""
    _, result = _calibrated(str(tmp_path))
    good = _robtarget(JOINTS[0])
    for text, said in (
        (
            "MODULE M\n  CONST robtarget p:=[[1,2,3],[1,0,0,0],[0,0,0,0]];\nENDMODULE\n",
            "line 2: p: a robtarget is 4 lists",
        ),
        (
            f"MODULE M\n  CONST robtarget p:=[[1,2],[1,0,0,0],[0,0,0,0],{EXTAX}];\n",
            "line 2: p: '[1,2]' has 2 values",
        ),
        (
            f"MODULE M\n  CONST robtarget p:=[[1,2,3],[1,1,0,0],[0,0,0,0],{EXTAX}];\n",
            "line 2: p: the quaternion has norm 1.41421",
        ),
        (
            f"MODULE M\n  CONST robtarget p:={good};\n  PROC main()\n"
            "    MoveL p, v100, fine, tool0\n  ENDPROC\n",
            "line 4: MoveL has no ';'",
        ),
    ):
        path = tmp_path / "bad.mod"
        path.write_text(text)
        run = runner.invoke(
            app,
            [
                "compensate",
                str(result),
                "--nominal",
                ROBOT,
                "--program",
                str(path),
                "-o",
                str(tmp_path / "o.mod"),
            ],
        )
        assert run.exit_code == 2, run.output
        assert f"{path}, {said}" in " ".join(run.output.split()), run.output
    path = tmp_path / "tool.mod"
    path.write_text(
        f"MODULE M\n  CONST robtarget p:={good};\n  PROC main()\n"
        "    MoveL p, v100, fine, tOther;\n  ENDPROC\nENDMODULE\n"
    )
    run = runner.invoke(
        app,
        [
            "compensate",
            str(result),
            "--nominal",
            ROBOT,
            "--program",
            str(path),
            "-o",
            str(tmp_path / "o.mod"),
        ],
    )
    assert run.exit_code == 3 and "its tool tother is not declared in the module" in " ".join(
        run.output.split()
    )
