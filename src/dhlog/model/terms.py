"""Joint-value terms beyond the geometric model: gravity compliance and transmission harmonics.

Each term moves one joint by a coefficient times a known function of the pose,
``Δq_i = Σ_t θ_t b_t(q)``, added to the encoder's (scaled) move before the chain is evaluated:

* ``compliance`` (joint i, lump l): ``b = z_i · ((p_l − o_i) × ĝ)``, the lever arm (m) about
  joint i's axis (through ``o_i`` along ``z_i``) of a unit mass at the lump point ``p_l`` under
  gravity ``ĝ`` (unit, the direction it pulls). A joint's gravity torque is ``g Σ m_l b`` over
  the masses downstream of it, so with a stiffness ``1/c_i`` the joint yields
  ``Δq_i = c_i g Σ m_l b_l``: ``θ = c_i g m_l`` (rad per metre of lever arm) is what the samples
  determine of compliance and masses together (the *lumped gravity terms*). The lumps are the
  points where joint i's successors meet the axes after it (the DH frame origins: on each later
  axis, its foot on the axis before) and the target (payload and tool). The torque is taken at
  the encoders' pose (the deflection it causes is far too small to change it).
* ``compliance_masses`` (joint i), with the links' masses known (a URDF's ``<inertial>``):
  ``b = Σ m_l z_i · ((p_l − o_i) × ĝ)`` over the links downstream (kg·m), so that the
  coefficient is ``c_i g`` — the joint's compliance itself, beside a ``compliance`` term for the
  payload at the target.
* ``harmonic_sin`` / ``harmonic_cos`` (joint i): ``b = sin q_i`` / ``cos q_i`` of the encoder
  value, the first harmonic of a transmission's angle error (rad).

The same terms are evaluated on the fitted axes (:mod:`dhlog.identify.fit.prediction`) and on the DH
table (:func:`table_deflection`: the result JSON's ``nongeometric`` block, the ``fk`` command
and the simulator's truth), from points given in the frames each carries.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.geometry._checks import FloatArray

KINDS = ("compliance", "compliance_masses", "harmonic_sin", "harmonic_cos")
#: The unit of each kind's coefficient.
UNITS = {
    "compliance": "rad/m",
    "compliance_masses": "rad/(kg·m)",
    "harmonic_sin": "rad",
    "harmonic_cos": "rad",
}
#: A first joint whose axis is within this angle (rad) of gravity carries no gravity torque.
VERTICAL = np.radians(1.0)
#: Lump points closer than this (m) at the reference pose are one (a spherical wrist's centre).
SAME_POINT = 0.02


@dataclass(frozen=True)
class Term:
    """One term: its kind, the joint it moves (0-based) and, for compliance, its lump."""

    kind: str
    joint: int
    lump: int = -1

    def name(self, lumps: tuple[Lump, ...]) -> str:
        if self.kind == "compliance":
            return f"compliance_{self.joint + 1}_{lumps[self.lump].name}"
        if self.kind == "compliance_masses":
            return f"compliance_{self.joint + 1}_masses"
        return f"{self.kind}_{self.joint + 1}"


@dataclass(frozen=True, eq=False)
class Lump:
    """A point a mass is lumped at, moved by joints 1 … ``axis`` (0-based: the joints before
    axis ``axis``): a unit mass on that axis, or (``mass`` > 0) a link's known mass at its
    centre (a URDF's ``<inertial>``; ``axis`` then counts the joints that move the link), or
    with ``axis`` −1 the target (moved by every joint). ``point`` is in the frame its owner
    gives (the measurement frame at the reference pose for the fitted axes; for a table, its
    frame ``axis`` of ``fk_frames`` — the last for the target)."""

    axis: int
    point: FloatArray
    mass: float = 0.0

    @property
    def name(self) -> str:
        if self.target:
            return "target"
        return f"link{self.axis}" if self.mass > 0 else f"axis{self.axis + 1}"

    @property
    def target(self) -> bool:
        return self.axis < 0


@dataclass(frozen=True, eq=False)
class Terms:
    """The terms of a model, their coefficients (k,), the lumps and gravity (unit, in the
    owner's frame: the measurement frame, or a table's base frame)."""

    terms: tuple[Term, ...]
    lumps: tuple[Lump, ...]
    gravity: FloatArray
    coefficients: FloatArray

    @property
    def size(self) -> int:
        return len(self.terms)

    def names(self) -> list[str]:
        return [t.name(self.lumps) for t in self.terms]

    def families(self) -> list[str]:
        """The families present: ``compliance`` and/or ``harmonic``."""
        kinds = {t.kind for t in self.terms}
        out = ["compliance"] if kinds & {"compliance", "compliance_masses"} else []
        return out + (["harmonic"] if kinds & {"harmonic_sin", "harmonic_cos"} else [])

    def with_coefficients(self, coefficients: FloatArray) -> Terms:
        return replace(self, coefficients=np.asarray(coefficients, dtype=np.float64))

    def basis(
        self,
        Q: FloatArray,
        axis_points: list[FloatArray],
        axis_dirs: list[FloatArray],
        lump_points: list[FloatArray],
    ) -> FloatArray:
        """Each term's function ``b_t`` (k, m) at the encoder values ``Q`` (m, n), from each
        joint's axis point and direction (3, m) and each lump's position (3, m) at the samples
        (any one frame with ``gravity`` in it)."""
        m = Q.shape[0]
        B = np.empty((self.size, m))
        g = self.gravity
        for k, t in enumerate(self.terms):
            if t.kind == "harmonic_sin":
                B[k] = np.sin(Q[:, t.joint])
            elif t.kind == "harmonic_cos":
                B[k] = np.cos(Q[:, t.joint])
            elif t.kind == "compliance":
                B[k] = _lever(g, axis_dirs[t.joint], axis_points[t.joint], lump_points[t.lump])
            else:  # the known masses downstream of the joint
                B[k] = 0.0
                for lump, p in zip(self.lumps, lump_points, strict=True):
                    if lump.mass > 0 and lump.axis > t.joint:
                        B[k] += lump.mass * _lever(g, axis_dirs[t.joint], axis_points[t.joint], p)
        return B

    def without(self, drop: Callable[[Term], bool]) -> Terms:
        """These terms without those ``drop`` names; the lumps no term names are left out (a
        URDF's link masses stay: ``compliance_masses`` sums them all)."""
        keep = [k for k, t in enumerate(self.terms) if not drop(t)]
        terms = [self.terms[k] for k in keep]
        used = sorted(
            {t.lump for t in terms if t.lump >= 0}
            | {k for k, lump in enumerate(self.lumps) if lump.mass > 0}
        )
        terms = [replace(t, lump=used.index(t.lump)) if t.lump >= 0 else t for t in terms]
        lumps = tuple(self.lumps[k] for k in used)
        return Terms(tuple(terms), lumps, self.gravity, self.coefficients[keep])

    def deflection(self, B: FloatArray, n: int) -> FloatArray:
        """``Δq`` (n, m) from the term functions ``B`` (k, m)."""
        dq = np.zeros((n, B.shape[1]))
        for k, t in enumerate(self.terms):
            dq[t.joint] += self.coefficients[k] * B[k]
        return dq

    def document(self, std: FloatArray | None = None) -> dict[str, Any]:
        """The JSON ``nongeometric`` block's ``terms``, ``lumps`` and ``gravity``."""
        return {
            "gravity": [float(v) for v in self.gravity],
            "lumps": [
                {
                    "on": "target"
                    if lump.target
                    else (f"link {lump.axis}" if lump.mass > 0 else f"axis {lump.axis + 1}"),
                    "point": [float(v) for v in lump.point],
                    **({"mass": lump.mass} if lump.mass > 0 else {}),
                }
                for lump in self.lumps
            ],
            "terms": [
                {
                    "name": t.name(self.lumps),
                    "kind": t.kind,
                    "joint": t.joint + 1,
                    **({"lump": t.lump} if t.kind == "compliance" else {}),
                    "value": float(self.coefficients[k]),
                    "std": None if std is None else float(std[k]),
                    "unit": UNITS[t.kind],
                }
                for k, t in enumerate(self.terms)
            ],
        }


def _lever(g: FloatArray, z: FloatArray, o: FloatArray, p: FloatArray) -> FloatArray:
    """``z · ((p − o) × g)`` per sample (m): the lever arm about the axis (o, z) of a unit mass
    at ``p`` under gravity ``g``."""
    r = p - o
    # z · (r × g) = g · (z × r)
    return np.asarray(
        g[0] * (z[1] * r[2] - z[2] * r[1])
        + g[1] * (z[2] * r[0] - z[0] * r[2])
        + g[2] * (z[0] * r[1] - z[1] * r[0]),
        dtype=np.float64,
    )


def design(
    families: tuple[str, ...],
    axis_points: list[FloatArray],
    axis_dirs: list[FloatArray],
    target: FloatArray,
    revolute: list[bool],
    gravity: FloatArray,
    harmonic_joints: tuple[int, ...] | None = None,
    masses: tuple[Lump, ...] = (),
) -> Terms:
    """The terms of ``families`` (``compliance``, ``harmonic``) for a chain whose axes at the
    reference pose are ``axis_points``/``axis_dirs`` (3,) with its target, in one frame with
    ``gravity``. Compliance: every revolute joint but those along gravity that no joint before
    can tilt (the first revolute joint when it is along gravity, and each later one while every
    revolute axis up to it is), with
    a lump on each later axis (its foot on the axis before; for parallel neighbours the foot of
    the previous lump) and at the target, none on the joint's own axis (no lever about it);
    harmonics on ``harmonic_joints`` (0-based; default every revolute joint). With the links'
    ``masses`` (lumps with their mass), compliance is one term per joint for the torque of those
    masses (its coefficient ``c g``) and one for a payload at the target."""
    n = len(axis_dirs)
    g = np.asarray(gravity, dtype=np.float64)
    g = g / np.linalg.norm(g)
    lumps: list[Lump] = []
    terms: list[Term] = []
    # an axis along gravity that no joint before it can tilt carries no gravity torque at any
    # pose: the first revolute joint's (a rotary table behind linear stages too), and a later
    # one's while every revolute axis before it is along gravity as well (a SCARA's)
    along = [abs(float(d @ g)) > np.cos(VERTICAL) for d in axis_dirs]
    upright = [all(along[j] for j in range(i + 1) if revolute[j]) for i in range(n)]
    compliant = [i for i in range(n) if revolute[i] and not upright[i]]
    if "compliance" in families and masses:
        lumps = [*masses, Lump(-1, np.asarray(target, dtype=np.float64))]
        for i in compliant:
            if any(lump.axis > i for lump in masses):
                terms.append(Term("compliance_masses", i))
            terms.append(Term("compliance", i, len(lumps) - 1))
    elif "compliance" in families:
        previous = axis_points[0]
        for lx in range(1, n):
            p = _foot(axis_points[lx], axis_dirs[lx], axis_points[lx - 1], axis_dirs[lx - 1])
            if p is None:
                p = _project(axis_points[lx], axis_dirs[lx], previous)
            previous = p
            if any(np.linalg.norm(p - q.point) < SAME_POINT for q in lumps):
                continue
            lumps.append(Lump(lx, p))
        lumps.append(Lump(-1, np.asarray(target, dtype=np.float64)))
        for i in compliant:
            for k, lump in enumerate(lumps):
                on_axis = _distance(lump.point, axis_points[i], axis_dirs[i]) < SAME_POINT
                if (lump.target or lump.axis > i) and not on_axis:  # no lever about it
                    terms.append(Term("compliance", i, k))
    if "harmonic" in families:
        joints = (
            tuple(i for i in range(n) if revolute[i])
            if harmonic_joints is None
            else harmonic_joints
        )
        for i in joints:
            terms += [Term("harmonic_sin", i), Term("harmonic_cos", i)]
    # the lumps no term names (on the first axis; on a joint's own) are left out
    return Terms(tuple(terms), tuple(lumps), g, np.zeros(len(terms))).without(lambda t: False)


def _distance(x: FloatArray, point: FloatArray, direction: FloatArray) -> float:
    return float(np.linalg.norm(np.cross(x - point, direction)))


def _project(point: FloatArray, direction: FloatArray, x: FloatArray) -> FloatArray:
    return np.asarray(point + ((x - point) @ direction) * direction, dtype=np.float64)


def _foot(
    p: FloatArray, d: FloatArray, q: FloatArray, e: FloatArray, parallel: float = 0.035
) -> FloatArray | None:
    """The point on line (p, d) nearest line (q, e); None when they are within ~2° of parallel."""
    c = np.cross(d, e)
    s = float(np.linalg.norm(c))
    if s < parallel:
        return None
    # p + t d − (q + u e) ⟂ d, e
    w = p - q
    b = float(d @ e)
    denom = 1.0 - b * b
    t = (b * float(e @ w) - float(d @ w)) / denom
    return np.asarray(p + t * d, dtype=np.float64)


def to_table(terms: Terms, frames_ref: FloatArray) -> Terms:
    """``terms`` (points and gravity in the measurement frame M) in a table's frames:
    ``frames_ref`` (n+1, 4, 4) the table's frames in M at its reference pose (``fk_frames``:
    entry 0 the base, entry i the frame whose z is joint i+1's axis, entry n the last). Lumps on
    axis l go to entry l, the target to entry n; gravity to the base frame."""
    n = frames_ref.shape[0] - 1
    lumps = []
    for lump in terms.lumps:
        F = frames_ref[n if lump.target else lump.axis]
        lumps.append(Lump(lump.axis, F[:3, :3].T @ (lump.point - F[:3, 3]), lump.mass))
    return replace(terms, lumps=tuple(lumps), gravity=frames_ref[0][:3, :3].T @ terms.gravity)


def from_table(terms: Terms, frames_ref: FloatArray) -> Terms:
    """The inverse of :func:`to_table`: ``terms`` in a table's frames carried into the frame of
    ``frames_ref`` (its ``fk_frames`` at the reference pose, with the base placed there)."""
    n = frames_ref.shape[0] - 1
    lumps = []
    for lump in terms.lumps:
        F = frames_ref[n if lump.target else lump.axis]
        lumps.append(Lump(lump.axis, F[:3, :3] @ lump.point + F[:3, 3], lump.mass))
    return replace(terms, lumps=tuple(lumps), gravity=frames_ref[0][:3, :3] @ terms.gravity)


def table_deflection(table: Any, terms: Terms, Q: ArrayLike, Q_table: ArrayLike) -> FloatArray:
    """``Δq`` (m, n) of ``terms`` given in ``table``'s frames (:func:`to_table`) at the encoder
    values ``Q`` (m, n) whose table joint values are ``Q_table`` (the encoders scaled, when
    scales were fitted); add it to ``Q_table`` for the forward kinematics."""
    from dhlog.model.fk import fk_frames

    Qe = np.atleast_2d(np.asarray(Q, dtype=np.float64))
    Qt = np.atleast_2d(np.asarray(Q_table, dtype=np.float64))
    n, m = table.n, Qt.shape[0]
    out = np.empty((m, n))
    for start in range(0, m, 8192):
        sl = slice(start, min(start + 8192, m))
        F = fk_frames(table, Qt[sl])  # (c, n+1, 4, 4), in the base frame
        points = [F[:, i, :3, 3].T for i in range(n)]
        dirs = [F[:, i, :3, 2].T for i in range(n)]
        lumps = [
            (F[:, n if lump.target else lump.axis, :3, :3] @ lump.point).T
            + F[:, n if lump.target else lump.axis, :3, 3].T
            for lump in terms.lumps
        ]
        out[sl] = terms.deflection(terms.basis(Qe[sl], points, dirs, lumps), n).T
    return out


def from_document(doc: Any, n: int, where: str) -> Terms:
    """The ``nongeometric`` block of a result JSON (untrusted): one-line errors name the field."""
    from dhlog.errors import InputError

    def bad(field: str, what: str) -> InputError:
        return InputError(f"{where}: nongeometric.{field} {what}")

    if not isinstance(doc, dict):
        raise bad("", "is not an object")
    try:
        g = np.asarray(doc["gravity"], dtype=np.float64)
    except (KeyError, TypeError, ValueError) as exc:
        raise bad("gravity", "must be three numbers") from exc
    if g.shape != (3,) or not np.all(np.isfinite(g)) or np.linalg.norm(g) == 0:
        raise bad("gravity", "must be three finite numbers, not all zero")
    lumps = []
    for k, item in enumerate(doc.get("lumps") or []):
        try:
            on, point = item["on"], np.asarray(item["point"], dtype=np.float64)
        except (KeyError, TypeError, ValueError) as exc:
            raise bad(f"lumps[{k}]", "needs 'on' and a 'point' of three numbers") from exc
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise bad(f"lumps[{k}].point", "must be three finite numbers")
        if on == "target":
            lumps.append(Lump(-1, point))
            continue
        if str(on).startswith("link "):
            try:
                link, mass = int(str(on).removeprefix("link ")), float(item["mass"])
            except (KeyError, TypeError, ValueError) as exc:
                raise bad(f"lumps[{k}]", "'link N' needs a whole N and a numeric 'mass'") from exc
            if not 1 <= link <= n or not np.isfinite(mass) or mass <= 0:
                raise bad(f"lumps[{k}]", f"names link {link} of mass {mass} (links 1-{n}, kg > 0)")
            lumps.append(Lump(link, point, mass))
            continue
        try:
            axis = int(str(on).removeprefix("axis ")) - 1
        except ValueError as exc:
            raise bad(f"lumps[{k}].on", "must be 'target', 'axis N' or 'link N'") from exc
        if not 1 <= axis < n:
            raise bad(f"lumps[{k}].on", f"names axis {axis + 1}; the table has {n} joints")
        lumps.append(Lump(axis, point))
    terms, values = [], []
    for k, item in enumerate(doc.get("terms") or []):
        try:
            kind, joint, value = item["kind"], int(item["joint"]) - 1, float(item["value"])
        except (KeyError, TypeError, ValueError) as exc:
            raise bad(f"terms[{k}]", "needs 'kind', 'joint' and a numeric 'value'") from exc
        if kind not in KINDS or not 0 <= joint < n or not np.isfinite(value):
            raise bad(f"terms[{k}]", f"has kind {kind!r}, joint {joint + 1}, value {value}")
        lump = -1
        if kind == "compliance":
            try:
                lump = int(item["lump"])
            except (KeyError, TypeError, ValueError) as exc:
                raise bad(f"terms[{k}].lump", "must name a lump by its index") from exc
            if not 0 <= lump < len(lumps):
                raise bad(f"terms[{k}].lump", f"is {lump}; there are {len(lumps)} lumps")
        terms.append(Term(kind, joint, lump))
        values.append(value)
    return Terms(tuple(terms), tuple(lumps), g / np.linalg.norm(g), np.array(values))
