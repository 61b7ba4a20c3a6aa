"""A pipeline as data: per stream its topic, fields and options (:class:`StreamSpec`), the
segmentation tolerances and clock offset (:class:`SegmentationSettings`), a camera pipeline's
image stream (:class:`ImageStreamSpec`) and camera (:class:`CameraSpec`), and the whole
(:class:`Pipeline`); the streams (:data:`STREAMS`), their default topics and the encodings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from dhlog.model.dh import JointType
from dhlog.model.noise import NoiseModel

if TYPE_CHECKING:  # OpenCV imported only when a camera pipeline is read
    from dhlog.vision.boards import BoardSpec
    from dhlog.vision.camera import Intrinsics


STREAMS = ("point", "joints", "base", "phase", "commanded")


DEFAULT_TOPICS = {
    "point": "/tracker/point",
    "joints": "/joint_states",
    "base": "/tracker/base_plane",
    "phase": "/calibration/phase",
    "commanded": "/joint_command",
}


ENCODINGS = ("cdr", "json", "protobuf")


DEFAULT_IMAGE_TOPIC = "/camera/image_raw/compressed"


DEFAULT_INFO_TOPIC = "/camera/camera_info"


@dataclass(frozen=True)
class StreamSpec:
    """One input stream: its topic, whether the pipeline needs it, and JSON field paths."""

    topic: str
    required: bool
    fields: dict[str, str] = field(default_factory=dict)
    extra_topics: tuple[str, ...] = ()
    orientation: bool = False
    child_frame: str = ""
    pose_index: int = 0
    coordinates: str = "cartesian"
    vertical: str = "zenith"


@dataclass(frozen=True)
class SegmentationSettings:
    """Tolerances of the segmentation, in SI units (rad for revolute, m for prismatic joints).

    ``lock_tolerance``: a joint is locked while it stays this close to its locked value.
    ``motion_window``: half-width (s) of the window over which a joint's motion is judged.
    ``join_tolerance``: largest gap (s) between a target sample and the encoder samples around it.
    ``min_samples``: fewest target samples a sweep needs. ``min_sweep``: smallest sweep (rad)
    and ``min_travel`` (m) a segment needs to count as a sweep. ``clock_offset``: seconds added
    to the joint-state stamps to bring them onto the tracker's clock — the start of the
    estimate from the data, or, with ``clock_offset_fixed``, the offset used as it is.
    """

    lock_tolerance: float = 2e-5
    motion_window: float = 0.05
    join_tolerance: float = 0.05
    min_samples: int = 3
    min_sweep: float = math.radians(5.0)
    min_travel: float = 1e-3
    clock_offset: float = 0.0
    clock_offset_fixed: bool = False


@dataclass(frozen=True)
class ImageStreamSpec:
    """A camera pipeline's image stream: ``topic``, and ``alternatives`` read instead of it
    (in order) where the log lacks it."""

    topic: str = DEFAULT_IMAGE_TOPIC
    required: bool = True
    alternatives: tuple[str, ...] = ()


@dataclass(frozen=True)
class CameraSpec:
    """Where a camera pipeline's intrinsics come from: ``info_topic`` (the log's
    ``CameraInfo``), or ``intrinsics`` read from the calibration file ``calibration`` (the
    path as resolved against the pipeline's folder). ``rectified``: whether the images are
    rectified, their intrinsics the camera info's projection ``P`` without distortion (ROS's
    convention: ``K`` and ``D`` describe the raw images); None: as the image topic's name says
    (``image_rect…``, as image_pipeline names them)."""

    info_topic: str | None = DEFAULT_INFO_TOPIC
    calibration: str | None = None
    intrinsics: Intrinsics | None = None
    rectified: bool | None = None


@dataclass(frozen=True)
class Pipeline:
    """A parsed pipeline file."""

    name: str
    description: str
    source: str
    encodings: tuple[str, ...]
    length_unit: str
    streams: dict[str, StreamSpec]
    joint_names: tuple[str, ...] | None
    joint_types: tuple[JointType | None, ...] | None
    segmentation: SegmentationSettings
    noise: NoiseModel = field(default_factory=NoiseModel)
    angle_unit: str = "rad"
    image: ImageStreamSpec | None = None
    camera: CameraSpec | None = None
    target: BoardSpec | None = None

    @property
    def is_camera(self) -> bool:
        """Whether the pipeline reads camera images (``[streams.image]``), not a tracker."""
        return self.image is not None

    @property
    def length_scale(self) -> float:
        """Factor from the log's length unit to metres."""
        return 1e-3 if self.length_unit == "mm" else 1.0

    @property
    def angle_scale(self) -> float:
        """Factor from the log's angle unit (revolute encoders) to radians."""
        return {"deg": math.pi / 180.0, "gon": math.pi / 200.0}.get(self.angle_unit, 1.0)
