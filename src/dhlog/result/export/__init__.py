"""A result in the forms robot stacks load: a URDF (:mod:`.urdf`), a user's URDF template with
calibrated origins (:mod:`.template`, the template read in :mod:`.templatefile`, a xacro expanded
in :mod:`.expand`; a xacro template written back as a xacro: :mod:`.xacroout`), ROS 2 tf
(:mod:`.tf`), the UR
description's calibration file in the factory's shape (:mod:`.ur`), a roboticstoolbox robot
(:mod:`.robotics`), the plain DH tables
(:mod:`.tables`), a camera calibration's hand-eye poses as fixed URDF links and ROS 2 static
transforms (:mod:`.camera`); each reads the result through :mod:`.source`."""

from dhlog.result.export.camera import static_transforms_document
from dhlog.result.export.robotics import rtb_document
from dhlog.result.export.tables import dh_table_document
from dhlog.result.export.template import urdf_from_template
from dhlog.result.export.tf import tf_document
from dhlog.result.export.ur import ur_calibration
from dhlog.result.export.urdf import urdf_document
from dhlog.result.export.xacroout import xacro_from_template

__all__ = [
    "dh_table_document",
    "rtb_document",
    "static_transforms_document",
    "tf_document",
    "ur_calibration",
    "urdf_document",
    "urdf_from_template",
    "xacro_from_template",
]
