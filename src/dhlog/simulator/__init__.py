"""Simulated calibration sessions: what a tracker and the robot's encoders would have recorded.

A session moves the robot through piecewise-linear joint trajectories, by protocol
(:mod:`~dhlog.simulator.protocols`):

* ``sweeps``: for each joint, a move that drives several joints at once to that joint's locked
  pose (a transition), a dwell, the sweep (continuous at constant speed, or step-and-measure), a
  dwell.
* ``random-poses``: ``poses`` random still poses within the joint limits (every joint changes
  from one to the next), each held for a dwell; no sweep.
* ``coupled``: each joint swept alone in ``steps`` stops, except joint 2, which only moves
  together with joint 3 (q3 = −q2: the level forearm move), also in ``steps`` stops — the
  industrial session where joints 1 and 3–6 had sweeps and joint 2 never moved
  alone.

Then come the coupled moves asked for (``coupled``: joints moved together, ``q_b = ratio · q_a``,
the ratio held within the limits). ``random-poses`` and ``coupled`` are step-and-measure
protocols: the tracker records only while the robot is still.
The tracker samples the target (FK of the true robot — off its nominal, deflected by gravity and
gears, with an unmodelled smooth error of its position if asked: :mod:`~dhlog.simulator.robot` —
plus noise, gross outliers and dropouts: :mod:`~dhlog.simulator.tracker`) at its own rate; the
encoders are sampled at another rate with another clock phase and jitter. Base-plane points are
probed first. The settings and their checks: :mod:`~dhlog.simulator.config`; the session itself:
:mod:`~dhlog.simulator.session`; its ground truth as a result document:
:mod:`~dhlog.simulator.truth`. Everything is pure numpy; :mod:`dhlog.io.writer` turns a
:class:`~dhlog.simulator.session.Session` into an MCAP file.
"""
