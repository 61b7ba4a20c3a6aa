"""Joint values from a file of their own (``--joints-file``), matched to an export's points by
point name (the full name or its last ``::`` part) when both files name points, else by row."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.io.exports.layout import (
    JOINT_HEADER,
    NAME_HEADERS,
    claim,
    given_order,
    joints_by_number,
    named_joints,
)
from dhlog.io.exports.options import ImportOptions
from dhlog.io.exports.source import Source, joint_values
from dhlog.io.exports.table import ConversionError, Table, read_table


def _joints_name_column(joints: Table, opts: ImportOptions) -> int | None:
    if opts.name_column and joints.find(opts.name_column) is not None:
        return joints.find(opts.name_column)
    k = joints.key(*NAME_HEADERS)
    if k is None and not joints.numeric(0):
        k = 0  # a first column of names
    return k


def with_joints_file(src: Source, opts: ImportOptions) -> Source:
    """``src`` with the joint values of ``opts.joints_file``, matched by point name (when both
    name points) or by row; by name, the points come in the joints file's order."""
    assert opts.joints_file is not None
    joints = read_table(opts.joints_file, option="--joints-file")
    nk = _joints_name_column(joints, opts)
    if opts.name_column and joints.find(opts.name_column) is None and not src.named_by_option:
        raise ConversionError(
            joints.path,
            f"has no column '{opts.name_column}' (--name-column), nor has {src.path}; its "
            f"columns are {', '.join(joints.header)}; name the point column with --name-column.",
        )
    claims: dict[int, str] = {} if nk is None else {nk: "the point name"}
    if opts.joint_columns:
        cols = []
        for c in opts.joint_columns:
            k = joints.column(c, "a joint", "--joint-columns")
            claim(joints, claims, k, "--joint-columns")
            cols.append(k)
        given_order(joints, cols, src.notes)
    else:
        cols = joints_by_number(
            joints,
            [k for k, h in enumerate(joints.heads) if k != nk and JOINT_HEADER.match(h.key)],
            src.notes,
        ) or named_joints(joints, claims, src.notes)
    if not cols:
        raise ConversionError(
            joints.path,
            "has no joint columns (q1…, j1…, A1…, joint_1…, axis1…); its columns are "
            f"{', '.join(joints.header)}; name them with --joint-columns.",
        )
    names, q = joint_values(joints, cols, opts, src.warnings)
    by_name = nk is not None and src.names is not None
    if nk is not None and src.names is not None:
        p_idx, r_idx = _match_by_name(src, joints, nk)
    else:
        if len(joints.rows) != len(src.xyz):
            raise ConversionError(
                joints.path,
                f"has {len(joints.rows)} row(s), {src.path} {len(src.xyz)} point(s); without "
                "point names in both files to match them by, rows are matched in order and "
                "must be as many (name the point column with --name-column).",
            )
        p_idx = r_idx = np.arange(len(src.xyz))
        src.notes.append(
            f"{joints.path}: its rows were matched to the points of {src.path} in order (the "
            "points are not named in both files; --name-column names the column)."
        )
    if src.t_ns is not None:  # timed samples keep their time order
        order = np.argsort(p_idx, kind="stable")
        p_idx, r_idx = p_idx[order], r_idx[order]
    out = src.take(p_idx)
    out.joint_names, out.q = names, q[r_idx]
    out.provenance["joints_matched"] = "by point name" if by_name else "by row"
    return out


def _match_by_name(
    src: Source, joints: Table, nk: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Rows of the points and of the joints file that name the same point (the full name or
    its last ``::`` part), in the joints file's order."""
    assert src.names is not None
    by_name: dict[str, int] = {}
    for i, name in enumerate(src.names):
        for key in {name, name.split("::")[-1]}:
            if key in by_name and by_name[key] != i and key == name:
                raise ConversionError(
                    src.path,
                    f"names the point '{name}' twice; point names must be unique to match "
                    "--joints-file by name.",
                    src.lines[i],
                )
            by_name.setdefault(key, i)
    rows, missing = [], []
    for r, name in enumerate(joints.texts(nk)):
        if name in by_name:
            rows.append((r, by_name[name]))
        else:
            missing.append((joints.lines[r], name))
    if missing:
        line, name = missing[0]
        src.warnings.append(
            f"{joints.path}: {len(missing)} row(s) name a point that {Path(src.path).name} "
            f"does not hold (first: '{name}', line {line}); they were left out."
        )
    unused = len(src.names) - len({p for _, p in rows})
    if unused:
        src.warnings.append(
            f"{src.path}: {unused} point(s) have no joint values in {joints.path} and were "
            "left out."
        )
    if not rows:
        raise ConversionError(
            joints.path,
            f"names none of the points of {Path(src.path).name}; name its point column with "
            "--name-column.",
        )
    return (
        np.array([p for _, p in rows], dtype=np.int64),
        np.array([r for r, _ in rows], dtype=np.int64),
    )
