"""``dhlog import`` of tracker exports as the tracker software writes them (issue 17, item 6): a
KR5 measured with a 6-DoF probe at 40 random static poses (``fk_frames`` of the library robot
at joint vectors within its limits, the tracker 3 m away), exported with the real header
layouts — ``Point Name``, ``X [mm]``, ``U(95)  [mm]`` (two spaces), ``Q0…Q3`` scalar first, the
joints in the export or in a joints file — with the U95 to 3 decimals. Each layout
imports unchanged: read back, the positions within 1e-9 m and the orientation equal to the
exported quaternion; ``dhlog process`` uses the orientation with no pipeline. Every bad export
is one line with exit 2 naming the option that fixes it."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.io.decode.frames import COVARIANCE_COLUMNS, ORIENTATION_COLUMNS
from dhlog.io.exports.table import parse_header
from dhlog.io.importer import STOP_JOINT_TIMES
from dhlog.io.reader import read_log
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot

runner = CliRunner()
POSES = 40
#: The probe in the flange frame: its origin (m) and frame (rotation vector, rad).
PROBE_POINT = np.array([0.021, -0.013, 0.118])
PROBE_ROTATION = Rotation.from_rotvec([0.3, -0.2, 1.1])


@dataclass(frozen=True)
class Measured:
    """What the tracker measured, in the tracker's frame: the probe's positions (mm) and
    orientations (quaternions w, x, y, z), the U95 (mm, 3 decimals as exported) and
    the joint values (deg)."""

    xyz_mm: np.ndarray
    quat_wxyz: np.ndarray
    u95_mm: list[str]
    joints_deg: np.ndarray
    names: list[str] = field(default_factory=list)


@pytest.fixture(scope="module")
def measured() -> Measured:
    rob = load_robot("kr5")
    rng = np.random.default_rng(17)
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (POSES, rob.n))
    T_measurement_base = np.eye(4)
    T_measurement_base[:3, :3] = Rotation.from_euler("z", 2.2).as_matrix()
    T_measurement_base[:3, 3] = [2.4, 1.3, -0.6]
    T_last = fk_frames(rob.table, Q, T_base=T_measurement_base @ rob.T_base)[:, -1]
    xyz = T_last[:, :3, :3] @ PROBE_POINT + T_last[:, :3, 3]
    u95 = 15e-6 + 6e-6 * np.linalg.norm(xyz, axis=1)  # 15 µm + 6 µm/m (m)
    xyz += rng.normal(size=xyz.shape) * (u95 / 2.7954834829151074)[:, None]
    tilt = Rotation.from_rotvec(rng.normal(scale=np.radians(0.003), size=(POSES, 3)))
    R = tilt * Rotation.from_matrix(T_last[:, :3, :3]) * PROBE_ROTATION
    quat = R.as_quat(scalar_first=True)
    exported = [f"{u * 1e3:.3f}" for u in u95]
    names = [f"P{k + 1:03d}" for k in range(POSES)]
    return Measured(xyz * 1e3, quat, exported, np.degrees(Q), names)


@dataclass(frozen=True)
class Layout:
    """One export layout: its header cells and how it writes the values."""

    xyz: tuple[str, str, str] = ("X [mm]", "Y [mm]", "Z [mm]")
    u95: tuple[str, ...] = ("U(95)  [mm]",)
    orientation: tuple[str, ...] = ("Q0", "Q1", "Q2", "Q3")
    name: str | None = "Point Name"
    joints: str = "own"  # "own", "by name", "by row"
    joint_headers: tuple[str, ...] = ("j1", "j2", "j3", "j4", "j5", "j6")
    sep: str = ","
    xyz_scale: float = 1.0  # mm → the header's unit
    u95_scale: float = 1.0


def _cell(value: float | str, sep: str, decimals: int = 6) -> str:
    text = value if isinstance(value, str) else f"{value:.{decimals}f}"
    return text.replace(".", ",") if sep == ";" else text


def _orientation_cells(layout: Layout, q_wxyz: np.ndarray) -> list[float]:
    keys = [parse_header(h).key for h in layout.orientation]
    if keys == ["q0", "q1", "q2", "q3"]:
        return list(q_wxyz)
    if set(keys) == {"qw", "qx", "qy", "qz"}:
        by = dict(zip(("qw", "qx", "qy", "qz"), q_wxyz, strict=True))
        return [by[k] for k in keys]
    angles = Rotation.from_quat(q_wxyz, scalar_first=True).as_euler("xyz", degrees=True)
    return list(angles)


def write_export(folder: Path, m: Measured, layout: Layout) -> tuple[Path, Path | None]:
    """The export (and its joints file) as ``layout`` lays it out."""
    sep = layout.sep
    header = [*([layout.name] if layout.name else []), *layout.xyz, *layout.u95]
    header += [*layout.orientation, *(layout.joint_headers if layout.joints == "own" else ())]
    rows = [sep.join(header)]
    for k in range(POSES):
        cells = [m.names[k]] if layout.name else []
        cells += [_cell(v * layout.xyz_scale, sep) for v in m.xyz_mm[k]]
        for _ in layout.u95:
            u = m.u95_mm[k]
            scaled = float(u) * layout.u95_scale  # µm: whole numbers, as a µm export writes
            cells.append(_cell(u if layout.u95_scale == 1.0 else scaled, sep, 0))
        cells += [_cell(v, sep, 9) for v in _orientation_cells(layout, m.quat_wxyz[k])]
        if layout.joints == "own":
            cells += [_cell(v, sep) for v in m.joints_deg[k]]
        rows.append(sep.join(cells))
    src = folder / "export.csv"
    src.write_text("\n".join(rows) + "\n", encoding="cp1252" if sep == ";" else "utf-8")
    if layout.joints == "own":
        return src, None
    joints = folder / "joints.csv"
    order = np.random.default_rng(3).permutation(POSES) if layout.joints == "by name" else None
    lines = [",".join([*(["Point Name"] if order is not None else []), *layout.joint_headers])]
    for k in order if order is not None else range(POSES):
        lines.append(
            ",".join(
                [
                    *([m.names[k]] if order is not None else []),
                    *(f"{v:.6f}" for v in m.joints_deg[k]),
                ]
            )
        )
    joints.write_text("\n".join(lines) + "\n")
    return src, joints


def imported(*args: str) -> str:
    result = runner.invoke(app, ["import", *args])
    assert result.exit_code == 0, result.output
    return " ".join(result.output.split())  # as one line, whatever the console's width


LAYOUTS = {
    "Tracker Pilot: U(95)  [mm], Q0…Q3, joints in the export": (Layout(), ["--format", "leica"]),
    "Tracker Pilot, ; and decimal commas, joints file by name": (
        Layout(sep=";", joints="by name"),
        ["--format", "leica"],
    ),
    "joints file by row (no point names)": (
        Layout(name=None, joints="by row"),
        ["--format", "leica"],
    ),
    "X (mm), U95 X/Y/Z (mm), Qx Qy Qz Qw, generic csv": (
        Layout(
            xyz=("X (mm)", "Y (mm)", "Z (mm)"),
            u95=("U95 X (mm)", "U95 Y (mm)", "U95 Z (mm)"),
            orientation=("Qx", "Qy", "Qz", "Qw"),
        ),
        [],
    ),
    "X[m], U95 [µm], RX [deg] RY [deg] RZ [deg], SpatialAnalyzer table": (
        Layout(
            xyz=("X[m]", "Y[m]", "Z[m]"),
            u95=("U95 [µm]",),
            orientation=("RX [deg]", "RY [deg]", "RZ [deg]"),
            joints="by name",
            xyz_scale=1e-3,
            u95_scale=1e3,
        ),
        ["--format", "spatialanalyzer"],
    ),
    "A1 [deg]… joints, qw qx qy qz in lower case": (
        Layout(
            orientation=("qw", "qx", "qy", "qz"),
            joint_headers=tuple(f"A{k} [deg]" for k in range(1, 7)),
        ),
        ["--format", "leica", "--angle-unit", "deg"],
    ),
}


@pytest.mark.parametrize("case", list(LAYOUTS))
def test_an_export_imports_unchanged(measured: Measured, tmp_path: Path, case: str) -> None:
    layout, args = LAYOUTS[case]
    src, joints = write_export(tmp_path, measured, layout)
    out = tmp_path / "run.mcap"
    extra = ["--joints-file", str(joints)] if joints is not None else []
    printed = imported(str(src), "-o", str(out), *args, *extra)
    assert "with the target's orientation" in printed
    data = read_log(out)  # no pipeline: the orientation is turned on by the import's record
    assert data.pipeline.streams["point"].orientation
    assert data.pipeline_reason is not None and "orientation" in data.pipeline_reason
    points = data.points
    assert points.equals(read_log(out, fast=False).points)  # the mcap library's decoders agree
    order = np.arange(POSES)
    if layout.joints == "by name":  # the points come in the joints file's order
        order = np.random.default_rng(3).permutation(POSES)
    # positions as exported (mm, 6 decimals), to 1e-9 m
    written = np.round(measured.xyz_mm[order] * layout.xyz_scale, 6) / layout.xyz_scale
    np.testing.assert_allclose(points.select(["x", "y", "z"]).to_numpy(), written * 1e-3, atol=1e-9)
    # the orientation: the exported quaternion (x, y, z, w), or the rotation the angles give
    got = points.select(ORIENTATION_COLUMNS).to_numpy()
    want = measured.quat_wxyz[order][:, [1, 2, 3, 0]]
    if parse_header(layout.orientation[0]).key.startswith("q"):
        np.testing.assert_allclose(got, want, atol=1e-8)
    else:
        angle = (Rotation.from_quat(got).inv() * Rotation.from_quat(want)).magnitude()
        assert np.all(angle < 1e-8), angle.max()
    # the joints, and the U95 as each sample's covariance
    assert data.joints is not None
    assert data.joint_names == [h.split(" ")[0] for h in layout.joint_headers]
    q = data.joints.select([f"q_{j}" for j in range(1, 7)]).to_numpy()[:: len(STOP_JOINT_TIMES)]
    np.testing.assert_allclose(np.degrees(q), measured.joints_deg[order], atol=1e-6)
    cov = points.select(COVARIANCE_COLUMNS).to_numpy()
    u95 = np.array([float(u) for u in measured.u95_mm])[order]
    k = 1.959963984540054 if len(layout.u95) == 3 else 2.7954834829151074
    np.testing.assert_allclose(np.sqrt(cov[:, 0]), u95 * 1e-3 / k, rtol=1e-9)
    np.testing.assert_allclose(cov[:, [1, 2, 4]], 0.0)
    assert "each point's σ was read from" in printed


def test_the_leica_export_processes_with_its_orientation(
    measured: Measured, tmp_path: Path
) -> None:
    """The whole way: the export imported, ``dhlog process`` with the nominal — the orientation
    enters the fit with no pipeline named, and the result gives the probe's frame in the last
    frame (the rotation the test put there)."""
    src, _ = write_export(tmp_path, measured, Layout())
    imported(str(src), "--format", "leica", "-o", str(tmp_path / "run.mcap"))
    done = runner.invoke(
        app,
        [
            "process",
            str(tmp_path / "run.mcap"),
            "--nominal",
            "kr5",
            "--out",
            str(tmp_path / "r"),
            "--no-rrd",
        ],
    )
    assert done.exit_code == 0, done.output
    assert "orientation" in done.output
    doc = json.loads((tmp_path / "r" / "run.dh.json").read_text())
    rotation = np.asarray(doc["tool"]["orientation"]["matrix"])
    angle = (Rotation.from_matrix(rotation).inv() * PROBE_ROTATION).magnitude()
    assert angle < 1e-4, angle
    np.testing.assert_allclose(doc["tool"]["point"], PROBE_POINT, atol=1e-5)


def test_orientation_columns_are_never_joints(measured: Measured, tmp_path: Path) -> None:
    """The issue's export through --format csv: Q0…Q3 are the orientation, the six j columns
    the joints (not ten), and a column the header names as something else is left alone."""
    src, _ = write_export(tmp_path, measured, Layout())
    text = src.read_text().splitlines()
    text[0] += ",Temp [°C],Rx,Ry,Rz"
    text[1:] = [line + ",20.1,1,2,3" for line in text[1:]]
    src.write_text("\n".join(text) + "\n")
    printed = imported(str(src), "-o", str(tmp_path / "run.mcap"))
    assert "joints j1, j2, j3, j4, j5, j6;" in printed
    assert "Q0, Q1, Q2, Q3 (quaternion, scalar first)" in printed
    with (tmp_path / "run.mcap").open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert meta["dhlog.import"]["orientation"] == "true"


def test_joints_counted_from_zero_are_joints_when_named(tmp_path: Path) -> None:
    src = tmp_path / "zero.csv"
    src.write_text("x,y,z,q0,q1,q2,q3,q4,q5\n1,2,3,0,10,20,30,40,50\n")
    printed = imported(str(src), "--joint-columns", "q0,q1,q2,q3,q4,q5")
    assert "joints q0, q1, q2, q3, q4, q5" in printed and "orientation" not in printed


@pytest.mark.parametrize(
    ("text", "key", "unit"),
    [
        ("X [mm]", "x", "mm"),
        ("X (mm)", "x", "mm"),
        ("X[mm]", "x", "mm"),
        ("  x  [ MM ] ", "x", "mm"),
        ("U(95)  [mm]", "u95", "mm"),
        ("U(95)", "u95", None),
        ("U95 X [µm]", "u95x", "µm"),
        ("U_95_X", "u95x", None),
        ("Point Name", "pointname", None),
        ("Point-ID", "pointid", None),
        ("RX [deg]", "rx", "deg"),
        ("Rx (°)", "rx", "°"),
        ("Q0 [-]", "q0", "-"),
        ("A1", "a1", None),
    ],
)
def test_headers_are_read_by_what_they_say(text: str, key: str, unit: str | None) -> None:
    h = parse_header(text)
    assert (h.key, h.unit) == (key, unit)


HEADER = "Point Name,X [mm],Y [mm],Z [mm],U(95)  [mm],Q0,Q1,Q2,Q3,j1,j2"
ROW = "P1,1,2,3,0.020,1,0,0,0,10,20"


@pytest.mark.parametrize(
    ("text", "args", "message", "option"),
    [
        (
            f"{HEADER}\n{ROW}\n",
            ["--length-unit", "m"],
            "states mm but --length-unit m",
            "--length-unit",
        ),
        ("x [ft],y,z,q1\n1,2,3,0\n", [], "states the unit 'ft'", "--length-unit"),
        ("x,y,z,A1 [rad]\n1,2,3,0\n", ["--angle-unit", "deg"], "states rad but", "--angle-unit"),
        (f"{HEADER}\n{ROW}\n{ROW.replace('0.020', '-0.002')}\n", [], "line 3: U(95)", "--no-u95"),
        (f"{HEADER}\n{ROW.replace('0.020', '0.000')}\n", [], "line 2: U(95)", "--no-u95"),
        (f"{HEADER}\n{ROW.replace('0.020', 'n/a')}\n", [], "line 2: U(95)", "--no-u95"),
        (
            f"{HEADER}\n{ROW.replace(',1,0,0,0,', ',0.9,0,0,0,')}\n",
            [],
            "line 2: the quaternion",
            "--orientation-columns",
        ),
        (
            "x,y,z,q0,q1,q2,q3,q4,q5\n1,2,3,1,0,0,0,5,6\n",
            [],
            "joints counted from 0",
            "--joint-columns",
        ),
        (f"{HEADER}\n{ROW}\n", ["--joint-columns", "j1,Q1"], "not a joint", "--joint-columns"),
        (f"{HEADER}\n{ROW}\n", ["--joint-columns", "j1,U(95)"], "not a joint", "--joint-columns"),
        ("x,y,z,Rx,Ry,Rz\n1,2,3,0,0,0\n", [], "has no joint columns", "--joints-file"),
        ("x,y,z,Rx,Ry,Rz,q1\n1,2,3,0,0,0,0\n", ["--euler", "xxy"], "--euler must be", "--euler"),
        (
            "x,y,z,q1,q2\n1,2,3,0,0\n",
            ["--orientation-columns", "q1,q2"],
            "names 2 column(s)",
            "--orientation-columns",
        ),
        ("x,y,z,q1\n1,2,3,0\n", ["--format", "leica"], "has no U95 column", "--no-u95"),
        ("a,b,c,q1\n1,2,3,0\n", [], "no column 'x'", "--x"),
        ("x,y,z,q1\n1,2,3,0\n", ["--name-column", "Point"], "no column 'Point'", "--name-column"),
        (
            "t,x,y,z,q1\n1,1,2,3,0\n0.5,1,2,3,1\n",
            ["--time", "t"],
            "line 3: time does not",
            "--time",
        ),
        ("x,y,z,q1\n1,2,oops,0\n", [], "line 2: z 'oops' is not a number", "--z"),
        ("x,y,z,q1\n1,2,3,0\n1,2\n", [], "line 3: has 2 field(s)", "--format"),
        ("x,y,z,q1\n1,2,3,0\n", ["--format", "nikon"], "--format must be one of", "--format"),
    ],
)
def test_a_bad_export_is_one_line_naming_the_option(
    tmp_path: Path, text: str, args: list[str], message: str, option: str
) -> None:
    src = tmp_path / "bad.csv"
    src.write_text(text)
    result = runner.invoke(app, ["import", str(src), *args])
    assert result.exit_code == 2, result.output
    assert message in result.output and option in result.output, result.output
    assert "Traceback" not in result.output
    assert str(src) in result.output or message.startswith("--format")
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert not (tmp_path / "bad.mcap").exists()


POINTS = "Point Name,X,Y,Z\nP1,1,2,3\nP2,4,5,6\n"


@pytest.mark.parametrize(
    ("points", "joints", "args", "message", "option"),
    [
        ("x,y,z\n1,2,3\n4,5,6\n", "q1\n0\n", [], "rows are matched in order", "--name-column"),
        (POINTS, "Point Name,q1\nP8,0\nP9,0\n", [], "names none of the points", "--name-column"),
        (POINTS, "Point Name,speed\nP1,0\nP2,0\n", [], "has no joint columns", "--joint-columns"),
        (
            POINTS,
            "Point Name,q1\nP1,0\nP2,0\n",
            ["--name-column", "Pt"],
            "no column 'Pt'",
            "--name-column",
        ),
        (
            "P1 1 2 3\nP2 4 5 6\n",
            None,
            ["--format", "spatialanalyzer"],
            "holds no joint values",
            "--joints-file",
        ),
        (
            "P1 1 2 3\nP2 4 5\n",
            "Point,q1\nP1,0\n",
            ["--format", "spatialanalyzer"],
            "line 2: is not 'name x y z'",
            "--format",
        ),
        (POINTS, "missing", [], "cannot be read", "--joints-file"),
    ],
)
def test_a_bad_joints_file_is_one_line_naming_the_option(
    tmp_path: Path,
    points: str,
    joints: str | None,
    args: list[str],
    message: str,
    option: str,
) -> None:
    src = tmp_path / "points.txt"
    src.write_text(points)
    extra = []
    if joints is not None:
        jf = tmp_path / "joints.csv"
        if joints != "missing":
            jf.write_text(joints)
        extra = ["--joints-file", str(jf)]
    result = runner.invoke(app, ["import", str(src), *args, *extra])
    assert result.exit_code == 2, result.output
    assert message in result.output and option in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output


def test_joints_from_a_file_in_every_format(tmp_path: Path) -> None:
    """csv without names, by row; csv with names, by name; the joint columns chosen."""
    src = tmp_path / "p.csv"
    src.write_text("x,y,z\n1,2,3\n4,5,6\n")
    jf = tmp_path / "j.csv"
    jf.write_text("speed,q1,q2,q3\n9,10,20,30\n9,11,21,31\n")
    printed = imported(str(src), "--joints-file", str(jf), "--joint-columns", "q2,q3")
    assert "matched to the points" in printed and "joints q2, q3;" in printed
    data = read_log(tmp_path / "p.mcap")
    assert data.joints is not None
    q = np.degrees(data.joints.select(["q_1", "q_2"]).to_numpy()[:: len(STOP_JOINT_TIMES)])
    np.testing.assert_allclose(q, [[20, 30], [21, 31]])
    named = tmp_path / "n.csv"
    named.write_text("Name,x,y,z\nB,4,5,6\nA,1,2,3\n")
    jf.write_text("Name,q1\nA,1\nB,2\n")
    imported(str(named), "--joints-file", str(jf))
    data = read_log(tmp_path / "n.mcap")
    np.testing.assert_allclose(data.points["x"].to_numpy(), [1e-3, 4e-3])


def test_what_the_options_leave_out(measured: Measured, tmp_path: Path) -> None:
    """--no-u95 and --orientation-columns none leave those out (a plain PointStamped log, the
    Q columns still no joints); a joints file wins over the export's own joint columns, said."""
    src, _ = write_export(tmp_path, measured, Layout())
    printed = imported(
        str(src), "--no-u95", "--orientation-columns", "none", "-o", str(tmp_path / "a.mcap")
    )
    assert "U95" not in printed and "orientation" not in printed
    assert "joints j1, j2, j3, j4, j5, j6;" in printed
    data = read_log(tmp_path / "a.mcap")
    assert not data.pipeline.streams["point"].orientation
    assert "cxx" not in data.points.columns
    joints = tmp_path / "joints.csv"
    joints.write_text(
        "Point Name,A1,A2,A3,A4,A5,A6\n" + "".join(f"{n},1,2,3,4,5,6\n" for n in measured.names)
    )
    printed = imported(str(src), "--joints-file", str(joints), "-o", str(tmp_path / "b.mcap"))
    assert "its joint columns (j1, j2, j3, j4, j5, j6) were left out" in printed
    assert "joints A1, A2, A3, A4, A5, A6;" in printed
