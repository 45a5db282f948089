"""Plane geometry over whole paths at once (numpy): rays against walls, points against polygons.

A *segment* array has shape ``(W, 2, 2)``: wall ``w`` runs from ``segments[w, 0]`` to
``segments[w, 1]`` (metres).  Every function takes all positions of a path together and works
through them in blocks, so memory stays bounded however long the path is.
"""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as PolygonPath

__all__ = ["ray_distances", "segment_distances", "inside_polygon", "nearest_on_segments",
           "polygon_edges"]

#: most elements (rows x beams x walls) of one block's temporaries
_BLOCK_ELEMENTS = 1 << 21


def _block_rows(per_row: int) -> int:
    return max(1, _BLOCK_ELEMENTS // max(per_row, 1))


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


def ray_distances(origins, angles, segments, max_range: float) -> np.ndarray:
    """Distance from each origin along each ray to the first wall, at most ``max_range``.

    Parameters
    ----------
    origins : (T, 2) float
    angles : (T, B) or (B,) float
        Ray directions in radians, anticlockwise from +x (east).
    segments : (W, 2, 2) float
    max_range : float
        The value of a ray that meets no wall within ``max_range``.

    Returns
    -------
    (T, B) float array.  A ray meets a wall where ``origin + t * direction`` (``t >= 0``) crosses
    the segment (its end points included); a ray running along a wall does not meet it.
    """
    P = np.asarray(origins, dtype=np.float64)
    theta = np.broadcast_to(np.asarray(angles, dtype=np.float64), (P.shape[0], np.shape(angles)[-1]))
    S = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    ax, ay = S[:, 0, 0], S[:, 0, 1]
    ex, ey = S[:, 1, 0] - ax, S[:, 1, 1] - ay
    out = np.empty(theta.shape)
    rows = _block_rows(theta.shape[1] * S.shape[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(0, P.shape[0], rows):
            dx = np.cos(theta[i:i + rows])[:, :, None]
            dy = np.sin(theta[i:i + rows])[:, :, None]
            wx = (ax - P[i:i + rows, :1])[:, None, :]
            wy = (ay - P[i:i + rows, 1:])[:, None, :]
            denom = _cross(dx, dy, ex, ey)
            t = _cross(wx, wy, ex, ey) / denom
            s = _cross(wx, wy, dx, dy) / denom
            hit = (denom != 0) & (t >= 0) & (s >= 0) & (s <= 1)
            out[i:i + rows] = np.where(hit, t, np.inf).min(axis=2, initial=np.inf)
    return np.minimum(out, max_range)


def nearest_on_segments(points, segments) -> tuple[np.ndarray, np.ndarray]:
    """For each point, the nearest point on any segment and its distance: ``(T, 2)``, ``(T,)``."""
    P = np.asarray(points, dtype=np.float64)
    S = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 2)
    a, e = S[:, 0], S[:, 1] - S[:, 0]
    length2 = np.maximum((e ** 2).sum(axis=1), 1e-300)
    nearest = np.empty_like(P)
    dist = np.empty(P.shape[0])
    rows = _block_rows(S.shape[0] * 2)
    for i in range(0, P.shape[0], rows):
        w = P[i:i + rows, None, :] - a[None]
        s = np.clip((w * e[None]).sum(axis=2) / length2, 0.0, 1.0)
        foot = a[None] + s[:, :, None] * e[None]
        d = np.hypot(*(P[i:i + rows, None, :] - foot).transpose(2, 0, 1))
        k = d.argmin(axis=1)
        nearest[i:i + rows] = foot[np.arange(k.size), k]
        dist[i:i + rows] = d[np.arange(k.size), k]
    return nearest, dist


def segment_distances(points, segments) -> np.ndarray:
    """Distance from each point to the nearest of the segments, ``(T,)``."""
    return nearest_on_segments(points, segments)[1]


def inside_polygon(points, polygon) -> np.ndarray:
    """Which points lie strictly inside the polygon ``(N, 2)`` (its corners, in order)."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return PolygonPath(np.asarray(polygon, dtype=np.float64)).contains_points(P)


def polygon_edges(polygon) -> np.ndarray:
    """The edges of a closed polygon as segments ``(N, 2, 2)``."""
    C = np.asarray(polygon, dtype=np.float64)
    return np.stack([C, np.roll(C, -1, axis=0)], axis=1)
