"""What a result's recording shows and how large: the colours and time lines every part shares,
the scene's sizes from the robot's extent (:class:`Scene`), the result read once into what is
drawn (:class:`Shown`: samples, DH frames, the base frame, the camera) and the magnifications of
the residual, held-out and deflection views (1-2-5 numbers)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dhlog.geometry._checks import FloatArray
from dhlog.identify.check.validate import shown_stride
from dhlog.identify.segment.persample import PerSample
from dhlog.model.dh import JointType
from dhlog.model.fk import fk_frames

if TYPE_CHECKING:
    from dhlog.identify.run import Identification


#: Joint colours, joint k the (k − 1)-th (cycling).
PALETTE = np.array(
    [
        [230, 25, 75],
        [60, 180, 75],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [170, 110, 40],
        [128, 128, 0],
        [0, 0, 128],
    ],
    dtype=np.uint8,
)
#: Samples set aside by the segmentation (dimmed grey).
DIM = np.array([150, 150, 150, 90], dtype=np.uint8)
#: The time line of the samples' own stamps.
TIMELINE = "sensor_time"
#: The time line of the residual plots: the moved joint's encoder value (revolute in
#: millidegrees, prismatic in micrometres), so bias and periodic errors show against the angle.
JOINT_TIMELINE = "joint_position"


def joint_color(k: int) -> FloatArray:
    """Joint ``k``'s colour (RGB, uint8)."""
    return np.asarray(PALETTE[(k - 1) % len(PALETTE)])


def time_column(t_ns: np.ndarray) -> rr.TimeColumn:
    """Stamps (integer ns) as a column of the sensor time line."""
    return rr.TimeColumn(
        TIMELINE, timestamp=np.asarray(t_ns, dtype=np.int64).astype("datetime64[ns]")
    )


@dataclass(frozen=True)
class Scene:
    """Sizes chosen from the robot's extent ``E`` (m) so that the picture reads at any size:
    samples, lines, arrows and frame axes are fixed fractions of it."""

    extent: float

    @property
    def sample(self) -> float:
        return 0.004 * self.extent

    @property
    def line(self) -> float:
        return 0.0012 * self.extent

    @property
    def arrow(self) -> float:
        return 0.18 * self.extent

    @property
    def frame(self) -> float:
        return 0.07 * self.extent


@dataclass(frozen=True)
class Shown:
    """What a result's recording draws, read from the result once: the samples (``xyz`` in M,
    ``t`` stamps, ``q`` encoder values or None; read by table rows as they are drawn), every
    how many rows of the table are drawn (``stride``: the viewer shows no more than
    :data:`~dhlog.identify.check.validate.SHOWN_SAMPLES`), the DH frames of the shown table, the
    transform from M to the displayed base frame and the scene's sizes."""

    result: Identification
    xyz: FloatArray | PerSample
    t: np.ndarray
    q: FloatArray | PerSample | None
    frames: FloatArray | None
    T: FloatArray
    scene: Scene
    stride: int = 1

    @classmethod
    def of(cls, result: Identification) -> Shown:
        seg = result.segmentation
        stride = shown_stride(seg.height)
        xyz = PerSample((seg.height, 3), seg.xyz)
        q = PerSample((seg.height, seg.n_joints), seg.q) if seg.encoders is not None else None
        frames: FloatArray | None = None
        T: FloatArray = np.eye(4)
        ex = result.extraction
        if ex is not None:
            frames = ex.frames
            if result.conditioned is not None:  # the Hayati table's frames: the standard
                # table's origins run off along near-parallel axes (d of metres)
                frames = fk_frames(
                    result.conditioned.table, ex.reference_pose, T_base=ex.T_measurement_base
                )
            frames = frames if result.complete else frames[:-1]
            # M → the base frame (DH frame 1, z along axis 1), turned over when the robot's
            # frames (its structure, not where it reaches) lie below it: it stands on the grid
            T = np.asarray(np.linalg.inv(ex.T_measurement_base), dtype=np.float64)
            if float(np.median(frames[:, :3, 3] @ T[2, :3] + T[2, 3])) < 0.0:
                T = np.diag([1.0, -1.0, -1.0, 1.0]) @ T
        some = xyz[::stride]
        centre = ex.T_measurement_base[:3, 3] if ex is not None else np.median(some, axis=0)
        reach = float(np.max(np.linalg.norm(some - centre, axis=1))) if some.size else 1.0
        return cls(result, xyz, seg.t_ns, q, frames, T, Scene(max(reach, 0.05)), stride)

    def drawn(self, rows: np.ndarray) -> np.ndarray:
        """The table ``rows`` (ascending) the recording draws: every :attr:`stride`-th row."""
        return rows if self.stride == 1 else rows[rows % self.stride == 0]

    def position(self, rows: np.ndarray, joint: int) -> np.ndarray:
        """The moved joint's encoder value at ``rows`` on the joint time line (m°, or µm)."""
        if self.q is None:
            return np.zeros(rows.size, dtype=np.int64)
        prismatic = self.result.joints[joint - 1].type is JointType.PRISMATIC
        scale = 1e6 if prismatic else 180e3 / math.pi
        return np.asarray(np.round(np.nan_to_num(self.q[rows, joint - 1]) * scale), np.int64)

    def eye(self) -> rrb.EyeControls3D:
        """A camera on the robot (not on the probed base area, which may be much wider):
        looking at the samples' centre from the front-right, above, at 1.9 times the robot's
        extent."""
        T = self.T
        xyz = self.xyz[:: self.stride]
        centre = np.median(xyz @ T[:3, :3].T + T[:3, 3], axis=0) if xyz.size else np.zeros(3)
        centre[2] *= 0.6  # a little towards the floor: the base stays in the picture
        towards = np.array([1.0, -1.3, 0.8])
        eye = centre + 1.9 * self.scene.extent * towards / np.linalg.norm(towards)
        return rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital, position=eye, look_target=centre, eye_up=[0.0, 0.0, 1.0]
        )

    def magnification(self) -> float:
        """The factor that makes the FK residuals about 2 % of the robot's extent in 3D."""
        v = self.result.validation
        if v is None or not math.isfinite(v.rms) or v.rms <= 0:
            return 1.0
        return _nice(0.02 * self.scene.extent / v.rms)


def _nice(value: float) -> float:
    """The 1-2-5 number nearest below ``value`` (≥ 1)."""
    if not math.isfinite(value) or value <= 1.0:
        return 1.0
    exp = 10 ** math.floor(math.log10(value))
    return float(max(m * exp for m in (1, 2, 5) if m * exp <= value))


def holdout_magnification(shown: Shown) -> float:
    """The factor that makes the largest held-out RMS error about 4 % of the robot's extent."""
    worst = max(
        (
            s.rms
            for h in shown.result.holdout
            for s in (h.nominal, h.calibrated)
            if s is not None and s.rms > 0
        ),
        default=0.0,
    )
    return _nice(0.04 * shown.scene.extent / worst) if worst > 0 else 1.0


def deflection_magnification(shown: Shown) -> float:
    """The factor that makes the terms' largest displacement of the target about 4 % of the
    robot's extent."""
    worst = shown.result.deflection_target
    return _nice(0.04 * shown.scene.extent / worst) if worst > 0 else 1.0
