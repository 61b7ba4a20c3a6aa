"""``dhlog export --template`` with a real vendor xacro, and ``--format tf`` of a tracker result.

The description is Universal Robots' own ur_description (tests/data/xacro/ur_description: a
trimmed copy of github.com/UniversalRobots/Universal_Robots_ROS2_Description at commit
2221ec0f720fb1af99339eb891639b499b62f1da, BSD-3-Clause, its LICENSE beside it): the top-level
``urdf/ur.urdf.xacro`` includes ``$(find ur_description)/urdf/ur_macro.xacro``, whose
``ur_robot`` macro writes the joints with ``${…}`` origins read from the YAML files of
``config/ur5e``. Outputs are expanded by the real xacro package (its ``$(find)`` pointed at that
folder: it needs a ROS 2 ament index otherwise) and loaded by yourdfpy; FK (``dhlog_target`` in
``dhlog_measurement``) must equal ``Calibration.fk`` to 1e-9 m at 200 random joint vectors, and
every mesh, inertial, limit and uncalibrated origin must be the vendor's own expansion's.
"""

from __future__ import annotations

import difflib
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
import yourdfpy  # type: ignore[import-untyped]
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import dhlog
from dhlog.cli.app import app
from dhlog.model.robots import load_robot

UR = Path(__file__).parent / "data" / "xacro" / "ur_description"
TOP = UR / "urdf" / "ur.urdf.xacro"
ARGS = ["--xacro-arg", "ur_type:=ur5e", "--xacro-arg", "name:=ur5e"]
NAMES = load_robot("ur5e").joint_names
runner = CliRunner()


@pytest.fixture
def xacro_expand() -> Iterator[object]:
    """The real xacro's ``process_file``, its ``$(find ur_description)`` the copy's folder."""
    import xacro
    from xacro import substitution_args  # type: ignore[import-untyped]

    find = substitution_args._eval_find
    substitution_args._eval_find = {"ur_description": str(UR)}.__getitem__

    def expand(path: Path) -> str:
        doc = xacro.process_file(str(path), mappings={"ur_type": "ur5e", "name": "ur5e"})
        return str(doc.toxml())

    yield expand
    substitution_args._eval_find = find
    xacro.init_stacks(None)


def _load(text: str, folder: Path, name: str) -> yourdfpy.URDF:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=True)


def _worst(model: yourdfpy.URDF, result: Path) -> float:
    """The largest distance (m) between yourdfpy's dhlog_target in dhlog_measurement and
    Calibration.fk at 200 random joint vectors within ±π (elbow ±π too: the vendor's limit)."""
    calibration = dhlog.load(result)
    Q = np.random.default_rng(7).uniform(-math.pi, math.pi, (200, 6))
    want = calibration.fk(Q)
    worst = 0.0
    for q, p in zip(Q, want, strict=True):
        model.update_cfg(dict(zip(NAMES, q, strict=True)))
        T = model.get_transform("dhlog_target", "dhlog_measurement")
        worst = max(worst, float(np.abs(T[:3, 3] - p).max()))
    return worst


def _assert_vendors_but_origins(vendor: yourdfpy.URDF, ours: yourdfpy.URDF) -> None:
    """Every vendor link's meshes and inertial, every joint's type, axis and limits and every
    uncalibrated joint's origin are the vendor's, exactly."""
    for name, link in vendor.link_map.items():
        mine = ours.link_map[name]
        for kind in ("visuals", "collisions"):
            a, b = getattr(link, kind), getattr(mine, kind)
            assert len(a) == len(b), (name, kind)
            for x, y in zip(a, b, strict=True):
                assert x.geometry.mesh.filename == y.geometry.mesh.filename
                assert np.array_equal(x.origin, y.origin)
        if link.inertial is None:
            assert mine.inertial is None
            continue
        assert link.inertial.mass == mine.inertial.mass
        assert np.array_equal(link.inertial.inertia, mine.inertial.inertia)
        assert np.array_equal(link.inertial.origin, mine.inertial.origin)
    for name, joint in vendor.joint_map.items():
        mine = ours.joint_map[name]
        assert (joint.type, joint.parent, joint.child) == (mine.type, mine.parent, mine.child)
        assert np.array_equal(joint.axis, mine.axis)
        if joint.limit is not None:
            for key in ("lower", "upper", "effort", "velocity"):
                assert getattr(joint.limit, key) == getattr(mine.limit, key), (name, key)
        if name not in NAMES[1:]:
            assert np.array_equal(joint.origin, mine.origin), name
    assert set(ours.joint_map) - set(vendor.joint_map) == {
        "dhlog_measurement_fixed",
        "dhlog_target_fixed",
    }


def _export(result: Path, out: Path, *extra: str) -> str:
    made = runner.invoke(app, ["export", str(result), "-o", str(out), *extra])
    assert made.exit_code == 0, made.output
    return str(made.output)


def test_a_vendor_xacro_gives_a_xacro_with_only_joint_origins_changed(
    ur5e_result: Path, tmp_path: Path, xacro_expand: object
) -> None:
    """``-o cal.urdf.xacro``: the template's text kept line for line (only lines added: the
    calibrated copy of ur_robot after its include, the note, the two dhlog links); the vendor's
    macro file untouched; the output expanded by xacro reproduces Calibration.fk to 1e-9 m and
    the vendor's meshes, inertials and limits."""
    expand = xacro_expand
    assert callable(expand)
    macro = (UR / "urdf" / "ur_macro.xacro").read_bytes()
    out = tmp_path / "cal.urdf.xacro"
    _export(ur5e_result, out, "--template", str(TOP), *ARGS, "--nominal", "ur5e")
    before, after = TOP.read_text().splitlines(), out.read_text().splitlines()
    changed = [d for d in difflib.ndiff(before, after) if d[:1] in "-?"]
    assert not changed, changed[:5]
    assert (UR / "urdf" / "ur_macro.xacro").read_bytes() == macro
    ours = _load(expand(out), tmp_path, "ours.urdf")  # its includes found by $(find)
    vendor = _load(expand(TOP), tmp_path, "vendor.urdf")
    worst = _worst(ours, ur5e_result)
    assert worst < 1e-9, worst
    _assert_vendors_but_origins(vendor, ours)


def test_a_vendor_xacro_gives_the_calibrated_urdf(
    ur5e_result: Path, tmp_path: Path, xacro_expand: object
) -> None:
    """``-o cal.urdf`` from the xacro: the expanded description with calibrated origins."""
    expand = xacro_expand
    assert callable(expand)
    out = tmp_path / "cal.urdf"
    _export(ur5e_result, out, "--template", str(TOP), *ARGS, "--nominal", "ur5e")
    ours = yourdfpy.URDF.load(str(out), load_meshes=False, build_scene_graph=True)
    worst = _worst(ours, ur5e_result)
    assert worst < 1e-9, worst
    _assert_vendors_but_origins(_load(expand(TOP), tmp_path, "vendor.urdf"), ours)


def _published(path: Path) -> tuple[dict[str, tuple[str, np.ndarray, str]], list[dict[str, Any]]]:
    """The launch file's static_transform_publisher nodes (child → (parent, 4×4, unless)), read
    as tf2_ros reads its arguments, and its other entries."""
    doc = yaml.safe_load(path.read_text())
    statics, others = {}, []
    for entry in doc["launch"]:
        node = entry.get("node")
        if node is None or node["exec"] != "static_transform_publisher":
            others.append(entry)
            continue
        words = node["args"].split()
        args = dict(zip(words[::2], words[1::2], strict=True))
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat([float(args[f"--q{k}"]) for k in "xyzw"]).as_matrix()
        T[:3, 3] = [float(args[f"--{k}"]) for k in "xyz"]
        statics[args["--child-frame-id"]] = (args["--frame-id"], T, node["unless"])
    return statics, others


def test_tf_of_a_tracker_result_places_the_tracker_and_the_target(
    ur5e_result: Path, tmp_path: Path
) -> None:
    """``--format tf``: base_link → measurement is the inverse of T_measurement_base, flange →
    tool0 the tool point (to 1e-9); robot_state_publisher takes the ``description`` URDF, and
    runs exactly when the static publishers do not."""
    out = tmp_path / "tf.launch.yaml"
    _export(ur5e_result, out, "--format", "tf")
    statics, others = _published(out)
    calibration = dhlog.load(ur5e_result)
    parent, T, unless = statics["measurement"]
    assert parent == "base_link"
    assert np.abs(np.linalg.inv(T) - calibration.T_base).max() < 1e-9
    parent, T, _ = statics["tool0"]
    assert parent == "flange" and np.abs(T[:3, 3] - calibration.tool_point).max() < 1e-9
    assert np.abs(T[:3, :3] - np.eye(3)).max() < 1e-15
    arg = others[0]["arg"]
    rsp = others[1]["node"]
    assert arg["name"] == "description" and arg["default"] == ""
    assert rsp["exec"] == "robot_state_publisher" and rsp["if"] == unless
    assert rsp["param"] == [
        {"name": "robot_description", "value": "$(command 'cat $(var description)')"}
    ]
    assert unless == '$(eval \'"$(var description)" != ""\')'


def test_tf_with_a_template_is_in_the_templates_links(ur5e_result: Path, tmp_path: Path) -> None:
    """``--format tf --template ur.urdf.xacro``: world → dhlog_measurement and wrist_3_link →
    dhlog_target; composed with the calibrated URDF's world → wrist_3_link (yourdfpy), the
    target in the measurement frame is Calibration.fk to 1e-9 m."""
    out = tmp_path / "tf.launch.yaml"
    _export(ur5e_result, out, "--format", "tf", "--template", str(TOP), *ARGS, "--nominal", "ur5e")
    statics, _ = _published(out)
    (root, B, _), (last, target, _) = statics["dhlog_measurement"], statics["dhlog_target"]
    assert (root, last) == ("world", "wrist_3_link")
    urdf = tmp_path / "cal.urdf"
    _export(ur5e_result, urdf, "--template", str(TOP), *ARGS, "--nominal", "ur5e")
    model = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True)
    calibration = dhlog.load(ur5e_result)
    Q = np.random.default_rng(3).uniform(-math.pi, math.pi, (50, 6))
    for q, p in zip(Q, calibration.fk(Q), strict=True):
        model.update_cfg(dict(zip(NAMES, q, strict=True)))
        wrist = model.get_transform("wrist_3_link", "world")
        got = np.linalg.inv(B) @ wrist @ target
        assert np.abs(got[:3, 3] - p).max() < 1e-9


# ---------------------------------------------------------------------------------------------
# bad inputs: one line, exit 2, nothing written


def _refused(result: Path, out: Path, *extra: str, code: int = 2) -> str:
    """One line and the exit code: 2 for an input that cannot be used, 1 for options."""
    made = runner.invoke(app, ["export", str(result), "-o", str(out), *extra])
    lines = [line for line in made.output.splitlines() if line.strip()]
    assert made.exit_code == code and len(lines) == 1, made.output
    assert "Traceback" not in made.output
    return lines[0]


def test_bad_templates_are_one_line(ur5e_result: Path, tmp_path: Path) -> None:
    """Not XML; a xacro that does not expand (an argument missing, a macro undefined, a
    package not found); joints
    not matching (named); the output the template or a file it includes; a xacro output of a
    URDF template and a --xacro-arg without ':=' (options: exit 1)."""
    out = tmp_path / "out.urdf"
    junk = tmp_path / "junk.urdf.xacro"
    junk.write_text("this is not <xml")
    assert "not well-formed XML" in _refused(ur5e_result, out, "--template", str(junk))
    line = _refused(ur5e_result, out, "--template", str(TOP), "--xacro-arg", "ur_type:=ur5e")
    assert "cannot be expanded by xacro" in line and "name" in line
    broken = tmp_path / "broken.urdf.xacro"
    broken.write_text(
        '<robot xmlns:xacro="http://wiki.ros.org/xacro" name="r"><xacro:no_such_macro/></robot>'
    )
    line = _refused(ur5e_result, out, "--template", str(broken))
    assert "cannot be expanded by xacro" in line and "no_such_macro" in line
    elsewhere = tmp_path / "cell.urdf.xacro"  # includes $(find ur_description) from elsewhere
    elsewhere.write_text(TOP.read_text())
    line = _refused(ur5e_result, out, "--template", str(elsewhere), *ARGS)
    assert "needs the ROS package ur_description" in line and "ROS_PACKAGE_PATH" in line
    line = _refused(ur5e_result, out, "--template", str(TOP), *ARGS)  # no --nominal: joint_1 …
    assert "has no joint joint_1, joint_2" in line and "shoulder_pan_joint" in line
    same = tmp_path / "mine.urdf.xacro"
    same.write_text(TOP.read_text())
    (tmp_path / "package.xml").write_text("<package><name>other</name></package>")
    text = same.read_bytes()
    line = _refused(ur5e_result, same, "--template", str(same), *ARGS, "--force")
    assert "mine.urdf.xacro" in line and same.read_bytes() == text
    macro = UR / "urdf" / "ur_macro.xacro"
    held = macro.read_bytes()
    line = _refused(
        ur5e_result, macro, "--template", str(TOP), *ARGS, "--nominal", "ur5e", "--force"
    )
    assert "ur_macro.xacro" in line and macro.read_bytes() == held
    plain = tmp_path / "plain.urdf"
    _export(ur5e_result, plain, "--nominal", "ur5e")
    line = _refused(ur5e_result, tmp_path / "x.urdf.xacro", "--template", str(plain), code=1)
    assert "is a URDF, not a xacro" in line
    line = _refused(ur5e_result, out, "--template", str(TOP), "--xacro-arg", "ur=5", code=1)
    assert "NAME:=VALUE" in line
    assert not out.exists() and not (tmp_path / "x.urdf.xacro").exists()


def test_a_joint_its_xacro_cannot_take_is_named(ur5e_result: Path, tmp_path: Path) -> None:
    """A joint whose origin comes from xacro:insert_block has no place for the calibrated one
    in a xacro output: named with its file; the URDF output still works."""
    folder = tmp_path / "desc"
    folder.mkdir()
    joints = "".join(
        f'<link name="l{k}"/><joint name="{n}" type="revolute"><parent link="l{k - 1}"/>'
        f'<child link="l{k}"/><xacro:insert_block name="o{k}"/><axis xyz="0 0 1"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        for k, n in enumerate(NAMES, start=1)
    )
    blocks = "".join(f'<o{k}><origin xyz="0 0 0.1"/></o{k}>' for k in range(1, 7))
    params = " ".join(f"*o{k}" for k in range(1, 7))
    (folder / "arm.urdf.xacro").write_text(
        '<robot xmlns:xacro="http://wiki.ros.org/xacro" name="arm"><link name="l0"/>'
        f'<xacro:macro name="arm" params="{params}">{joints}</xacro:macro>'
        f"<xacro:arm>{blocks}</xacro:arm></robot>"
    )
    template = folder / "arm.urdf.xacro"
    line = _refused(
        ur5e_result, tmp_path / "x.urdf.xacro", "--template", str(template), "--nominal", "ur5e"
    )
    assert "joint shoulder_lift_joint is written in arm.urdf.xacro without an <origin>" in line
    _export(ur5e_result, tmp_path / "x.urdf", "--template", str(template), "--nominal", "ur5e")
    assert ET.parse(tmp_path / "x.urdf").getroot().get("name") == "arm"


def test_the_python_api_writes_the_xacro_and_refuses_a_vendor_file(
    ur5e_result: Path, tmp_path: Path
) -> None:
    """``Calibration.export(template=…, xacro_args=…)``: a ``.xacro`` path gets the xacro (the
    same text the command writes); a path that is a file the template includes is refused."""
    calibration = dhlog.load(ur5e_result, nominal="ur5e")
    args = {"ur_type": "ur5e", "name": "ur5e"}
    out = tmp_path / "api.urdf.xacro"
    text = calibration.export("urdf", out, template=TOP, xacro_args=args)
    assert out.read_text() == text and 'xacro:macro name="ur_robot"' in text
    cli = tmp_path / "cli.urdf.xacro"
    _export(ur5e_result, cli, "--template", str(TOP), *ARGS, "--nominal", "ur5e")
    assert cli.read_text() == text
    with pytest.raises(dhlog.UsageError, match=r"ur_macro\.xacro"):
        calibration.export(
            "urdf", UR / "urdf" / "ur_macro.xacro", template=TOP, xacro_args=args, overwrite=True
        )


def test_an_included_file_with_a_doctype_is_refused(ur5e_result: Path, tmp_path: Path) -> None:
    """Every file xacro reads is checked as the template is: an include with a DOCTYPE (the door
    to entity expansion) is one line naming it, before xacro parses it."""
    (tmp_path / "evil.xacro").write_text(
        '<!DOCTYPE r [<!ENTITY a "aaaa">]><robot xmlns:xacro="http://wiki.ros.org/xacro"/>'
    )
    top = tmp_path / "top.urdf.xacro"
    top.write_text(
        '<robot xmlns:xacro="http://wiki.ros.org/xacro" name="r">'
        '<xacro:include filename="evil.xacro"/></robot>'
    )
    line = _refused(ur5e_result, tmp_path / "x.urdf", "--template", str(top))
    assert "evil.xacro" in line and "DOCTYPE" in line


#: A description in the style of the ROS-Industrial ``*_support`` packages' xacros (one file: its
#: dimensions as xacro:property, a macro with ``${prefix}`` names and ``${…}`` origins, called
#: once), with a UR5e's joint origins as ur_description's config/ur5e/default_kinematics.yaml
#: gives them (tests/data/ur_description.toml), a mesh and an inertial on every link.
ONE_FILE = """<?xml version="1.0"?>
<robot xmlns:xacro="http://wiki.ros.org/xacro" name="ur5e_ros_industrial_style">
  <xacro:property name="d1" value="0.1625"/>
  <xacro:property name="a2" value="-0.425"/>
  <xacro:property name="a3" value="-0.3922"/>
  <xacro:property name="d4" value="0.1333"/>
  <xacro:property name="d5" value="0.0997"/>
  <xacro:property name="d6" value="0.0996"/>
  <xacro:macro name="arm" params="prefix">
    <link name="${prefix}base_link"/>
    LINKS
    JOINTS
  </xacro:macro>
  <xacro:arm prefix=""/>
</robot>
"""
_ORIGINS = (
    ("0 0 ${d1}", "0 0 0"),
    ("0 0 0", "${pi/2} 0 0"),
    ("${a2} 0 0", "0 0 0"),
    ("${a3} 0 ${d4}", "0 0 0"),
    ("0 ${-d5} 0", "${pi/2} 0 0"),
    ("0 ${d6} 0", "${pi/2} ${pi} ${pi}"),
)


def _one_file_xacro() -> str:
    links, joints = [], []
    parent = "${prefix}base_link"
    for k, (name, (xyz, rpy)) in enumerate(zip(NAMES, _ORIGINS, strict=True), start=1):
        links.append(
            f'<link name="${{prefix}}link_{k}"><visual><geometry><mesh filename="package://'
            f'arm_support/meshes/link_{k}.stl"/></geometry></visual><inertial><mass value="{k}"/>'
            f'<inertia ixx="0.{k}" ixy="0" ixz="0" iyy="0.{k}" iyz="0" izz="0.{k}"/></inertial>'
            "</link>"
        )
        joints.append(
            f'<joint name="${{prefix}}{name}" type="revolute">\n'
            f'      <origin xyz="{xyz}" rpy="{rpy}"/>\n'
            f'      <parent link="{parent}"/><child link="${{prefix}}link_{k}"/>'
            f'<axis xyz="0 0 1"/>\n'
            f'      <limit lower="${{-2*pi}}" upper="${{2*pi}}" effort="{k}" velocity="3.14"/>\n'
            "    </joint>"
        )
        parent = f"${{prefix}}link_{k}"
    return ONE_FILE.replace("LINKS", "\n    ".join(links)).replace("JOINTS", "\n    ".join(joints))


def test_a_one_file_xacro_gets_its_own_origins_rewritten(ur5e_result: Path, tmp_path: Path) -> None:
    """Joints written in the template itself: each calibrated ``<origin>`` line replaced by
    numbers, every other line (the properties, the links, joint 1's origin) as it was; expanded
    by xacro, FK = Calibration.fk to 1e-9 m, meshes, inertials and limits the template's."""
    import xacro

    template = tmp_path / "arm.urdf.xacro"
    template.write_text(_one_file_xacro())
    out = tmp_path / "arm_calibrated.urdf.xacro"
    _export(ur5e_result, out, "--template", str(template), "--nominal", "ur5e")
    before, after = template.read_text().splitlines(), out.read_text().splitlines()
    assert "calibrated by dhlog export" in after.pop(2)  # the note after <robot>
    block = next(k for k, line in enumerate(after) if 'name="dhlog_measurement"' in line)
    assert after[-1] == "</robot>" and all("dhlog" in x or "<" in x for x in after[block:-1])
    after = after[:block] + after[-1:]  # without the tracker's frame and the target (end)
    assert len(after) == len(before)
    changed = [(a, b) for a, b in zip(before, after, strict=True) if a != b]
    assert len(changed) == 5, changed  # the calibrated joints' origins: joints 2 … 6
    assert all(a.strip().startswith("<origin xyz=") and "${" not in b for a, b in changed)
    expanded = xacro.process_file(str(out)).toxml()
    xacro.init_stacks(None)
    ours = _load(expanded, tmp_path, "ours.urdf")
    vendor = _load(xacro.process_file(str(template)).toxml(), tmp_path, "vendor.urdf")
    xacro.init_stacks(None)
    worst = _worst(ours, ur5e_result)
    assert worst < 1e-9, worst
    _assert_vendors_but_origins(vendor, ours)


def test_xacros_own_output_is_a_urdf(tmp_path: Path) -> None:
    """A URDF that declares xacro's namespace (as xacro's output does) and uses nothing of it is
    read as a URDF; a name in .xacro, an element of xacro's or a ${…} make a xacro."""
    from dhlog.result.export.expand import is_xacro

    plain = tmp_path / "expanded.urdf"
    plain.write_text(
        '<robot xmlns:xacro="http://wiki.ros.org/xacro" name="r"><link name="a"/></robot>'
    )
    assert not is_xacro(plain)
    for name, body in (("a.xacro", "<link name='a'/>"), ("b.urdf", "<xacro:property name='x'/>"),
                       ("c.urdf", "<link name='${x}'/>")):  # fmt: skip
        path = tmp_path / name
        path.write_text(f'<robot xmlns:xacro="http://wiki.ros.org/xacro" name="r">{body}</robot>')
        assert is_xacro(path), name
