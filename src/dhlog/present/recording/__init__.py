"""The Rerun recording of a processed log (``<stem>.rrd``) and of a robot (``dhlog show``).

One ``log_*`` function per thing shown. Fitted geometry is static; samples and residuals are on
two time lines: ``sensor_time`` (the samples' own stamps) and ``joint_position`` (the moved
joint's encoder value, m° or µm: the residual plots' x axis), sent as columns. Each run is its
own recording (a new recording id; the log's hash is a property). The default blueprint opens
on the 3D view and the DH table, the per-joint residual plots below the table, side panels
closed; ``dhlog.present.render`` draws it headless to check it.

By concern: ``scene`` (colours, time lines, sizes, :class:`Shown`, magnifications), ``spatial``
(the ``log_*`` of the 3D view), ``residuals`` (the residual plots), ``camera`` (a camera
calibration's frames, corners, pinhole and board: ``log_cameras``, ``camera_tabs``; imported
only when a result has cameras), ``blueprint`` (the layout), ``stream`` (a recording written
atomically), ``writers`` (the two recordings).

Entities (``world`` is the robot's base frame, DH frame 1, z up; ``world/m`` carries the
measurement frame M into it, so everything below is logged in M):

* ``world/m/samples/segment_<k>`` target samples of each sweep (joint colours, sized from the
  robot's extent), ``world/m/samples/set_aside`` the others (dimmed), ``.../outliers`` (red:
  the sweep fits'), ``.../fit_outliers`` (red: the whole-model fit's); the set-aside samples
  and the fit's outliers labelled with the export's point ids where the log carries them;
* ``world/m/joints/j<k>/fit`` the fitted arc over the swept range (or the line over the travel),
  thin and lighter than its samples; ``world/m/joints/j<k>/axis`` the axis, an arrow ``Jk``;
* ``world/m/dh/frame_<i>`` DH frame i of the shown table (Hayati rows included), labelled once
  per place (``world/m/dh/labels``); ``world/m/robot/links`` segments between frame origins;
* ``world/m/base_plane`` probed base points and the fitted plane's outline;
* ``world/m/magnified/j<k>`` each sample at FK + k × FK residual (k in the view's name);
* ``world/m/holdout/<check>/{poses,nominal,calibrated}`` held-out poses (labelled with the
  point ids where the log carries them) and their magnified errors; ``world/m/deflection``
  the target's displacement by the terms beyond the geometry;
* ``sweeps`` one text line per sweep on the sensor time line;
* ``residuals/{fk,fit}/j<k>/{radial,axial,tangential}`` signed residual components (mm);
* ``report/dh_table`` the DH tables, fits, set-aside counts and nominal as Markdown;
* a camera calibration's (``result.cameras``): ``world/base`` the robot's base frame,
  ``world/base/cameras/<cam>`` each camera (``.../image`` its pinhole and frames, compressed, on
  ``sensor_time``; ``.../image/{detected,reprojected,errors}`` in pixels),
  ``world/base/boards/<cam>`` the board's corners, ``report/cameras/<cam>`` its summary (see
  :mod:`~dhlog.present.recording.camera`).
"""

from dhlog.present.recording.residuals import Residuals, residual_parts
from dhlog.present.recording.stream import recording_file
from dhlog.present.recording.writers import write_process_recording, write_robot_recording

__all__ = [
    "Residuals",
    "recording_file",
    "residual_parts",
    "write_process_recording",
    "write_robot_recording",
]
