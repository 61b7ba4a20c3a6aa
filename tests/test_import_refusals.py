"""``dhlog import`` refuses what it cannot read right, or reads it right and says how: header
units obeyed (``[m]`` stays m, inches converted), a unit stated in a comment line obeyed,
contradictions and mixed units refused, joint columns out of chain order reordered by their
numbers, ``grad`` (a degree in German software, a gon in English) refused, an uncertainty of 0 or
below refused naming its line, an uncertainty no tracker gives in the unit read (inches or
metres read as mm) refused, points that cannot be a robot's in the unit read refused, and a DH
file naming two joints alike refused. Every refusal is exit 2 with one line naming the column,
line or field.

The export: a KR5 (the library robot) at 30 random joint vectors within its limits, the tool
point 0.1 m off the flange, the tracker 2 m away; a U95 of 15 µm + 6 µm/m, as a tracker's
specification gives it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.io.decode.frames import COVARIANCE_COLUMNS
from dhlog.io.reader import read_log
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot

runner = CliRunner()
POSES = 30
U95_SPHERE, U95_AXIS = 2.7954834829151074, 1.959963984540054


@dataclass(frozen=True)
class Session:
    """The tracker's points (m) and U95 (m), and the joint values (deg)."""

    xyz: np.ndarray
    u95: np.ndarray
    q_deg: np.ndarray


def _session() -> Session:
    rob = load_robot("kr5")
    rng = np.random.default_rng(39)
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (POSES, rob.n))
    T_base = np.eye(4)
    T_base[:3, 3] = [2.0, 0.4, -0.5]
    T = fk_frames(rob.table, Q, T_base=T_base @ rob.T_base)[:, -1]
    xyz = T[:, :3, :3] @ np.array([0.02, 0.01, 0.1]) + T[:, :3, 3]
    u95 = 15e-6 + 6e-6 * np.linalg.norm(xyz, axis=1)
    return Session(xyz, u95, np.degrees(Q))


SESSION = _session()
JOINTS = [f"A{k}" for k in range(1, 7)]


def export(
    header: list[str],
    cell: Callable[[str, int], str],
    comments: tuple[str, ...] = (),
) -> str:
    """A CSV export: ``comments`` first, the ``header``, one row a pose (``cell(column, row)``)."""
    rows = [",".join(cell(h, i) for h in header) for i in range(POSES)]
    return "\n".join([*comments, ",".join(header), *rows]) + "\n"


def value(scale: float, u95: float = 1.0) -> Callable[[str, int], str]:
    """Cells: positions and U95 in a unit of ``scale`` m (the U95 as a 3-D figure, or per axis
    ``U95 X``; ``u95``: its factor), joints A1… in degrees, in the header's order."""

    def cell(h: str, i: int) -> str:
        key = h.split(" ")[0].split("_")[0].upper()
        if key in ("X", "Y", "Z"):
            return f"{SESSION.xyz[i, 'XYZ'.index(key)] / scale:.7f}"
        if key.startswith("A"):
            return f"{SESSION.q_deg[i, int(key[1:]) - 1]:.5f}"
        if key.startswith("U95") or key.startswith("UNC"):
            return f"{SESSION.u95[i] * u95 / scale:.7f}"
        if key == "POINT":
            return f"P{i + 1:03d}"
        raise AssertionError(h)

    return cell


@dataclass(frozen=True)
class Case:
    """An export, the options, and what must happen: ``code`` 0 with the positions read at
    ``scale`` (the file's unit, m) and the joints in ``order``, or 2 with ``message`` in the one
    line on stderr."""

    text: str
    args: tuple[str, ...] = ()
    code: int = 0
    message: str = ""
    scale: float = 1e-3
    printed: str = ""
    #: the joints' order in the log: the session's joints at these indices
    order: tuple[int, ...] = (0, 1, 2, 3, 4, 5)


POS = ["Point", "X [mm]", "Y [mm]", "Z [mm]"]
CASES = {
    "header [m] read as m": Case(
        export(["Point", "X [m]", "Y [m]", "Z [m]", *JOINTS], value(1.0)), scale=1.0
    ),
    "header _m read as m": Case(
        export(["Point", "X_m", "Y_m", "Z_m", *JOINTS], value(1.0)), scale=1
    ),
    "header (mm) read as mm": Case(
        export(["Point", "X (mm)", "Y (mm)", "Z (mm)", *JOINTS], value(1e-3))
    ),
    "header [in] converted, said": Case(
        export(["Point", "X [in]", "Y [in]", "Z [in]", *JOINTS], value(0.0254)),
        scale=0.0254,
        printed="read in inches (the header)",
    ),
    "a comment's unit obeyed": Case(
        export(["Point", "X", "Y", "Z", *JOINTS], value(0.0254), ("# Units: inch",)),
        scale=0.0254,
        printed="read in inches (line 1 states it)",
    ),
    "a comment that states no unit": Case(
        export([*POS, *JOINTS], value(1e-3), ("# unit tests passed; exported 2026-12-01",))
    ),
    "a comment's unknown unit": Case(
        export(["Point", "X", "Y", "Z", *JOINTS], value(1e-3), ("# Units: feet",)),
        code=2,
        message="line 1: the comment '# Units: feet' states the unit 'feet'",
    ),
    "header [m] against --length-unit mm": Case(
        export(["Point", "X [m]", "Y [m]", "Z [m]", *JOINTS], value(1.0)),
        ("--length-unit", "mm"),
        2,
        "'X [m]' states m but --length-unit mm",
    ),
    "a comment's unit against --length-unit": Case(
        export(["Point", "X", "Y", "Z", *JOINTS], value(0.0254), ("# Units: inch",)),
        ("--length-unit", "mm"),
        2,
        "line 1: states in but --length-unit mm",
    ),
    "a comment's unit against the header": Case(
        export(["Point", "X [mm]", "Y [mm]", "Z [mm]", *JOINTS], value(1e-3), ("# Units: in",)),
        code=2,
        message="'X [mm]' contradicts line 1",
    ),
    "x in m beside y, z in mm": Case(
        export(["Point", "X [m]", "Y [mm]", "Z [mm]", *JOINTS], value(1e-3)),
        code=2,
        message="'X [m]' (m), 'Y [mm]' (mm)",
    ),
    "metres without a unit read as mm": Case(
        export(["Point", "X", "Y", "Z", *JOINTS], value(1.0)),
        code=2,
        message="metres read as mm?",
    ),
    "A2 before A1: by their numbers": Case(
        export([*POS, "A2", "A1", "A3", "A4", "A5", "A6"], value(1e-3)),
        printed="taken in the order of their numbers (A1, A2",
    ),
    "--joint-columns A2 before A1: as given, said": Case(
        export([*POS, *JOINTS], value(1e-3)),
        ("--joint-columns", "A2,A1,A3,A4,A5,A6"),
        printed="in the order --joint-columns gives (A2, A1",
        order=(1, 0, 2, 3, 4, 5),
    ),
    "--angle-unit grad": Case(
        export([*POS, *JOINTS], value(1e-3)), ("--angle-unit", "grad"), 2, "--angle-unit"
    ),
    "a joint header in grad": Case(
        export([*POS, "A1 [grad]", *JOINTS[1:]], value(1e-3)),
        code=2,
        message="'A1 [grad]' states the unit 'grad' ('grad' is a degree in German",
    ),
    "Leica in inches, stated": Case(
        export(["Point", "X [in]", "Y [in]", "Z [in]", "U95 [in]", *JOINTS], value(0.0254)),
        ("--format", "leica"),
        scale=0.0254,
        printed="read in inches",
    ),
    "Leica in inches, unstated": Case(
        export(["Point", "X", "Y", "Z", "U95", *JOINTS], value(0.0254)),
        ("--format", "leica"),
        2,
        "the uncertainty U95 read in mm (the default) gives a median σ of",
    ),
    "a U95 of 0": Case(
        export([*POS, "U95 [mm]", *JOINTS], value(1e-3)).replace(
            f",{SESSION.u95[4] * 1e3:.7f},", ",0.000,"
        ),
        ("--format", "leica"),
        2,
        "line 6: U95 [mm] is 0.000",
    ),
    "a negative σ": Case(
        export([*POS, "U95 X", "U95 Y", "U95 Z", *JOINTS], value(1e-3)).replace(
            f",{SESSION.u95[2] * 1e3:.7f},", f",-{SESSION.u95[2] * 1e3:.7f},", 1
        ),
        code=2,
        message="line 4: U95 X is -",
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_an_export_is_read_right_or_refused(name: str, tmp_path: Path) -> None:
    case = CASES[name]
    src, out = tmp_path / "export.csv", tmp_path / "run.mcap"
    src.write_text(case.text)
    result = runner.invoke(app, ["import", str(src), "-o", str(out), *case.args])
    if case.code:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        assert result.exit_code == case.code, result.output
        assert len(lines) == 1, result.stderr
        assert case.message in " ".join(result.stderr.split()), result.stderr
        assert not out.exists()
        return
    assert result.exit_code == 0, result.output
    assert case.printed in " ".join(result.stdout.split()), result.stdout
    data = read_log(out)
    assert data.joints is not None
    # the positions as written, in the file's unit, to its 7 decimals
    xyz = data.points.select(["x", "y", "z"]).to_numpy()
    np.testing.assert_allclose(xyz, SESSION.xyz, atol=1e-7 * case.scale)
    # the joints in chain order, whatever the header's
    q = np.degrees(data.joints.select([f"q_{j}" for j in range(1, 7)]).to_numpy()[::3])
    np.testing.assert_allclose(q, SESSION.q_deg[:, list(case.order)], atol=1e-5)
    if "U95" in case.text.splitlines()[0]:
        cov = data.points.select(COVARIANCE_COLUMNS).to_numpy()
        np.testing.assert_allclose(np.sqrt(cov[:, 0]), SESSION.u95 / U95_SPHERE, rtol=1e-4)


def test_a_dh_file_naming_two_joints_alike_is_refused(tmp_path: Path) -> None:
    dh = tmp_path / "robot.toml"
    rows = "\n".join(f"[[standard_dh]]\na = {0.1 * k}\nalpha = 0.0" for k in range(3))
    names = "\n".join(f'[[joints]]\nname = "{n}"' for n in ("base", "shoulder", "base"))
    dh.write_text(f"{rows}\n{names}\n")
    result = runner.invoke(app, ["fk", str(dh), "--q", "0,0,0"])
    assert result.exit_code == 2, result.output
    assert "joints[2].name" in result.stderr and "joint 1 too" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


# --------------------------------------------------------------------------- uncertainty


def _sigma(tmp_path: Path, header: list[str], u95: float = 1.0) -> tuple[np.ndarray, str]:
    """Import an export with ``header`` (uncertainty cells: the U95 × ``u95``, in mm); the σ per
    coordinate the log carries (m) and what the command printed."""
    src, out = tmp_path / "export.csv", tmp_path / "run.mcap"

    def cell(h: str, i: int) -> str:
        if h.lower().startswith(("leica", "temp", "unc", "uncertainty")):
            scale = 1.0 if h.endswith("_m") else 1e-3
            return f"{SESSION.u95[i] * u95 / scale:.12f}"
        return value(1e-3, u95)(h, i)

    src.write_text(export(header, cell))
    result = runner.invoke(app, ["import", str(src), "-o", str(out)])
    assert result.exit_code == 0, result.output
    cov = read_log(out).points
    if not all(c in cov.columns for c in COVARIANCE_COLUMNS):
        return np.zeros((0, 3)), " ".join(result.output.split())
    c = cov.select(COVARIANCE_COLUMNS).to_numpy()
    return np.sqrt(c[:, [0, 3, 5]]), " ".join(result.output.split())


def test_a_leica_export_s_per_axis_uncertainty_is_read_and_its_3d_figure_named(
    tmp_path: Path,
) -> None:
    """``leica_uncX_m …`` (a standard uncertainty per axis, in m) are each point's σ as written;
    ``leica_unc_m`` beside them (the same, as one 3-D figure) is named as left out."""
    header = [*POS, "leica_unc_m", "leica_uncX_m", "leica_uncY_m", "leica_uncZ_m", *JOINTS]
    sd, printed = _sigma(tmp_path, header)
    np.testing.assert_allclose(sd, np.repeat(SESSION.u95[:, None], 3, axis=1), rtol=1e-6)
    assert "leica_unc_m were left out" in printed
    assert "σ was read from leica_uncX_m, leica_uncY_m, leica_uncZ_m" in printed


def test_a_u95_per_axis_is_1_96_sigma(tmp_path: Path) -> None:
    sd, _ = _sigma(tmp_path, [*POS, "U95 X", "U95 Y", "U95 Z", *JOINTS])
    np.testing.assert_allclose(sd[:, 0], SESSION.u95 / U95_AXIS, rtol=1e-4)


def test_a_3d_standard_uncertainty_is_root_3_sigma(tmp_path: Path) -> None:
    """One radial figure ``Uncertainty [mm]``: √(σx² + σy² + σz²) of an isotropic σ."""
    sd, printed = _sigma(tmp_path, [*POS, "Uncertainty [mm]", *JOINTS])
    np.testing.assert_allclose(
        sd, np.repeat(SESSION.u95[:, None], 3, axis=1) / np.sqrt(3), rtol=1e-6
    )
    assert "σ = u / √3" in printed


def test_a_vendor_s_3d_uncertainty_alone_is_read(tmp_path: Path) -> None:
    """``leica_unc_m`` alone (a standard uncertainty, one 3-D figure, in m): σ = u / √3."""
    sd, printed = _sigma(tmp_path, [*POS, "leica_unc_m", *JOINTS])
    np.testing.assert_allclose(sd[:, 1], SESSION.u95 / np.sqrt(3), rtol=1e-6)
    assert "σ was read from leica_unc_m" in printed


def test_an_uncertainty_of_something_else_is_named_as_left_out(tmp_path: Path) -> None:
    """``temp_std`` (a 3-D figure of another prefix: a temperature's?) is not read as the
    position's σ, and the warning names it."""
    sd, printed = _sigma(tmp_path, [*POS, "temp_std", *JOINTS])
    assert sd.size == 0
    assert "temp_std were left out" in printed and "(none was read)" in printed


def test_a_spread_under_a_micrometre_is_read(tmp_path: Path) -> None:
    """A σ column may be an averaged reading's spread, under a µm (here 0.6 µm at 3 m): read as
    written; the same from a U95 would be refused (no tracker's uncertainty model goes there)."""
    header = [*POS, "Unc X [mm]", "Unc Y [mm]", "Unc Z [mm]", *JOINTS]
    sd, _ = _sigma(tmp_path, header, u95=0.02)
    np.testing.assert_allclose(sd[:, 2], SESSION.u95 * 0.02, rtol=1e-6)
    assert float(np.median(sd)) < 1e-6


@pytest.mark.parametrize(
    ("head", "args", "message"),
    [
        ("Name X[m] Y[m] Z[m]", (), ""),
        ("Name X[m] Y[m] Z[m]", ("--length-unit", "mm"), "the header states m but --length-unit"),
        ("Name X[m] Y[mm] Z[m]", (), "not alike"),
    ],
)
def test_a_point_list_s_header_unit_is_obeyed(
    tmp_path: Path, head: str, args: tuple[str, ...], message: str
) -> None:
    """A SpatialAnalyzer point list (space-separated, no table) whose header line states the
    unit: metres read as metres (the header was skipped and the points read as mm)."""
    points, joints = tmp_path / "points.txt", tmp_path / "joints.csv"
    rows = [f"P{i + 1:03d} " + " ".join(f"{v:.7f}" for v in SESSION.xyz[i]) for i in range(POSES)]
    points.write_text("\n".join([head, *rows]) + "\n")
    joints.write_text(export(["Point", *JOINTS], value(1e-3)))
    out = tmp_path / "run.mcap"
    cmd = ["import", str(points), "--format", "spatialanalyzer", "--joints-file", str(joints)]
    result = runner.invoke(app, [*cmd, "-o", str(out), *args])
    if message:
        assert result.exit_code == 2, result.output
        assert message in " ".join(result.stderr.split()) and "line 1" in result.stderr
        return
    assert result.exit_code == 0, result.output
    xyz = read_log(out).points.select(["x", "y", "z"]).to_numpy()
    np.testing.assert_allclose(xyz, SESSION.xyz, atol=1e-7)


def test_ur_joint_names_in_alphabetical_order_are_taken_in_chain_order(tmp_path: Path) -> None:
    """A header with a UR arm's joints as its ROS 2 driver lists them (alphabetical: elbow
    first): the joints in the log in chain order (shoulder_pan … wrist_3), said in a note."""
    chain = [
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "elbow_joint",
        "wrist_1_joint",
        "wrist_2_joint",
        "wrist_3_joint",
    ]
    alphabetical = sorted(chain)
    assert alphabetical[0] == "elbow_joint"
    base = value(1e-3)

    def cell(h: str, i: int) -> str:
        return f"{SESSION.q_deg[i, chain.index(h)]:.5f}" if h in chain else base(h, i)

    src, out = tmp_path / "ur.csv", tmp_path / "ur.mcap"
    src.write_text(export([*POS, *alphabetical], cell))
    result = runner.invoke(app, ["import", str(src), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "taken in chain order" in " ".join(result.stdout.split())
    data = read_log(out)
    assert data.joints is not None and data.joint_names == chain
    q = np.degrees(data.joints.select([f"q_{j}" for j in range(1, 7)]).to_numpy()[::3])
    np.testing.assert_allclose(q, SESSION.q_deg, atol=1e-5)
