"""The default layout of a result's recording (one blueprint function): the 3D views on the
left, the DH table above the per-joint residual plots on the right, each plot ranged to its
data, side panels closed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import rerun.blueprint as rrb

from dhlog.model.dh import JointType
from dhlog.present.recording.camera import base_in_world, camera_tabs
from dhlog.present.recording.residuals import Residuals
from dhlog.present.recording.scene import (
    JOINT_TIMELINE,
    TIMELINE,
    Shown,
    deflection_magnification,
    holdout_magnification,
)

if TYPE_CHECKING:
    from dhlog.vision.view import CameraView


def process_blueprint(
    shown: Shown, k: float, found: list[Residuals], cameras: Sequence[CameraView] = ()
) -> rrb.Blueprint:
    """The default layout: the 3D evidence (samples and fits; FK residuals magnified) on the
    left, the DH table above the per-joint residual plots on the right, side panels closed.
    With ``cameras``, a tab per camera after the first (``camera.camera_tabs``: its frames on
    the ``sensor_time`` line; unless there are residual plots, which are ranged on
    ``joint_position``, the time panel then shows that line and the first camera's tab is
    open) and the main 3D view without them (it shows every time at once)."""
    result = shown.result
    eye = shown.eye()
    everything = [
        rrb.VisibleTimeRange(
            timeline,
            start=rrb.TimeRangeBoundary.infinite(),
            end=rrb.TimeRangeBoundary.infinite(),
        )
        for timeline in (TIMELINE, JOINT_TIMELINE)
    ]

    def view(res: Residuals, title: str) -> rrb.TimeSeriesView:
        (x0, x1), (y0, y1) = res.ranges()
        prismatic = result.joints[res.joint - 1].type is JointType.PRISMATIC
        return rrb.TimeSeriesView(
            name=f"J{res.joint} {title[:-1].lower().replace('fk', 'FK')} [mm] vs "
            f"q{res.joint} [{'µm' if prismatic else 'm°'}]",
            origin=f"residuals/{res.kind}/j{res.joint}",
            plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.RightTop, visible=True),
            time_ranges=everything,
            axis_x=rrb.TimeAxis(
                link=rrb.components.LinkAxis.Independent,
                view_range=rrb.TimeRange(
                    start=rrb.TimeRangeBoundary.absolute(seq=x0),
                    end=rrb.TimeRangeBoundary.absolute(seq=x1),
                ),
            ),
            axis_y=rrb.ScalarAxis(range=(y0, y1)),
        )

    def plots(kind: str, title: str) -> rrb.Grid:
        return rrb.Grid(*[view(res, title) for res in found if res.kind == kind], name=title)

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(
                rrb.Spatial3DView(
                    name="Samples and fits [m, robot base frame]",
                    origin="world",
                    contents=[
                        "+ $origin/**",
                        "- $origin/m/magnified/**",
                        "- $origin/m/holdout/**",
                        "- $origin/m/deflection/**",
                        *(["- $origin/base/cameras/**"] if cameras else []),
                    ],
                    time_ranges=everything,
                    eye_controls=eye,
                ),
                *camera_tabs(cameras, base_in_world(shown)),
                *(
                    [
                        rrb.Spatial3DView(
                            name=f"Held-out errors ×{holdout_magnification(shown):g}: nominal "
                            "orange, calibrated green [m, robot base frame]",
                            origin="world",
                            contents=[
                                "+ $origin/m/holdout/**",
                                "+ $origin/m/joints/**",
                                "+ $origin/m/robot/**",
                            ],
                            eye_controls=eye,
                        )
                    ]
                    if result.holdout
                    else []
                ),
                *(
                    [
                        rrb.Spatial3DView(
                            name=f"Deflection by the terms ×{deflection_magnification(shown):g} "
                            "(compliance, harmonics) [m, robot base frame]",
                            origin="world",
                            contents=[
                                "+ $origin/m/deflection/**",
                                "+ $origin/m/joints/**",
                                "+ $origin/m/robot/**",
                            ],
                            eye_controls=eye,
                        )
                    ]
                    if result.deflection_vectors.size
                    else []
                ),
                rrb.Spatial3DView(
                    name=f"FK residuals ×{k:g} [m, robot base frame]",
                    origin="world",
                    contents=[
                        "+ $origin/m/magnified/**",
                        "+ $origin/m/joints/**",
                        "+ $origin/m/robot/**",
                    ],
                    eye_controls=eye,
                ),
                active_tab=1 if cameras and not found else None,  # the first camera's
            ),
            rrb.Vertical(
                rrb.TextDocumentView(name="DH parameters", origin="report/dh_table"),
                rrb.Tabs(
                    *[
                        plots(kind, title)
                        for kind, title in (("fk", "FK residuals"), ("fit", "Fit residuals"))
                        if any(res.kind == kind for res in found)  # no encoders: no FK plots
                    ]
                ),
                row_shares=[1, 1],
            ),
            column_shares=[1, 1],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(
            state="collapsed", timeline=TIMELINE if cameras and not found else JOINT_TIMELINE
        ),
    )
