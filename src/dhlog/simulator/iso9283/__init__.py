"""The ISO 9283 test run by a simulated robot whose performance is known (protocol ``iso9283``).

The robot runs the test program (:mod:`dhlog.iso9283.program`): ``iso_cycles`` cycles of the pose
test, each visiting P1 → P5 → P4 → P3 → P2 (clause 7.2.1) with a dwell of ``iso_dwell`` s at each,
then ``iso_path_cycles`` cycles of the path test, each running every test path at its commanded
speed. The joints are commanded point to point (the smooth profile of
:func:`dhlog.simulator.protocols.joints_at`) and along each path by arc length at constant speed
(trapezoidal, with ramps of ``PATH_RAMP`` s). The robot is the robot off its nominal (the session's
perturbed table and model error, the same draws as a calibration session of the same seed), so the
pose accuracy is its model error at the poses; on its true forward kinematics come

* the repeatability: each visit attains its position off by a random offset (σ ``repeatability``
  per coordinate, base frame) and its orientation by a random rotation (σ
  ``orientation_repeatability`` per axis), blended in during the move into the pose;
* the drift: ``drift`` · u · k (1 − e^(−(t − t₀)/τ)), a warm-up along a fixed direction u from
  the first arrival t₀ (τ = ``drift_time``, or a third of the pose test), k such that the
  barycentre of a cycle's attained positions moves by ``drift`` from the first cycle to the last
  (from 0 to the last cycle with one cycle), going on through the paths;
* the overshoot: at each arrival, ``overshoot`` · v · e^(−ζωt) sin(ωt) / peak along the approach
  direction v, ω = 2π ``overshoot_frequency``, ζ = ``overshoot_damping``, scaled so that its
  largest distance from the final position is ``overshoot``;
* on the paths, a systematic deviation ``path_error`` · sin(π f) · n(f) (f: the fraction of the
  path's length, n: a fixed direction made normal to the path's tangent) and a random offset
  per path cycle (σ ``path_repeatability`` per coordinate, its part normal to the tangent,
  blended in on the way to the path's start and out after its end).

The tracker samples the target at its rate with its noise; the encoders read the commanded joint
trajectory; ``/joint_command`` carries each commanded joint target when it is commanded. The
truth (:func:`truth_block`) lists every visit and every path cycle without tracker noise.

The parts: :mod:`~dhlog.simulator.iso9283.plan` (the commanded trajectory),
:mod:`~dhlog.simulator.iso9283.shapes` (overshoot and drift in time),
:mod:`~dhlog.simulator.iso9283.motion` (the target's true motion),
:mod:`~dhlog.simulator.iso9283.truth` (the truth block) and
:mod:`~dhlog.simulator.iso9283.session` (the session); every public name of theirs is
importable from here.
"""

from dhlog.simulator.iso9283.motion import Motion, approach_directions, motion_at
from dhlog.simulator.iso9283.plan import (
    PATH_DWELL,
    PATH_RAMP,
    Iso9283Run,
    Segment,
    commanded_at,
    plan_run,
    program_of,
)
from dhlog.simulator.iso9283.session import simulate_iso9283
from dhlog.simulator.iso9283.shapes import drift_shape, overshoot_shape, stabilisation_truth
from dhlog.simulator.iso9283.truth import TRUTH_FORMAT, truth_block

__all__ = [
    "PATH_DWELL",
    "PATH_RAMP",
    "TRUTH_FORMAT",
    "Iso9283Run",
    "Motion",
    "Segment",
    "approach_directions",
    "commanded_at",
    "drift_shape",
    "motion_at",
    "overshoot_shape",
    "plan_run",
    "program_of",
    "simulate_iso9283",
    "stabilisation_truth",
    "truth_block",
]
