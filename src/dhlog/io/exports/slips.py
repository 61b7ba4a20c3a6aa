"""Unit slips an export's numbers show, caught before the log is written: radians read as
degrees (or the reverse) in the joint values or in the rotation angles of a 6-DoF probe.

Joint values (:func:`joint_unit_slip`): revolute values that all lie within ±π while read as
degrees (the session would turn no joint by more than 6.3° in all: no calibration does), some
joint moving by 0.5 or more, over 10 samples or more, look like radians; values whose median
magnitude exceeds a turn (2π) while read as radians look like degrees.

Rotation angles (:func:`orientation_unit_slip`) are judged against the joints, by a bound that
holds for any serial chain: between two poses the flange (and the probe on it) turns by at most
the sum of the revolute joints' changes, ``θ(R_a⁻¹ R_b) ≤ Σ_i |q_b,i − q_a,i|`` (a composition of
rotations turns by at most the sum of their angles; prismatic joints turn nothing). Each sample
is paired with its nearest other sample in joint space (that sum, at least :data:`MIN_TURN`;
at most :data:`MAX_SAMPLES` samples, evenly strided), and

* degrees read as radians turn the probe 57× too far: a rotation angle beyond a full turn
  (software writes them within ±180° or 0–360°), or more than half of the pairs whose bound is
  informative (``2 Σ + 1° < 150°``) breaking ``θ ≤ 2 Σ|Δq| + 1°`` (the factor 2 and the 1° leave
  room for noise and for an Euler sequence near its singularity);
* radians read as degrees turn it 57× too little: every angle within ±π (in degrees: the probe
  never turned by more than a few degrees from the tracker's axes) and the median of
  ``θ / Σ|Δq|`` over the pairs below :data:`LOW_RATIO` (a real session turns the probe by about
  half of the joints' sum; a path that keeps the tool's orientation is the legitimate case).

A slip where the unit was a default, or ``--angle-unit`` alone covering the joints and the angles
alike, is refused (the error names the option that fixes it); where the header or an option meant
for that column stated it, it is a warning.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

#: A revolute session whose joints all stay within this (in the unit read) looks like radians
#: read as degrees, when some joint moved at least :data:`MIN_SPAN` (in the unit read: a
#: calibration turns some joint by more than 0.5 rad) over at least :data:`MIN_ROWS` samples.
#: A full turn either way: UR joints run ±2π rad, and no calibration keeps every joint within
#: ±6.3° (±π missed a UR log with one wrist at −3.5 rad).
SMALL = 2.0 * math.pi
MIN_SPAN = 0.5
MIN_ROWS = 10
#: Pairs of samples whose joints turned less than this (rad, summed) are not judged.
MIN_TURN = math.radians(1.0)
#: The bound's slack: θ ≤ SLACK_FACTOR · Σ|Δq| + SLACK (rad).
SLACK_FACTOR, SLACK = 2.0, math.radians(1.0)
#: A pair is informative for the bound when the bound is below this (rad).
INFORMATIVE = math.radians(150.0)
#: Below this median θ / Σ|Δq| the probe barely turns while the joints do.
LOW_RATIO = 0.05
#: Samples judged at most (evenly strided): the pairs' search is quadratic.
MAX_SAMPLES = 1000
#: Pairs needed for a verdict.
MIN_PAIRS = 5


def joint_unit_slip(
    names: list[str], values: NDArray[np.float64], unit: str, option: str
) -> tuple[str, bool] | None:
    """The slip the revolute joint values ``values`` (m, r) as read (in ``unit``) show, as a
    message and whether to refuse it, or None. ``option``: where the unit came from —
    ``"the header"`` (a warning), ``"--joint-angle-unit"`` (nothing: said explicitly),
    ``"--angle-unit"`` or ``"the default"`` (refused)."""
    if values.size == 0 or values.shape[0] < MIN_ROWS or option == "--joint-angle-unit":
        return None
    refuse = option != "the header"
    said = {"the header": "as the header states", "the default": "the default"}.get(
        option, f"{option}, which covers the joints and the rotation angles alike"
    )
    shown = ", ".join(names)
    fix = "--joint-angle-unit {} (or state the unit in the header: {} [{}])"
    if unit == "deg":
        span = float(np.max(np.ptp(values, axis=0)))
        if np.all(np.abs(values) <= SMALL) and span >= MIN_SPAN:
            return (
                f"the joint values ({shown}) all lie within ±{SMALL:.4f} while read as "
                f"degrees ({said}): no calibration turns its joints so little; they look like "
                f"radians; give {fix.format('rad', names[0], 'rad')}, or --joint-angle-unit deg "
                "if they are degrees.",
                refuse,
            )
    elif unit == "rad":
        median = float(np.median(np.abs(values)))
        if median > 2 * math.pi:
            return (
                f"the joint values ({shown}) read as radians ({said}) lie beyond a "
                f"full turn (median |q| {median:.4g} rad): they look like degrees; give "
                f"{fix.format('deg', names[0], 'deg')}, or --joint-angle-unit rad if they are "
                "radians.",
                refuse,
            )
    return None


def _pairs(
    q: NDArray[np.float64],
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """Each of the (strided) samples and its nearest other sample by the summed revolute
    change ``Σ|Δq|`` of at least :data:`MIN_TURN`: indices a, b and that sum."""
    m = q.shape[0]
    pick = np.unique(np.linspace(0, m - 1, min(m, MAX_SAMPLES)).astype(np.intp))
    sub = q[pick]
    dist = np.zeros((pick.size, pick.size))
    for j in range(sub.shape[1]):
        dist += np.abs(sub[:, j, None] - sub[None, :, j])
    dist[dist < MIN_TURN] = np.inf
    nearest = np.argmin(dist, axis=1)
    s = dist[np.arange(pick.size), nearest]
    ok = np.isfinite(s)
    return pick[ok], pick[nearest[ok]], s[ok]


def _turns(
    quat: NDArray[np.float64], a: NDArray[np.intp], b: NDArray[np.intp]
) -> NDArray[np.float64]:
    """The angle (rad) between the orientations (unit quaternions x, y, z, w) at ``a``, ``b``."""
    dot = np.abs(np.sum(quat[a] * quat[b], axis=1))
    return np.asarray(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)), dtype=np.float64)


def orientation_unit_slip(
    columns: str,
    angles: NDArray[np.float64],
    unit: str,
    option: str,
    quat: NDArray[np.float64],
    q_revolute: NDArray[np.float64],
) -> tuple[str, bool] | None:
    """The slip the rotation angles ``angles`` (m, 3, as written, in ``unit``; ``quat`` the
    orientations read from them) show against the revolute joint values ``q_revolute`` (m, r,
    rad), as a message and whether to refuse it, or None (see the module docstring).
    ``option``: where the unit came from — ``"the header"`` or ``"--angle-unit"`` given for the
    orientation alone (a warning), ``"--angle-unit"`` covering the joints too or ``"the
    default"`` (refused)."""
    if unit not in ("deg", "rad") or q_revolute.shape[1] == 0:
        return None
    refuse = option in ("the default", "--angle-unit (shared)")
    said = {
        "the header": "as the header states",
        "the default": "the default",
        "--angle-unit (shared)": "--angle-unit, which covers the joints too",
    }.get(option, option)
    fix = (
        "give the rotation angles' unit with --angle-unit {} (and the joints' with "
        "--joint-angle-unit), or state it in the header ({} [{}])"
    )
    first = columns.split(",")[0].strip()
    a, b, s = _pairs(q_revolute)
    theta = _turns(quat, a, b)
    if unit == "rad":
        largest = float(np.max(np.abs(angles)))
        informative = SLACK_FACTOR * s + SLACK < INFORMATIVE
        broken = theta[informative] > SLACK_FACTOR * s[informative] + SLACK
        many = informative.sum() >= MIN_PAIRS and broken.mean() > 0.5
        if largest > 2 * math.pi or many:
            why = (
                f"reach {largest:.4g} rad, beyond a full turn"
                if largest > 2 * math.pi
                else f"turn the probe by more than twice what the joints turn between "
                f"neighbouring poses at {int(broken.sum())} of {int(informative.sum())} pairs "
                "(no arm can)"
            )
            return (
                f"the rotation angles {columns} read as radians ({said}) {why}: they "
                f"look like degrees; {fix.format('deg', first, 'deg')}.",
                refuse,
            )
    else:
        if s.size < MIN_PAIRS or not np.all(np.abs(angles) <= SMALL):
            return None
        ratio = float(np.median(theta / s))
        if ratio < LOW_RATIO:
            return (
                f"the rotation angles {columns} all lie within ±{SMALL:.4f} read as "
                f"degrees ({said}), and turn the probe by {ratio:.3f} of what the joints turn "
                f"between neighbouring poses (median over {s.size} pairs; a session turns it "
                f"by about half): they look like radians; {fix.format('rad', first, 'rad')}.",
                refuse,
            )
    return None
