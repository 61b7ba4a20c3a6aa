"""Link masses from a URDF (``--masses robot.urdf``): each link's ``<inertial>`` mass and centre
of mass, and the URDF's joint axes, at the reference pose in the URDF's root frame — what the
gravity compliance needs to take the torques from the robot's own masses (read by yourdfpy, the
URDF library the template export uses).

The URDF's joints are matched to the result's by name (else by chain order when the counts
agree); its joint zero is taken to be the encoder zero (as in the robot maker's description).
Every fault of the file is one line naming it and what to do.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray


@dataclass(frozen=True)
class LinkMasses:
    """At the reference pose in the URDF's root frame: per link with a mass, the number of the
    result's joints that move it (``moved_by``: 1 … n), its mass (kg) and centre of mass; and
    the joint axes (points and unit directions, n each); ``matched``: how the joints were
    matched."""

    moved_by: tuple[int, ...]
    masses: FloatArray
    centres: FloatArray
    axis_points: FloatArray
    axis_dirs: FloatArray
    matched: str


def read_link_masses(
    path: str | Path, joint_names: tuple[str, ...], reference_pose: FloatArray
) -> LinkMasses:
    """The link masses of the URDF at ``path`` for a result whose joints are ``joint_names``
    (chain order), at ``reference_pose`` (rad or m)."""
    import yourdfpy  # type: ignore[import-untyped]

    src = str(path)
    try:
        urdf = yourdfpy.URDF.load(src, load_meshes=False, build_scene_graph=True)
    except (OSError, ElementTree.ParseError, ValueError, KeyError, AttributeError) as exc:
        raise InputError(
            f"{src}: cannot be read as a URDF ({type(exc).__name__}: {exc}); a xacro file must "
            "be expanded first (xacro robot.urdf.xacro > robot.urdf)."
        ) from None
    n = len(joint_names)
    actuated = list(urdf.actuated_joint_names)
    moving = {
        name: j
        for name, j in urdf.joint_map.items()
        if j.type in ("revolute", "continuous", "prismatic")
    }
    if all(name in moving for name in joint_names):
        chosen, matched = [moving[name] for name in joint_names], "by name"
    elif len(moving) == n:
        chosen, matched = [urdf.joint_map[name] for name in actuated], "in chain order"
    else:
        raise InputError(
            f"{src}: its moving joints ({', '.join(moving) or 'none'}) are not the result's "
            f"{n} ({', '.join(joint_names)}); give the URDF of this robot, its joints named as "
            "the log's joint states."
        )
    cfg = np.zeros(len(actuated))
    for k, j in enumerate(chosen):
        if j.name in actuated:
            cfg[actuated.index(j.name)] = float(reference_pose[k])
    urdf.update_cfg(cfg)
    root = urdf.base_link
    points, dirs = [], []
    for j in chosen:
        T = np.asarray(urdf.get_transform(j.child, root), dtype=np.float64)
        axis = np.asarray(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=np.float64)
        norm = float(np.linalg.norm(axis))
        if not np.isfinite(norm) or norm == 0.0:
            raise InputError(f"{src}: joint {j.name} has no usable <axis>; give a unit vector.")
        points.append(T[:3, 3])
        dirs.append(T[:3, :3] @ axis / norm)
    parent_of = {j.child: j for j in urdf.joint_map.values()}
    index = {j.name: k for k, j in enumerate(chosen)}
    moved_by, masses, centres = [], [], []
    for name, link in urdf.link_map.items():
        inertial = link.inertial
        if inertial is None or inertial.mass is None:
            continue
        mass = float(inertial.mass)
        if not np.isfinite(mass) or mass < 0:
            raise InputError(f"{src}: link {name} has mass {mass}; give a mass ≥ 0 kg.")
        if mass == 0.0:
            continue
        k, walk = 0, name
        while walk in parent_of:  # the result's joints between the root and this link
            j = parent_of[walk]
            if j.name in index:
                k = max(k, index[j.name] + 1)
            walk = j.parent
        if k == 0:
            continue  # the base: gravity turns no joint with it
        origin = np.eye(4) if inertial.origin is None else np.asarray(inertial.origin, float)
        T = np.asarray(urdf.get_transform(name, root), dtype=np.float64) @ origin
        if not np.all(np.isfinite(T)):
            raise InputError(f"{src}: link {name}'s centre of mass is not finite.")
        moved_by.append(k)
        masses.append(mass)
        centres.append(T[:3, 3])
    if not masses:
        raise InputError(
            f"{src}: no link after the first joint has an <inertial> mass; give the links' "
            "masses, or leave --masses out for the lumped gravity terms."
        )
    return LinkMasses(
        tuple(moved_by),
        np.array(masses),
        np.array(centres),
        np.array(points),
        np.array(dirs),
        matched,
    )
