"""The ``.csv`` (or gzip-compressed ``.csv.gz``) trajectory file: a header row
``o0,...,o{D-1},action[,gds][,place][,x,y[,z]][,odom_x,odom_y,odom_theta][,episode]`` and one
row per step (``docs/file-formats.md``), read into the fields of a
:class:`~topomap.core.data.trajectory.Trajectory` (:func:`read_csv`); a spreadsheet's UTF-8
byte-order mark is dropped, actions may be ids or names."""

from __future__ import annotations

import csv
import gzip
from pathlib import Path

import numpy as np

from .odometry import ODOMETRY_COLUMNS, csv_odometry
from .positions import POSITION_COLUMNS, csv_positions

__all__ = ["read_csv"]


def _csv_rows(path: Path) -> list[list[str]]:
    """The rows of a CSV file, gzip-compressed when its name ends in ``.gz`` (a UTF-8
    byte-order mark, as spreadsheets write, is dropped)."""
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    try:
        with opener(path, "rt", newline="", encoding="utf-8-sig") as fh:
            return list(csv.reader(fh))
    except (OSError, EOFError, UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"trajectory file {path} could not be read as CSV: {exc}") from None


def _check_csv_header(header: list[str], path: Path) -> list[int]:
    """The indices of the observation columns; a one-line error for a header that is not
    ``o0..o{D-1}, action`` and the optional columns (naming the nearest known column)."""
    import difflib

    obs_cols = [i for i, h in enumerate(header) if h.startswith("o") and h[1:].isdigit()]
    known = ["action", "gds", "place", "episode", *POSITION_COLUMNS, *ODOMETRY_COLUMNS]
    unknown = [h for i, h in enumerate(header) if i not in obs_cols and h not in known]
    if unknown:
        close = difflib.get_close_matches(unknown[0], known, n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ValueError(
            f"trajectory file {path}: unknown column(s) {', '.join(map(repr, unknown))}{hint} "
            "(expected o0..o{D-1}, action and optionally gds, place, x, y, z, odom_x, odom_y, "
            "odom_theta, episode)")
    if not obs_cols:
        raise ValueError(f"trajectory file {path} has no observation columns o0, o1, ...")
    expected = [f"o{i}" for i in range(len(obs_cols))]
    if [header[i] for i in obs_cols] != expected:
        raise ValueError(f"trajectory file {path}: observation columns must be {expected[0]}..{expected[-1]} in order")
    if "action" not in header:
        raise ValueError(f"trajectory file {path} has no 'action' column")
    return obs_cols


def _action_names(body: list[list[str]], column: int) -> tuple[list[str], list[str]] | None:
    """Actions given by name (a column whose values are not all numbers): the column as ids in
    order of first appearance (as text) and the names, or None for numeric actions."""
    values = [row[column].strip() if column < len(row) else "" for row in body]
    try:
        for v in values:
            float(v)
        return None
    except ValueError:
        pass
    names = list(dict.fromkeys(values))
    ids = {name: str(i) for i, name in enumerate(names)}
    return [ids[v] for v in values], names


def read_csv(path: Path) -> dict:
    """The columns of the ``.csv`` trajectory file ``path`` (``docs/file-formats.md``) as
    :class:`~topomap.core.data.trajectory.Trajectory`'s keyword arguments, with its ``episode``
    column as read (the caller checks it and the fields); every problem a one-line ValueError
    naming the file."""
    rows = _csv_rows(path)
    if not rows:
        raise ValueError(f"trajectory file {path} is empty")
    header = [h.strip() for h in rows[0]]
    obs_cols = _check_csv_header(header, path)
    body = rows[1:]
    if not body:
        raise ValueError(f"trajectory file {path} has a header but no data rows")
    action = header.index("action")
    named = _action_names(body, action)
    table = np.empty((len(body), len(header)), dtype=np.float64)
    for r, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise ValueError(
                f"trajectory file {path}, line {r}: {len(row)} fields but the header has {len(header)}"
            )
        if named is not None:
            row = [*row[:action], named[0][r - 2], *row[action + 1:]]
        for c, value in enumerate(row):
            try:
                table[r - 2, c] = float(value)
            except ValueError:
                raise ValueError(
                    f"trajectory file {path}, line {r}, column {header[c]!r}: {value!r} is not a number"
                ) from None
    col = {h: table[:, i] for i, h in enumerate(header)}
    kwargs = {"observations": table[:, obs_cols], "actions": col["action"]}
    if named is not None:
        kwargs["action_names"] = named[1]
    if "gds" in col:
        kwargs["gds"] = col["gds"]
    if "place" in col:
        kwargs["places"] = col["place"]
    positions = csv_positions(header, col, path)
    if positions is not None:
        kwargs["positions"] = positions
    odometry = csv_odometry(header, col, path)
    if odometry is not None:
        kwargs["odometry"] = odometry
    if "episode" in col:
        kwargs["episode"] = col["episode"]
    return kwargs
