"""The certificate's acceptance-test section: a ``<stem>.iso9283.json`` written by
``dhlog iso9283`` read untrusted (:func:`load_iso9283`: size, UTF-8, JSON, then every field the
section shows through the shared :class:`~dhlog.result.fields.FieldReader`, a fault one
:class:`~dhlog.present.certificate.read.ResultFileError` naming the file and the field) into
what the page shows (:class:`Iso9283Shown`). SI units (m, s), as the file has them; the page
shows mm and s (:mod:`.iso9283_section`)."""

from __future__ import annotations

import hashlib
import json
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.present.certificate.read import ResultFileError
from dhlog.result.fields import WORDING_MUST, FieldReader

#: The report file's format (:data:`dhlog.iso9283.report.FORMAT`).
ISO9283_FORMAT = "dhlog.iso9283/1"
#: Largest report file read (one of a 30-cycle test is a few kB).
MAX_ISO9283_BYTES = 16 << 20
#: What to do about a damaged report.
ISO9283_REMEDY = (
    "the file is damaged or not a dhlog ISO 9283 report: write it again with dhlog iso9283"
)
#: Where P2 … P5 lie on the measuring plane's diagonals (clause 6.3): 10 % of the diagonal from
#: a corner, so a corner is P1 + (P − P1) / 0.8.
CORNER_FROM_POSE = 1.0 / 0.8
#: How far (relative to the edge) the corners found from the poses may be from a cube's corners.
CUBE_TOLERANCE = 1e-3


@dataclass(frozen=True)
class IsoPose:
    """One pose's figures (m, s; None: not computed). ``attained``: the attained positions
    (n, 3) when the file carries them (optional ``attained`` field), else None."""

    name: str
    visits: int
    barycentre: list[float] | None
    commanded: list[float] | None
    AP_before: float | None
    AP_after: float | None
    RP: float | None
    AP_before_sigma: float | None  # the barycentre's sampling uncertainty (optional field)
    AP_after_sigma: float | None
    stabilisation_time: float | None
    stabilisation_time_max: float | None
    overshoot: float | None
    overshoot_max: float | None
    vAP: float | None
    attained: FloatArray | None


@dataclass(frozen=True)
class IsoPath:
    """One test path's AT (before, after) and RT (m) over ``cycles`` passes at ``points``
    commanded points."""

    name: str
    cycles: int
    points: int
    AT: float
    AT_after: float | None
    RT: float


@dataclass(frozen=True)
class IsoDistance:
    """Distance accuracy and repeatability between ``poses`` (clause 7.3), m."""

    poses: tuple[str, str]
    cycles: int
    D_mean: float
    D_commanded: float | None
    AD: float | None
    AD_after: float | None
    RD: float | None


@dataclass(frozen=True)
class IsoDrift:
    """Drift at ``pose`` (clause 7.6) between the first and last ``group`` cycles ``hours``
    apart: dAP, dRP, the barycentre's shift (m) and its rate (m/h)."""

    pose: str
    group: int
    hours: float | None  # None: not known (stops whose stamps are no times)
    dAP: float | None
    dRP: float | None
    shift: float
    rate_per_hour: float | None


@dataclass(frozen=True)
class Cube:
    """The test cube found from the commanded P1 … P5 (clause 6.3): its centre (3,) and edge
    (m) in the base frame, and the measuring plane's corners (4, 3) in the order of the poses
    near them (P2, P3, P4, P5: a closed quadrilateral)."""

    centre: list[float]
    edge: float
    plane: list[list[float]]

    def edges(self) -> FloatArray:
        """The cube's 12 edges as (12, 2, 3) segments."""
        c, h = np.asarray(self.centre), self.edge / 2
        out = []
        for axis in range(3):
            u, v = [k for k in range(3) if k != axis]
            for su in (-1.0, 1.0):
                for sv in (-1.0, 1.0):
                    a = c.copy()
                    a[u] += su * h
                    a[v] += sv * h
                    b = a.copy()
                    a[axis] -= h
                    b[axis] += h
                    out.append([a, b])
        return np.asarray(out, dtype=np.float64)


@dataclass(frozen=True)
class Iso9283Shown:
    """What the certificate shows of a ``<stem>.iso9283.json``, every field checked."""

    path: Path
    sha256: str
    modified: datetime
    version: str
    logs: list[str]
    nominal: str | None
    result: str | None
    frame: str
    registration: str
    commanded_from: str
    after: str | None
    rate_hz: float
    visits: int
    cycles: int
    poses: list[IsoPose]
    distance: IsoDistance | None
    drift: IsoDrift | None
    paths: list[IsoPath]
    notes: list[str]
    cube: Cube | None


def _length(f: FieldReader, holder: dict[str, Any], key: str, at: str) -> float | None:
    """``holder[key]``: a length (m) or null; a missing key is refused."""
    v = f.get(holder, key, at, null=True)
    return None if v is None else f.number(v, f"{at}.{key}", "length")


def _size(f: FieldReader, holder: dict[str, Any], key: str, at: str) -> float | None:
    """A length, a time or a spread that is not negative, or null."""
    v = f.get(holder, key, at, null=True)
    return None if v is None else f.number(v, f"{at}.{key}", "length", sigma=True)


def _point(f: FieldReader, holder: dict[str, Any], key: str, at: str) -> list[float] | None:
    v = f.get(holder, key, at, null=True)
    if v is None:
        return None
    got = f.vector(v, f"{at}.{key}", 3)
    return [f.number(x, f"{at}.{key}[{k}]", "length") for k, x in enumerate(got)]


def _accuracy(
    f: FieldReader, pose: dict[str, Any], key: str, at: str
) -> tuple[float | None, float | None]:
    """``pose[key]``'s AP and its optional ``AP_sigma`` (None, None when null)."""
    where = f"{at}.{key}"
    v = f.get(pose, key, at, null=True)
    if v is None:
        return None, None
    block = f.obj(v, where)
    for comp in ("AP_x", "AP_y", "AP_z"):
        f.number(f.get(block, comp, where), f"{where}.{comp}", "length")
    AP = f.number(f.get(block, "AP", where), f"{where}.AP", "length", sigma=True)
    s = f.get(block, "AP_sigma", where, required=False, null=True)
    return AP, None if s is None else f.number(s, f"{where}.AP_sigma", "length", sigma=True)


def _pose(f: FieldReader, item: Any, at: str) -> IsoPose:
    p = f.obj(item, at)
    name = f.text(f.get(p, "pose", at), f"{at}.pose")
    attained = None
    raw = f.get(p, "attained", at, required=False, null=True)
    if raw is not None:
        rows = f.array(raw, f"{at}.attained", most=100_000)
        attained = np.array(
            [
                [
                    f.number(x, f"{at}.attained[{i}][{k}]", "length")
                    for k, x in enumerate(f.vector(r, f"{at}.attained[{i}]", 3))
                ]
                for i, r in enumerate(rows)
            ],
            dtype=np.float64,
        ).reshape(-1, 3)
    before, before_sigma = _accuracy(f, p, "before", at)
    after, after_sigma = _accuracy(f, p, "after", at)
    return IsoPose(
        name,
        f.integer(f.get(p, "visits", at), f"{at}.visits", minimum=1),
        _point(f, p, "barycentre", at),
        _point(f, p, "commanded", at),
        before,
        after,
        _size(f, p, "RP", at),
        before_sigma,
        after_sigma,
        _size(f, p, "stabilisation_time", at),
        _size(f, p, "stabilisation_time_max", at),
        _size(f, p, "overshoot", at),
        _size(f, p, "overshoot_max", at),
        _size(f, p, "vAP", at),
        attained,
    )


def _path(f: FieldReader, item: Any, at: str) -> IsoPath:
    p = f.obj(item, at)
    AT = _size(f, p, "AT", at)
    RT = _size(f, p, "RT", at)
    if AT is None:
        f.fail(f"{at}.AT", "is null")
    if RT is None:
        f.fail(f"{at}.RT", "is null")
    return IsoPath(
        f.text(f.get(p, "path", at), f"{at}.path"),
        f.integer(f.get(p, "cycles", at), f"{at}.cycles", minimum=1),
        f.integer(f.get(p, "points", at), f"{at}.points", minimum=1),
        AT,
        _size(f, p, "AT_after", at),
        RT,
    )


def _distance(f: FieldReader, block: dict[str, Any]) -> IsoDistance | None:
    at = "iso9283.distance"
    v = f.get(block, "distance", "iso9283", null=True)
    if v is None:
        return None
    d = f.obj(v, at)
    poses = f.texts(f.get(d, "poses", at), f"{at}.poses")
    if len(poses) != 2:
        f.fail(f"{at}.poses", f"must name 2 poses, not {len(poses)}")
    D_mean = _size(f, d, "D_mean", at)
    if D_mean is None:
        f.fail(f"{at}.D_mean", "is null")
    return IsoDistance(
        (poses[0], poses[1]),
        f.integer(f.get(d, "cycles", at), f"{at}.cycles", minimum=1),
        D_mean,
        _size(f, d, "D_commanded", at),
        _length(f, d, "AD", at),
        _length(f, d, "AD_after", at),
        _size(f, d, "RD", at),
    )


def _drift(f: FieldReader, block: dict[str, Any]) -> IsoDrift | None:
    at = "iso9283.drift"
    v = f.get(block, "drift", "iso9283", null=True)
    if v is None:
        return None
    d = f.obj(v, at)
    shift = _size(f, d, "shift", at)
    rate = _size(f, d, "rate_per_hour", at)
    given = f.get(d, "hours", at, null=True)  # null: stops whose stamps are no times
    hours = None if given is None else f.number(given, f"{at}.hours", sigma=True)
    if shift is None:
        f.fail(f"{at}.shift", "is null")
    if rate is None and hours is not None:
        f.fail(f"{at}.rate_per_hour", "is null")
    return IsoDrift(
        f.text(f.get(d, "pose", at), f"{at}.pose"),
        f.integer(f.get(d, "group", at), f"{at}.group", minimum=1),
        hours,
        _size(f, d, "dAP", at),
        _size(f, d, "dRP", at),
        shift,
        rate,
    )


def cube_from_poses(poses: list[IsoPose]) -> Cube | None:
    """The test cube from the commanded P1 … P5 (clause 6.3: P1 the centre, P2 … P5 at 10 % of
    the measuring plane's diagonals from its corners; that plane holds two opposite edges, so
    the corners' bounding box is the cube). None when a pose or its commanded position is
    missing or the corners do not make a cube (the poses not the standard's)."""
    return cube_of({p.name: p.commanded for p in poses})


def cube_of(by: Mapping[str, Sequence[float] | FloatArray | None]) -> Cube | None:
    """The cube of the commanded positions of P1 … P5 by name (:func:`cube_from_poses`)."""
    if any(by.get(n) is None for n in ("P1", "P2", "P3", "P4", "P5")):
        return None
    P1 = np.asarray(by["P1"], dtype=np.float64)
    corners = np.array(
        [
            P1 + (np.asarray(by[n], dtype=np.float64) - P1) * CORNER_FROM_POSE
            for n in ("P2", "P3", "P4", "P5")
        ]
    )
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    size = hi - lo
    edge = float(size.mean())
    if edge <= 0 or np.max(np.abs(size - edge)) > CUBE_TOLERANCE * edge:
        return None
    # every corner on a corner of the box, P1 its centre
    at_corner = np.minimum(np.abs(corners - lo), np.abs(corners - hi))
    if (
        np.max(at_corner) > CUBE_TOLERANCE * edge
        or np.max(np.abs((lo + hi) / 2 - P1)) > CUBE_TOLERANCE * edge
    ):
        return None
    return Cube([float(v) for v in (lo + hi) / 2], edge, corners.tolist())


def read_iso9283(document: Any, path: Path, sha256: str, modified: datetime) -> Iso9283Shown:
    """The report ``document`` (parsed JSON, untrusted) checked field by field."""
    f = FieldReader(
        str(path),
        error=lambda p, field, problem: ResultFileError(p, field, problem, ISO9283_REMEDY),
        wording=WORDING_MUST,
    )
    doc = f.obj(document, "the file")
    fmt = f.text(f.get(doc, "format"), "format")
    if fmt != ISO9283_FORMAT:
        f.fail("format", f"must be {ISO9283_FORMAT}, not {fmt[:40]!r}")
    version = f.text(f.get(doc, "dhlog_version"), "dhlog_version")
    source = f.get_obj(doc, "source")
    assert source is not None
    logs = f.texts(f.get(source, "logs", "source"), "source.logs")
    nominal = f.get_text(source, "nominal", "source", required=False)
    result = f.get_text(source, "result", "source", required=False)
    block = f.get_obj(doc, "iso9283")
    assert block is not None
    at = "iso9283"
    frame = f.text(f.get(block, "frame", at), f"{at}.frame", ("base", "measurement"))
    after = f.get(block, "after", at, null=True)
    poses = [
        _pose(f, item, f"{at}.poses[{k}]")
        for k, item in enumerate(f.array(f.get(block, "poses", at), f"{at}.poses", most=1000))
    ]
    paths = [
        _path(f, item, f"{at}.paths[{k}]")
        for k, item in enumerate(f.array(f.get(block, "paths", at), f"{at}.paths", most=1000))
    ]
    shown = Iso9283Shown(
        path,
        sha256,
        modified,
        version,
        logs,
        nominal,
        result,
        frame,
        f.text(f.get(block, "registration", at), f"{at}.registration"),
        f.text(f.get(block, "commanded_from", at), f"{at}.commanded_from"),
        None if after is None else f.text(after, f"{at}.after"),
        f.number(f.get(block, "tracker_rate_hz", at), f"{at}.tracker_rate_hz", minimum=0),
        f.integer(f.get(block, "visits", at), f"{at}.visits", minimum=0),
        f.integer(f.get(block, "cycles", at), f"{at}.cycles", minimum=0),
        poses,
        _distance(f, block),
        _drift(f, block),
        paths,
        [*_not_determined(f, block, at), *f.texts(f.get(block, "notes", at), f"{at}.notes")],
        None,
    )
    if frame != "base":
        return shown
    from dataclasses import replace

    return replace(shown, cube=cube_from_poses(poses))


def _not_determined(f: FieldReader, block: dict[str, Any], at: str) -> list[str]:
    """The report's ``not_determined`` lines (a test from stops: stabilisation, paths) as
    notes, each marked so; none where the report has none."""
    given = block.get("not_determined")
    if given is None:
        return []
    return [f"Not determined: {t}." for t in f.texts(given, f"{at}.not_determined")]


def load_iso9283(path: Path) -> Iso9283Shown:
    """``path`` read (a regular file of at most 16 MiB, UTF-8 JSON), hashed and checked."""
    name = str(path)
    try:
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode):
            raise InputError(
                f"{name}: is not a regular file; give the <stem>.iso9283.json dhlog iso9283 wrote."
            )
        with open(path, "rb") as fh:
            data = fh.read(MAX_ISO9283_BYTES + 1)
        modified = datetime.fromtimestamp(path.stat().st_mtime, tz=UTC)
    except OSError as exc:
        raise InputError(
            f"{name}: cannot be read ({exc.strerror or exc}); give the <stem>.iso9283.json "
            "dhlog iso9283 wrote."
        ) from None
    if len(data) > MAX_ISO9283_BYTES:
        raise ResultFileError(
            name, "the file", f"is larger than {MAX_ISO9283_BYTES >> 20} MiB", ISO9283_REMEDY
        )
    try:
        document = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ResultFileError(
            name, "the file", f"is not UTF-8 text (byte {exc.start})", ISO9283_REMEDY
        ) from None
    except json.JSONDecodeError as exc:
        raise ResultFileError(
            name, "the file", f"is not valid JSON ({exc.msg} at line {exc.lineno})", ISO9283_REMEDY
        ) from None
    except (ValueError, RecursionError) as exc:
        raise ResultFileError(
            name, "the file", f"is not valid JSON ({type(exc).__name__})", ISO9283_REMEDY
        ) from None
    return read_iso9283(document, path, hashlib.sha256(data).hexdigest(), modified)
