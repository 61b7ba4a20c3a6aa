"""``dhlog import``: measurement exports (CSV, SpatialAnalyzer, Leica Tracker Pilot) to an MCAP
log that ``dhlog process`` reads with the shipped ``ros2_tracker`` pipeline.

Three sources, one reading of their header (:mod:`dhlog.io.exports`):

* ``csv``: a table of target positions and joint values, one row per sample, with a time column
  (``--time``) or without one as one stop per row (step and measure).
* ``spatialanalyzer``: a SpatialAnalyzer export of named points — a table with a header (read as
  the other two), or the ASCII point list ``name x y z`` / ``collection, group, point, x, y, z``
  — with the joint values in a joints CSV (``--joints-file``).
* ``leica``: a Tracker-Pilot-style CSV of named points with per-point U95 columns (a 3D ``U95``,
  ``U(95)``, or ``U95 X/Y/Z``), kept as each sample's covariance.

Every format reads the same columns by what the header says they are (the point name, x, y,
z, U95, a 6-DoF target's orientation, the time, the joints: :mod:`dhlog.io.exports.layout`), in
the units the header states (:mod:`dhlog.io.exports.table`), into SI points with U95 as σ
(:mod:`dhlog.io.exports.source`). The joints come from the source's own columns or from a joints
file matched by point name or by row (:mod:`dhlog.io.exports.joints`).

The log is written as rosbag2 would (profile ``ros2``, CDR): the target on ``/tracker/point``
(``geometry_msgs/msg/PointStamped``; ``PoseStamped`` with the orientation;
``PoseWithCovarianceStamped`` with the uncertainties, its pose holding the orientation when
there is one), the joints on ``/joint_states`` (``sensor_msgs/msg/JointState``, SI units), with
the conversion's provenance in an MCAP metadata record ``dhlog.import`` — whose ``orientation =
true`` makes :func:`dhlog.io.reader.read_log` read the orientation without a pipeline saying so —
and the export's point ids, when it names its points, in ``dhlog.point_ids``
(:mod:`dhlog.io.pointids`: dhlog names outliers and held-out poses by them).
Discrete points become stops: 2 s per point, the target measured in the middle, three joint
states holding the point's joint values — at the stop's start, at the measurement and at its end
one 20 Hz period before the next stop: what the segmentation sees of a step-and-measure cell's
20 Hz stream (the motion between two stops, the stillness around the measurement) in 3 messages
a stop instead of 40, so that 200 000 stops write in seconds.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.io import ros2
from dhlog.io.exports.checks import comment_length_unit, plausible_extent
from dhlog.io.exports.joints import with_joints_file
from dhlog.io.exports.options import ImportOptions, checked_options
from dhlog.io.exports.source import EPOCH_NS, Source, file_length_unit, from_table
from dhlog.io.exports.spatialanalyzer import is_table, spatialanalyzer_points
from dhlog.io.exports.table import Table, read_table, read_text
from dhlog.io.exports.targets import further_positions, further_topics, target_triples
from dhlog.io.paths import same_file
from dhlog.io.pointids import POINT_IDS_METADATA, point_ids_record
from dhlog.model.dh import JointType

#: The import's entry, as the command line takes it.
__all__ = [
    "STOP_JOINT_TIMES",
    "ImportOptions",
    "Imported",
    "import_source",
    "same_file",
    "write_imported",
]

#: Length units as a note names them.
UNIT_WORDS = {"um": "micrometres", "in": "inches"}
#: A stop's length and its encoder rate (s, Hz), the target measured in its middle.
STOP_SECONDS, STOP_RATE = 2.0, 20.0
#: When in a stop its joint states are written (s): its start, the measurement, its end.
STOP_JOINT_TIMES = (0.0, STOP_SECONDS / 2, STOP_SECONDS - 1.0 / STOP_RATE)


@dataclass
class Imported:
    """A converted source in SI units: target stamps and positions (with each sample's 3×3
    covariance columns ``cxx, cxy, cxz, cyy, cyz, czz`` in m² when known, and the target frame's
    orientation as unit quaternions ``x, y, z, w`` when measured), the joint stream, and the
    provenance written into the log; ``notes`` say what was done to the values."""

    point_t_ns: NDArray[np.int64]
    xyz: NDArray[np.float64]
    covariance: NDArray[np.float64] | None
    joint_names: list[str]
    joint_t_ns: NDArray[np.int64]
    joint_q: NDArray[np.float64]
    stepped: bool
    provenance: dict[str, str]
    warnings: list[str] = field(default_factory=list)
    orientation: NDArray[np.float64] | None = None
    notes: list[str] = field(default_factory=list)
    #: further targets' positions (k, m, 3), m, at the point stamps (``--targets``)
    further: NDArray[np.float64] | None = None
    #: the export's point ids (its point-name column), one per target sample, or None
    point_ids: list[str] | None = None


def import_source(source: str | Path, opts: ImportOptions) -> Imported:
    """Read ``source`` (and ``opts.joints_file``) as ``opts.format`` into SI samples."""
    path = Path(source)
    checked_options(opts)
    if opts.format == "spatialanalyzer" and not is_table(path, opts):
        if opts.targets:
            raise InputError(
                f"{path}: a SpatialAnalyzer point list holds one target per point; --targets "
                "is for a table whose rows hold several targets' x, y, z columns."
            )
        if opts.joints_file is None:
            raise InputError(
                f"{path}: a SpatialAnalyzer point list holds no joint values; give them with "
                "--joints-file (matched by point name, or by row)."
            )
        text = read_text(path)
        comments = [
            (i + 1, line.strip())
            for i, line in enumerate(text.splitlines())
            if line.lstrip().startswith(("#", "//"))
        ]
        unit, where = file_length_unit(str(path), opts, comment_length_unit(str(path), comments))
        names, xyz, lines, read = spatialanalyzer_points(path, unit, where)
        src = Source(str(path), lines, names, xyz, length_read=read)
    elif opts.targets:
        src = _with_targets(read_table(path), opts)
    else:
        src = from_table(read_table(path), opts)
    if opts.joints_file is not None:
        src = with_joints_file(src, opts)
    assert src.q is not None
    types = [JointType.parse(t) for t in opts.joint_types] or None
    src.unit_slips(types)
    if src.length_read is not None:
        unit, where = src.length_read
        revolute = [
            j
            for j in range(src.q.shape[1])
            if types is None or j >= len(types) or types[j] is JointType.REVOLUTE
        ]
        plausible_extent(src.path, src.xyz, src.q, revolute, unit, where)
        if unit in ("in", "um"):
            src.notes.append(
                f"{src.path}: the positions were read in {UNIT_WORDS.get(unit, unit)} "
                f"({where}{' states it' if where.startswith('line') else ''}) and converted "
                "to metres."
            )
    xyz, q = src.xyz, src.q
    if src.t_ns is not None:
        point_t, joint_t, joint_q, stepped = src.t_ns, src.t_ns, q, False
    else:
        m = len(xyz)
        start = EPOCH_NS + np.round(np.arange(m) * STOP_SECONDS * 1e9).astype(np.int64)
        point_t = start + int(STOP_SECONDS * 1e9 / 2)
        per_stop = len(STOP_JOINT_TIMES)
        offsets = np.round(np.array(STOP_JOINT_TIMES) * 1e9).astype(np.int64)
        joint_t = (start[:, None] + offsets[None, :]).reshape(-1)
        joint_q = np.repeat(q, per_stop, axis=0)
        stepped = True
    provenance = {
        "source": str(path.resolve()),
        "source_sha256": _sha256(path),
        "format": opts.format,
        "options": json.dumps(
            {k: (str(v) if isinstance(v, Path) else v) for k, v in opts.__dict__.items()}
        ),
        "samples": str(len(xyz)),
        "timing": "step and measure: one stop per point, 2 s apart"
        if stepped
        else "from the source",
        **src.provenance,
    }
    if src.further is not None:
        provenance["targets"] = str(1 + len(src.further))
        provenance["further_target_topics"] = ",".join(further_topics(len(src.further)))
    if opts.joints_file is not None:
        provenance["joints_file"] = str(Path(opts.joints_file).resolve())
        provenance["joints_file_sha256"] = _sha256(Path(opts.joints_file))
    return Imported(
        np.asarray(point_t, dtype=np.int64),
        np.asarray(xyz, dtype=np.float64),
        src.cov,
        list(src.joint_names),
        np.asarray(joint_t, dtype=np.int64),
        np.asarray(joint_q, dtype=np.float64),
        stepped,
        provenance,
        list(src.warnings),
        src.quat,
        list(src.notes),
        None if src.further is None else np.asarray(src.further, dtype=np.float64),
        None if src.names is None else list(src.names),
    )


def _with_targets(table: Table, opts: ImportOptions) -> Source:
    """A table's points with several targets (``--targets``): the first prefix's triple read
    as the target (``--x/--y/--z``), the others' positions beside it."""
    if (opts.x, opts.y, opts.z) != ("x", "y", "z"):
        raise InputError(
            f"{table.path}: --targets names the targets' columns; leave --x, --y, --z out."
        )
    triples = target_triples(table, opts.targets)
    (x, y, z), further = triples[0], triples[1:]
    src = from_table(table, replace(opts, x=x, y=y, z=z))
    if further:
        src.further = further_positions(table, further, opts)
        if src.cov is not None:
            src.notes.append(
                f"{table.path}: the uncertainty columns are the first target's; the further "
                "targets carry none (the noise model applies to them)."
            )
    shown = "; ".join(", ".join(t) for t in triples)
    src.notes.append(f"{table.path}: {len(triples)} target(s) read from {shown}.")
    return src


def _sha256(path: Path) -> str:
    from dhlog.io.writer import sha256_of

    return sha256_of(path)


# ---------------------------------------------------------------------------------------------
# the log


def _point_messages(imported: Imported) -> tuple[str, list[bytes]]:
    """The target's schema and CDR payloads: PointStamped, PoseStamped with the orientation,
    or PoseWithCovarianceStamped with the uncertainties (its pose holding the orientation when
    measured, the orientation block of the covariance then zero: not in the export)."""
    t, xyz, cov, quat = imported.point_t_ns, imported.xyz, imported.covariance, imported.orientation
    if cov is None and quat is None:
        return ros2.POINT_STAMPED, ros2.encode_point_stamped(t, xyz, "tracker")
    if cov is None:
        return ros2.POSE_STAMPED, ros2.encode_pose_stamped(t, xyz, "tracker", quat)
    if quat is None:
        return ros2.POSE_WITH_COVARIANCE, ros2.encode_pose_with_covariance(t, xyz, "tracker", cov)
    full = np.zeros((len(xyz), 6, 6), dtype="<f8")
    rows, cols = [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]
    full[:, rows, cols] = cov
    full[:, cols, rows] = cov
    poses = ros2.encode_pose_stamped(t, xyz, "tracker", quat)
    return ros2.POSE_WITH_COVARIANCE, [p + c.tobytes() for p, c in zip(poses, full, strict=True)]


def _joint_payloads(
    t_ns: NDArray[np.int64], names: list[str], q: NDArray[np.float64]
) -> list[bytes]:
    """CDR payloads of JointState messages, as :func:`ros2.encode_joint_state` writes them,
    built at once: with the same names every message has the same layout, so one encoded
    message is the template whose stamp (bytes 4–12) and positions (the 8·n bytes before the
    empty velocity and effort) are written in per message (checked against the encoder on
    the first and last message; the encoder itself where they differ)."""
    m, n = q.shape
    if m == 0:
        return []
    template = ros2.encode_joint_state(t_ns[:1], names, q[:1])[0]
    size = len(template)
    rows = np.tile(np.frombuffer(template, dtype=np.uint8), (m, 1))
    sec, nsec = np.divmod(np.asarray(t_ns, dtype=np.int64), 1_000_000_000)
    rows[:, 4:8] = sec.astype("<i4").view(np.uint8).reshape(m, 4)
    rows[:, 8:12] = nsec.astype("<i4").view(np.uint8).reshape(m, 4)
    end = size - 8
    rows[:, end - 8 * n : end] = np.ascontiguousarray(q, dtype="<f8").view(np.uint8)
    data = rows.tobytes()
    out = [data[i : i + size] for i in range(0, m * size, size)]
    if out[0] != template or out[-1] != ros2.encode_joint_state(t_ns[-1:], names, q[-1:])[0]:
        return ros2.encode_joint_state(t_ns, names, q)  # pragma: no cover - layout changed
    return out


def write_imported(imported: Imported, out: str | Path) -> None:
    """Write ``imported`` as a ROS 2 MCAP log (atomically), with its provenance; the messages
    in time order (points before joint states at the same stamp, further targets after them),
    ordered in one sort."""
    from mcap.writer import CompressionType, Writer

    from dhlog._version import __version__
    from dhlog.io.writer import atomic_output

    point_schema, points = _point_messages(imported)
    joints = _joint_payloads(imported.joint_t_ns, imported.joint_names, imported.joint_q)
    further = [] if imported.further is None else list(imported.further)
    extra = [ros2.encode_point_stamped(imported.point_t_ns, xyz, "tracker") for xyz in further]
    times = np.concatenate(
        [imported.point_t_ns, imported.joint_t_ns, *(imported.point_t_ns for _ in extra)]
    ).astype(np.int64)
    sizes = [len(points), len(joints), *(len(e) for e in extra)]
    stream = np.repeat(np.arange(len(sizes)), sizes)
    order = np.lexsort((stream, times))  # stable: each stream keeps its own order
    payloads = points + joints + [p for e in extra for p in e]
    with atomic_output(out) as f:
        writer = Writer(f, compression=CompressionType.ZSTD, enable_crcs=False)
        writer.start(profile="ros2", library=f"dhlog import {__version__}")
        pid = writer.register_schema(point_schema, "ros2msg", ros2.MSGDEFS[point_schema].encode())
        jid = writer.register_schema(
            ros2.JOINT_STATE, "ros2msg", ros2.MSGDEFS[ros2.JOINT_STATE].encode()
        )
        channels = [
            writer.register_channel("/tracker/point", "cdr", pid),
            writer.register_channel("/joint_states", "cdr", jid),
        ]
        if extra:  # further targets: PointStamped at the point stamps
            fid = writer.register_schema(
                ros2.POINT_STAMPED, "ros2msg", ros2.MSGDEFS[ros2.POINT_STAMPED].encode()
            )
            channels += [
                writer.register_channel(topic, "cdr", fid) for topic in further_topics(len(extra))
            ]
        add = writer.add_message
        ordered = zip(order.tolist(), times[order].tolist(), stream[order].tolist(), strict=True)
        for i, t, s in ordered:
            add(channels[s], t, payloads[i], t)
        writer.add_metadata("dhlog.import", {**imported.provenance, "dhlog": __version__})
        if imported.point_ids is not None:
            writer.add_metadata(
                POINT_IDS_METADATA, point_ids_record(imported.point_t_ns, imported.point_ids)
            )
        writer.finish()  # type: ignore[no-untyped-call]
