"""What each column of an export holds, read from its header: the point name, x, y, z (or a
prefixed triple such as ``measurement_x … measurement_z`` when the header has no plain x), U95 or
standard uncertainties of any prefix, per axis or one 3-D figure (``U95 X``, ``leica_uncX_m``,
``std x``, ``sigma_x``, ``measurement_std_x``, ``leica_unc_m``), the orientation of a 6-DoF
target (quaternion ``Q0 Q1 Q2 Q3`` scalar first as Leica writes it, ``Qw Qx Qy Qz`` in any
order, or rotation angles ``Rx Ry Rz`` in the ``--euler`` sequence, with the position's prefix
or without), the time, and the joints (``q1…``, ``j1…``, ``A1…``, ``joint_1…``, ``axis1…``, a
Universal Robots arm's ``shoulder_pan_joint … wrist_3_joint``; or ``--joint-columns``). A column
the header names (orientation, U95, σ, time) is never taken as a joint; a column two options
name is refused.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from dhlog.io.exports.options import ImportOptions
from dhlog.io.exports.table import ConversionError, Table, parse_header

#: Orientation columns by their (normalised) header: quaternions, scalar first, and rotation
#: angles (X, Y, Z).
QUATERNION_HEADERS = (("qw", "qx", "qy", "qz"), ("q0", "q1", "q2", "q3"))
ANGLE_HEADERS = (
    ("rx", "ry", "rz"),
    ("rotx", "roty", "rotz"),
    ("rotationx", "rotationy", "rotationz"),
)
#: Point-name columns by their (normalised) header, in order of preference.
NAME_HEADERS = ("pointname", "name", "pointid", "point", "id", "ptid", "target", "label")
#: A joint column by its (normalised) header, with the joint's number.
JOINT_HEADER = re.compile(r"^(?:q|j|a|joint|axis)(\d{1,3})$")
#: Joint columns by name, in chain order (normalised headers): a Universal Robots arm's as ROS
#: names them, with and without ``_joint``.
NAMED_JOINTS = (
    (
        "shoulderpanjoint",
        "shoulderliftjoint",
        "elbowjoint",
        "wrist1joint",
        "wrist2joint",
        "wrist3joint",
    ),
    ("shoulderpan", "shoulderlift", "elbow", "wrist1", "wrist2", "wrist3"),
)
#: An uncertainty column by its (normalised) header: any prefix (``leica_``, the position's
#: ``measurement_``), the word — a U95 (``u95``, ``U(95)``), a standard uncertainty (``unc``,
#: ``uncert``, ``uncertainty``) or a standard deviation (``std``, ``stddev``, ``sigma``, ``sd``) —
#: and the axis before or after it (``uncX``, ``x_std``; an orientation's ``rx``), or none (one
#: 3-D figure).
_UNC_WORD = r"(?P<word>u95|uncertainty|uncert|unc|stddev|std|sigma)"
UNCERTAINTY_HEADERS = (
    re.compile(rf"^(?P<pre>[a-z]*?){_UNC_WORD}(?P<axis>[xyz])?$"),
    re.compile(rf"^(?P<pre>[a-z]*?)(?P<axis>[xyz]){_UNC_WORD}$"),
)
#: An orientation's uncertainty: ``std_rx``, ``measurement_std_rotx``.
_ROTATION_UNCERTAINTY = re.compile(
    rf"^(?P<pre>[a-z]*?){_UNC_WORD}(?:r|rot|rotation)(?P<axis>[xyz])$"
)
#: Words that mark a column as an uncertainty (never a position, joint or orientation).
UNCERTAINTY_WORDS = ("std", "sigma", "u95", "stddev", "uncert", "unc", "dev", "err", "rms")
#: What turns a position's prefix into an orientation's (``measurement`` → ``measurementr``).
_ROTATION_TAILS = ("r", "rot", "rotation", "q", "angle")


@dataclass
class Layout:
    """The columns of a table by what they hold (indices into its header)."""

    xyz: list[int]
    name: list[int]
    time: int | None
    #: the position's uncertainty columns read: ("axes", [x, y, z]) a U95 per axis, ("sphere",
    #: [k]) a 3-D U95, ("std", [x, y, z]) σ per axis, ("std3d", [k]) a 3-D standard uncertainty
    u95: tuple[str, list[int]] | None
    orientation: tuple[str, list[int]] | None  # ("quaternion", [w, x, y, z]) or ("angles", …)
    joints: list[int]
    recognised: dict[int, str]  # every column the header says is not a joint, and what it is
    notes: list[str] = field(default_factory=list)
    #: uncertainty columns (σ, U95) that are not read: the orientation's, or beside others
    unread: list[int] = field(default_factory=list)


def claim(table: Table, claims: dict[int, str], k: int, option: str) -> None:
    """Column ``k`` taken by ``option``; a column that two options (or one option twice) name
    is refused."""
    if k in claims:
        other = claims[k]
        if other == option:
            raise ConversionError(
                table.path,
                f"{option} names the column '{table.header[k]}' twice; name each column once.",
            )
        raise ConversionError(
            table.path,
            f"{other} and {option} both name the column '{table.header[k]}'; give each its own "
            "column.",
        )
    claims[k] = option


def joints_by_number(table: Table, candidates: list[int], notes: list[str]) -> list[int]:
    """The joint columns the header names (``j2, j1, j3``), in the order of their numbers
    (``j1, j2, j3``, said in a note when it is not the header's); two columns for one joint, or
    a joint left out between others, are refused."""
    by_number: dict[int, int] = {}
    for k in candidates:
        m = JOINT_HEADER.match(table.heads[k].key)
        assert m is not None
        number = int(m[1])
        if number in by_number:
            raise ConversionError(
                table.path,
                f"has two columns for joint {number}, '{table.header[by_number[number]]}' and "
                f"'{table.header[k]}'; name the joint columns in chain order with "
                "--joint-columns.",
            )
        by_number[number] = k
    if not by_number:
        return []
    numbers = sorted(by_number)
    missing = [n for n in range(numbers[0], numbers[-1] + 1) if n not in by_number]
    if missing:
        raise ConversionError(
            table.path,
            f"has joint columns {', '.join(table.header[by_number[n]] for n in numbers)} but none "
            f"for joint {missing[0]}; name the joint columns in chain order with --joint-columns.",
        )
    ordered = [by_number[n] for n in numbers]
    if ordered != candidates:
        notes.append(
            f"{table.path}: the joint columns were taken in the order of their numbers "
            f"({', '.join(table.header[k] for k in ordered)}), not the header's "
            f"({', '.join(table.header[k] for k in candidates)})."
        )
    return ordered


def given_order(table: Table, cols: list[int], notes: list[str]) -> None:
    """Say so in a note when ``--joint-columns`` names numbered joints out of their numbers'
    order (``A7, A1, …``: a KUKA's linear unit first in the chain): the option's order is the
    chain's, as given."""
    numbers = [m[1] for k in cols if (m := JOINT_HEADER.match(table.heads[k].key))]
    if len(numbers) == len(cols) and [int(n) for n in numbers] != sorted(int(n) for n in numbers):
        notes.append(
            f"{table.path}: the joints were taken in the order --joint-columns gives "
            f"({', '.join(table.header[k] for k in cols)}), not by their numbers: the chain's "
            "order, as the option says."
        )


def named_joints(table: Table, taken: dict[int, str], notes: list[str]) -> list[int]:
    """The joint columns named as :data:`NAMED_JOINTS` (a UR arm's ``shoulder_pan_joint …``),
    in chain order, said in a note; empty when the header holds none of those sets whole."""
    for keys in NAMED_JOINTS:
        hits = [table.key(key) for key in keys]
        cols = [k for k in hits if k is not None and k not in taken]
        if len(cols) == len(keys):
            notes.append(
                f"{table.path}: the joints were taken in chain order from "
                f"{', '.join(table.header[k] for k in cols)} (a Universal Robots arm's names; "
                "--joint-columns names others)."
            )
            return cols
    return []


def position_prefixes(table: Table) -> list[str]:
    """The prefixes ``p`` (normalised) for which the header holds ``p x``, ``p y``, ``p z``
    (``measurement`` of ``measurement_x``): neither an uncertainty's (``std``, ``U95``…) nor an
    orientation's (``measurement_rx`` beside ``measurement_x``; ``rx`` alone)."""
    keys = {h.key for h in table.heads}
    found = [
        key[:-1]
        for key in sorted(keys)
        if key.endswith("x")
        and key[:-1] + "y" in keys
        and key[:-1] + "z" in keys
        and not any(w in key[:-1] for w in UNCERTAINTY_WORDS)
    ]
    return [
        p for p in found if not any(p == q + tail for q in ["", *found] for tail in _ROTATION_TAILS)
    ]


def _xyz_names(table: Table, opts: ImportOptions, notes: list[str]) -> tuple[str, str, str]:
    """The columns of x, y, z: the options', or, when they are the defaults and the header has
    no x, the one prefixed triple it holds (``measurement_x …``, said in a note); several
    triples are refused, naming them and the options."""
    names = (opts.x, opts.y, opts.z)
    if names != ("x", "y", "z") or table.find("x") is not None:
        return names
    found = position_prefixes(table)
    if not found:
        return names
    triples = [
        tuple(table.header[k] for k in (table.key(p + a) for a in "xyz") if k is not None)
        for p in found
    ]
    if len(found) > 1:
        shown = "; ".join(", ".join(t) for t in triples)
        raise ConversionError(
            table.path,
            f"has no column x but several triples that may be the target's position ({shown}); "
            "name the right one with --x, --y, --z (or several targets with --targets).",
        )
    x, y, z = triples[0]
    notes.append(f"{table.path}: the target's position was read from {x}, {y}, {z}.")
    return x, y, z


@dataclass(frozen=True)
class _Uncertainty:
    """One uncertainty column as its header names it: the prefix, what it is (``u95``, ``unc``:
    a standard uncertainty, ``std``: a standard deviation), its axis (``x``, ``y``, ``z``, or
    ``""``: one 3-D figure) and whether it is the orientation's (``std_rx``)."""

    k: int
    prefix: str
    word: str
    axis: str
    rotation: bool


def _word_starts(text: str, word: str) -> bool:
    """True when ``word`` starts a word of the header ``text``: after a separator or at a
    camel-case step (``leica_unc``, ``leicaUnc``), not inside another (``func``)."""
    low = text.lower()
    at = low.find(word)
    while at >= 0:
        if at == 0 or not text[at - 1].isalpha() or (text[at].isupper() and text[at - 1].islower()):
            return True
        at = low.find(word, at + 1)
    return False


def _uncertainty_column(k: int, text: str, key: str, prefix: str) -> _Uncertainty | None:
    """Column ``k`` (its header ``text``) read as an uncertainty by its ``key``, or None;
    ``prefix``: the position's (``{prefix}…r{axis}`` is the orientation's, as
    ``measurement_std_rx`` is). A prefix other than the position's starts the word at a word
    boundary of the header (``leica_uncX``, not ``func``)."""
    for pattern in (UNCERTAINTY_HEADERS[1], UNCERTAINTY_HEADERS[0], _ROTATION_UNCERTAINTY):
        m = pattern.match(key)
        if m is None:
            continue
        word = {"u95": "u95", "unc": "unc", "uncert": "unc", "uncertainty": "unc"}.get(
            m["word"], "std"
        )
        pre, axis = m["pre"], m["axis"] or ""
        rotation = pattern is _ROTATION_UNCERTAINTY
        if pattern is UNCERTAINTY_HEADERS[1]:  # "rx_std": the orientation's r before the axis
            for tail in _ROTATION_TAILS[:3]:
                if pre.endswith(tail) and pre[: -len(tail)] in (prefix, ""):
                    pre, rotation = pre[: -len(tail)], True
                    break
        if pre not in (prefix, "") and not _word_starts(text, m["word"]):
            return None
        return _Uncertainty(k, pre, word, axis, rotation)
    return None


def _uncertainty(
    table: Table, opts: ImportOptions, prefix: str, recognised: dict[int, str]
) -> tuple[tuple[str, list[int]] | None, list[int]]:
    """The position's uncertainty columns — per axis (``U95 X``, ``std x``, ``leica_uncX_m``)
    or one 3-D figure (``U95``, ``leica_unc_m``), of any prefix (:data:`UNCERTAINTY_HEADERS`) —
    and the uncertainty columns left unread (the orientation's, a second set, a 3-D figure
    beside the per-axis one), every one of them recognised (never a joint). Read, in this
    order: a U95 per axis, a 3-D U95, σ per axis, a 3-D σ; of the position's prefix first, then
    none, then any other (a 3-D σ of another prefix is not read: ``temp_std``)."""
    found = [
        u
        for k, h in enumerate(table.heads)
        if k not in recognised and (u := _uncertainty_column(k, h.text, h.key, prefix)) is not None
    ]
    for u in found:
        what = "the U95" if u.word == "u95" else "the σ"
        recognised[u.k] = (
            f"the orientation's σ '{table.header[u.k]}'"
            if u.rotation
            else f"{what} '{table.header[u.k]}'"
        )
    position = [u for u in found if not u.rotation]
    families: dict[tuple[str, str], dict[str, int]] = {}
    for u in position:
        family = families.setdefault((u.prefix, u.word), {})
        if u.axis in family:  # two columns of one figure: which would be read?
            table._one([family[u.axis], u.k])
        family[u.axis] = u.k

    def rank(family: tuple[str, str]) -> int:
        pre, _ = family
        return 0 if pre == prefix else 1 if pre == "" else 2

    u95: tuple[str, list[int]] | None = None
    for kind, words, axes in (
        ("axes", ("u95",), "xyz"),
        ("sphere", ("u95",), ""),
        ("std", ("std", "unc"), "xyz"),
        ("std3d", ("std", "unc"), ""),
    ):
        # one 3-D σ of another prefix (``temp_std``) may be another quantity's spread: not
        # read; an uncertainty (``leica_unc``, ``tracker_U95``) is the measurement's
        hits = sorted(
            (
                f
                for f, cols in families.items()
                if f[1] in words
                and (
                    all(a in cols for a in axes)
                    if axes
                    else "" in cols and (rank(f) < 2 or f[1] != "std")
                )
            ),
            key=rank,
        )
        if hits:
            cols = families[hits[0]]
            u95 = (kind, [cols[a] for a in axes] if axes else [cols[""]])
            break
    for k, h in enumerate(table.heads):
        if k not in recognised and any(w in h.key for w in UNCERTAINTY_WORDS[:5]):
            recognised[k] = f"an uncertainty '{table.header[k]}'"
    used = set(u95[1]) if u95 is not None and not opts.no_u95 else set()
    unread = [
        k
        for k, what in recognised.items()
        if k not in used and what.startswith(("the U95", "the σ", "the orientation's σ", "an "))
    ]
    return u95, sorted(unread)


def _name_columns(table: Table, opts: ImportOptions, *, required: bool) -> list[int]:
    """The point-name column(s): ``--name-column`` (which may name the joints file's instead,
    unless ``required``), else by the header (collection, group, point joined, or a name)."""
    if opts.name_column and (required or table.find(opts.name_column) is not None):
        return [table.column(opts.name_column, "the point name", "--name-column")]
    collection, group, point = table.key("collection"), table.key("group"), table.key("point")
    if point is not None and (collection is not None or group is not None):
        return [k for k in (collection, group, point) if k is not None]
    k = table.key(*NAME_HEADERS)
    return [] if k is None else [k]


def _orientation_columns(
    table: Table, opts: ImportOptions, recognised: dict[int, str], prefix: str = ""
) -> tuple[str, list[int]] | None:
    """The orientation's columns (and ``recognised`` completed with every orientation set the
    header holds, used or not); ``prefix``: the position's (``measurement_rx`` beside
    ``measurement_x``), tried first."""
    found: list[tuple[str, list[int]]] = []
    for kind, sets in (("quaternion", QUATERNION_HEADERS), ("angles", ANGLE_HEADERS)):
        prefixed = [tuple(prefix + key for key in keys) for keys in sets] if prefix else []
        for keys in [*prefixed, *sets]:
            hits = [table.key(key) for key in keys]
            if all(c is not None for c in hits):
                found.append((kind, [c for c in hits if c is not None]))
    # --joint-columns naming all of Q0…Q3: joints counted from 0, not a quaternion
    zero_based = set(QUATERNION_HEADERS[1]) <= {parse_header(c).key for c in opts.joint_columns}
    # Q0…Q3 beside Q4…: joints counted from 0, or a quaternion and more joints?
    leica = [f for f in found if [table.heads[c].key for c in f[1]] == list(QUATERNION_HEADERS[1])]
    if leica and not zero_based:
        more = [
            h.text
            for h in table.heads
            if (m := JOINT_HEADER.match(h.key)) and h.key.startswith("q") and int(m[1]) >= 4
        ]
        if more and not opts.orientation_columns and not opts.joint_columns:
            raise ConversionError(
                table.path,
                f"has Q0…Q3 and {', '.join(more)}: a quaternion (Q0 scalar first, as Leica "
                "writes it) beside more joints, or joints counted from 0? Name the joints "
                "with --joint-columns, or the orientation with --orientation-columns "
                "(none to leave it out).",
            )
    if zero_based:
        found = [f for f in found if f not in leica]
    for _, used in found:
        for c in used:
            recognised.setdefault(c, "the orientation")
    if opts.orientation_columns:
        if [c.lower() for c in opts.orientation_columns] == ["none"]:
            return None
        cols = [
            table.column(c, "the orientation", "--orientation-columns")
            for c in opts.orientation_columns
        ]
        if len(cols) not in (3, 4):
            raise ConversionError(
                table.path,
                f"--orientation-columns names {len(cols)} column(s); give four (a quaternion, "
                "scalar first: w, x, y, z) or three (rotation angles, see --euler), or none.",
            )
        for c in cols:
            recognised[c] = "the orientation"
        return ("quaternion" if len(cols) == 4 else "angles", cols)
    return found[0] if found else None


def column_layout(table: Table, opts: ImportOptions, *, joints: bool) -> Layout:
    """What each column of ``table`` holds; ``joints``: the joints are in this table. A column
    two options name (``--x X --y X``, ``--joint-columns A1,A1``) is refused."""
    recognised: dict[int, str] = {}
    claims: dict[int, str] = {}
    xyz = []
    notes: list[str] = []
    for name, axis in zip(_xyz_names(table, opts, notes), "xyz", strict=True):
        k = table.column(name, f"the target's {axis}", f"--{axis}")
        claim(table, claims, k, f"--{axis}")
        xyz.append(k)
        recognised[k] = f"the target's {axis}"
    time: int | None = None
    if opts.time:
        time = table.column(opts.time, "the time", "--time")
        claim(table, claims, time, "--time")
        recognised[time] = "the time"
    names = _name_columns(table, opts, required=opts.joints_file is None)
    for k in names:
        claim(table, claims, k, "--name-column" if opts.name_column else "the point name")
        recognised[k] = "the point name"
    keys = [table.heads[k].key for k in xyz]
    prefix = keys[0][:-1] if [k[-1:] for k in keys] == list("xyz") else ""
    if any(k[:-1] != prefix for k in keys):
        prefix = ""
    u95, unread = _uncertainty(table, opts, prefix, recognised)
    if u95 is not None and not opts.no_u95:
        for k in u95[1]:
            claim(table, claims, k, recognised[k])
    orientation = _orientation_columns(table, opts, recognised, prefix)
    if orientation is not None:
        option = "--orientation-columns" if opts.orientation_columns else "the orientation"
        for k in orientation[1]:
            claim(table, claims, k, option)
    cols: list[int] = []
    if joints and opts.joint_columns:
        for c in opts.joint_columns:
            k = table.column(c, "a joint", "--joint-columns")
            if k in recognised:
                raise ConversionError(
                    table.path,
                    f"--joint-columns names '{table.header[k]}', which is "
                    f"{recognised[k]}, not a joint; name the joint columns only.",
                )
            claim(table, claims, k, "--joint-columns")
            cols.append(k)
        given_order(table, cols, notes)
    elif joints:
        cols = joints_by_number(
            table,
            [
                k
                for k, h in enumerate(table.heads)
                if k not in recognised and JOINT_HEADER.match(h.key)
            ],
            notes,
        ) or named_joints(table, recognised, notes)
    unread = [k for k in unread if k not in cols]
    return Layout(xyz, names, time, u95, orientation, cols, recognised, notes, unread)
