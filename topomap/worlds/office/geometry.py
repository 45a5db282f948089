"""Geometry shared by the office modules: tolerances, walls, corners, angles."""

from __future__ import annotations

import math

import numpy as np

#: distances closer than this count as equal
TOL = 1e-7
#: outward normals of the south, east, north and west walls
WALL_NORMALS = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
CORNER_NAMES = ("corner SW", "corner SE", "corner NE", "corner NW")


def wrap(angle: float) -> float:
    """Wrap an angle in radians to ``(-pi, pi]``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def corner_points(width: float, height: float, offset: float) -> np.ndarray:
    """Corner points of the wall-following lane: SW, SE, NE, NW."""
    return np.array(
        [[offset, offset], [width - offset, offset], [width - offset, height - offset],
         [offset, height - offset]]
    )


def surface_gaps(centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Pairwise surface-to-surface distances (``inf`` on the diagonal)."""
    d = np.hypot(*(centers[:, None, :] - centers[None, :, :]).transpose(2, 0, 1))
    gap = d - radii[:, None] - radii[None, :]
    np.fill_diagonal(gap, np.inf)
    return gap


def check_positive(name: str, value, integer: bool = False, allow_inf: bool = False) -> None:
    """Raise a ValueError naming ``name`` unless ``value`` is a positive number (or integer)."""
    kinds = (int, np.integer) if integer else (int, float, np.integer, np.floating)
    if isinstance(value, bool) or not isinstance(value, kinds):
        kind = "an integer" if integer else "a number"
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    if not (value > 0) or (not allow_inf and not math.isfinite(value)) or math.isnan(value):
        raise ValueError(f"{name} must be positive{'' if allow_inf else ' and finite'}, got {value!r}")
