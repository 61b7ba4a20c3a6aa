"""A library entry against its vendor's URDF, as a URDF consumer composes it.

The vendor's description (its xacro expanded to plain URDF, meshes and all, kept under
``tests/data/vendor/`` with the repository and commit it came from) is loaded by yourdfpy, the
joints set by their names, and the transform from the description's base link to its flange link
read from yourdfpy's scene graph: the frames a ROS user's tf tree would show. The library entry's
FK to its last DH frame must be that transform at random joint vectors within the limits — after
one constant rotation of the flange frame where the vendor's flange link is turned against the DH
frame (ROS-Industrial's ``tool0`` has z out of the flange like DH frame n, but its x is the
vendor's choice), given by the caller as the rotation of the vendor's flange frame in DH frame n.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yourdfpy  # type: ignore[import-untyped]

from dhlog.geometry._checks import FloatArray
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot

VENDOR = Path(__file__).parent / "data" / "vendor"


def load_vendor_urdf(name: str) -> yourdfpy.URDF:
    """``tests/data/vendor/<name>.urdf`` without its meshes (their ``package://`` paths are not
    resolved: only the kinematics is compared)."""
    return yourdfpy.URDF.load(
        str(VENDOR / f"{name}.urdf"),
        load_meshes=False,
        build_scene_graph=True,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


def vendor_fk(urdf: yourdfpy.URDF, joints: tuple[str, ...], q: FloatArray, base: str, tip: str):
    """The vendor description's ``base`` → ``tip`` transform at joint values ``q`` (named
    ``joints``, in the library's chain order)."""
    urdf.update_cfg(dict(zip(joints, (float(v) for v in q), strict=True)))
    return np.asarray(urdf.get_transform(frame_to=tip, frame_from=base), dtype=np.float64)


def worst_fk_difference(
    robot: Robot,
    urdf: yourdfpy.URDF,
    *,
    base: str,
    tip: str,
    flange_rotation: FloatArray | None = None,
    samples: int = 200,
    seed: int = 40,
) -> tuple[float, float]:
    """Largest position (m) and rotation-matrix element difference between the library entry's
    last DH frame (turned by ``flange_rotation``) and the vendor's ``tip`` over ``samples`` random
    joint vectors within the entry's limits."""
    R_tip = np.eye(3) if flange_rotation is None else np.asarray(flange_rotation, dtype=float)
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (samples, robot.n))
    worst_p = worst_r = 0.0
    for q in Q:
        ours = fk_frames(robot.table, q, T_base=robot.T_base)[-1]
        theirs = vendor_fk(urdf, robot.joint_names, q, base, tip)
        worst_p = max(worst_p, float(np.abs(ours[:3, 3] - theirs[:3, 3]).max()))
        worst_r = max(worst_r, float(np.abs(ours[:3, :3] @ R_tip - theirs[:3, :3]).max()))
    return worst_p, worst_r


def chain_joints(urdf: yourdfpy.URDF, base: str, tip: str) -> list[yourdfpy.Joint]:
    """The description's moving joints from ``base`` to ``tip``, base first (its fixed joints and
    any joint off that chain left out)."""
    joints: list[yourdfpy.Joint] = []
    link = tip
    while link != base:
        joint = next(j for j in urdf.robot.joints if j.child == link)
        if joint.type != "fixed":
            joints.insert(0, joint)
        link = joint.parent
    return joints
