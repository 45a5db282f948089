"""Ground-truth positions of a trajectory's steps: checked once, and their CSV columns.

Positions are metres in the plane (``x``, ``y``) or in space (``x``, ``y``, ``z``): a ``(T, 2)`` or
``(T, 3)`` float array, one row per step, every value finite.
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_positions", "POSITION_COLUMNS", "csv_positions"]

#: the CSV columns of a position, in order (``z`` only for positions in space)
POSITION_COLUMNS = ("x", "y", "z")


def check_positions(values, n_steps: int) -> np.ndarray:
    """``values`` as a ``(n_steps, 2)`` or ``(n_steps, 3)`` float64 array, or a one-line
    ValueError naming ``positions``."""
    try:
        P = np.asarray(values)
    except (ValueError, TypeError):
        raise ValueError("positions must be a rectangular array (T, 2) or (T, 3) of numbers, "
                         "not nested lists of unequal lengths") from None
    if P.dtype.kind not in "fiu":
        raise ValueError(f"positions must be numbers, got values of type {P.dtype}")
    if P.ndim != 2 or P.shape[1] not in (2, 3):
        raise ValueError(f"positions must have shape ({n_steps}, 2) or ({n_steps}, 3), "
                         f"got {P.shape}")
    if P.shape[0] != n_steps:
        raise ValueError(f"positions has {P.shape[0]} rows but observations has {n_steps} rows; "
                         "they must have the same length")
    P = P.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(P).all(axis=1))
    if bad.size:
        raise ValueError(f"positions contain NaN or inf in {bad.size} row(s), first at step "
                         f"{int(bad[0])}")
    return P


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
