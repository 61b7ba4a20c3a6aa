"""Deprecated since 0.2, removed in 0.3: ``dhlog.identify.vision`` (the camera run, as an earlier
README documented it) is the package ``dhlog.identify.camera`` now, private, split by what each part
does; use ``dhlog.process(log, ...)`` on a camera log (``import dhlog``). This path warns once (a
``DeprecationWarning``) and hands on the module's public names from where they live now.
"""

from dhlog._deprecated import moved
from dhlog.identify.camera.checks import MOVED_DROP as MOVED_DROP
from dhlog.identify.camera.checks import MOVED_MIN_FRAMES as MOVED_MIN_FRAMES
from dhlog.identify.camera.checks import MOVED_SPLITS as MOVED_SPLITS
from dhlog.identify.camera.checks import SCALE_MIN_LENGTH as SCALE_MIN_LENGTH
from dhlog.identify.camera.checks import SCALE_TOLERANCE as SCALE_TOLERANCE
from dhlog.identify.camera.checks import SMALL_EFFECT as SMALL_EFFECT
from dhlog.identify.camera.checks import board_scale as board_scale
from dhlog.identify.camera.checks import camera_moved as camera_moved
from dhlog.identify.camera.checks import frame_clustered as frame_clustered
from dhlog.identify.camera.checks import placed_nominal_px as placed_nominal_px
from dhlog.identify.camera.flow import MIN_FRAMES as MIN_FRAMES
from dhlog.identify.camera.flow import process_observations as process_observations
from dhlog.identify.camera.hand_eye import hand_eye as hand_eye
from dhlog.identify.camera.holdout import cross_validate_pixels as cross_validate_pixels
from dhlog.identify.camera.poses import PNP_RMS as PNP_RMS
from dhlog.identify.camera.poses import board_poses as board_poses
from dhlog.identify.camera.poses import corners_of as corners_of
from dhlog.identify.camera.poses import of_frames as of_frames
from dhlog.identify.camera.report import CameraResult as CameraResult
from dhlog.identify.camera.report import PixelHoldout as PixelHoldout
from dhlog.identify.camera.view import camera_view as camera_view

moved("dhlog.identify.vision", "dhlog.process(log, ...)", now="dhlog.identify.camera")
