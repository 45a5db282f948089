"""Ground-truth positions of a trajectory's steps: checked once, and their CSV columns.

Positions are metres in the plane (``x``, ``y``) or in space (``x``, ``y``, ``z``): a ``(T, 2)`` or
``(T, 3)`` float array, one row per step, every value finite.
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_positions", "per_step_rows", "POSITION_COLUMNS", "csv_positions"]

#: the CSV columns of a position, in order (``z`` only for positions in space)
POSITION_COLUMNS = ("x", "y", "z")


def per_step_rows(values, name: str, n_steps: int, widths: tuple, layout: str,
                  shape_says: str) -> np.ndarray:
    """``values`` as a float64 array of ``n_steps`` finite rows of one of ``widths`` columns, or a
    one-line ValueError naming ``name``: ``layout`` is the shape in words (``"(T, 3)"``) and
    ``shape_says`` what a wrong shape is told (``"(T, 3): x, y, heading;"``, then the shape)."""
    try:
        arr = np.asarray(values)
    except (ValueError, TypeError):
        raise ValueError(f"{name} must be a rectangular array {layout} of numbers, not nested "
                         "lists of unequal lengths") from None
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be numbers, got values of type {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in widths:
        raise ValueError(f"{name} must have shape {shape_says} {arr.shape}")
    if arr.shape[0] != n_steps:
        raise ValueError(f"{name} has {arr.shape[0]} rows but observations has {n_steps} rows; "
                         "they must have the same length")
    arr = arr.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(arr).all(axis=1))
    if bad.size:
        verb = "contain" if name.endswith("s") else "contains"
        raise ValueError(f"{name} {verb} NaN or inf in {bad.size} row(s), first at step "
                         f"{int(bad[0])}")
    return arr


def check_positions(values, n_steps: int) -> np.ndarray:
    """``values`` as a ``(n_steps, 2)`` or ``(n_steps, 3)`` float64 array, or a one-line
    ValueError naming ``positions``."""
    return per_step_rows(values, "positions", n_steps, (2, 3), "(T, 2) or (T, 3)",
                         f"({n_steps}, 2) or ({n_steps}, 3), got")


def csv_positions(header: list, columns: dict, path) -> np.ndarray | None:
    """The positions held in a CSV's ``x``, ``y`` (and ``z``) columns, or None without them.

    ``columns`` maps a column name to its values; a ``z`` without ``x`` and ``y``, or an ``x``
    without a ``y``, is a ValueError naming the file.
    """
    present = [c for c in POSITION_COLUMNS if c in header]
    if not present:
        return None
    if present not in (["x", "y"], ["x", "y", "z"]):
        raise ValueError(f"trajectory file {path} has the position column(s) {', '.join(present)}"
                         "; positions need the columns x and y (and z for positions in space)")
    return np.column_stack([columns[c] for c in present])
