"""Geometry shared by the office modules: tolerances, walls, corners, angles."""

from __future__ import annotations

import math

import numpy as np

from ...core.checks import ParameterError, check_count

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
    """Raise a :class:`~topomap.core.checks.ParameterError` naming ``name`` unless ``value`` is a
    positive number (or integer)."""
    if integer:
        check_count(value, name)
        return
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(name, f"must be a number, got {value!r}")
    if not (value > 0) or (not allow_inf and not math.isfinite(value)) or math.isnan(value):
        raise ParameterError(name, f"must be positive{'' if allow_inf else ' and finite'}, "
                                   f"got {value!r}")
