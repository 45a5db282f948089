"""The arena's floor plan drawn on a matplotlib Axes: the outer wall, free-standing walls, holes,
objects and, optionally, the names of the regions.

Drawn with matplotlib alone (not ratinabox's own drawing, which makes its own figure style), in
artists that the run's figures can fade into a background: patches for the boundary and the holes,
one line collection for the walls, one marker set for the objects, texts for the regions.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_layout", "WALL_WIDTH"]

#: line width (points) of the walls
WALL_WIDTH = 2.0


def _region_centre(polygon: np.ndarray) -> np.ndarray:
    """A point inside a region to write its name at: its centroid (shapely's), or its mean corner
    when shapely is missing."""
    try:
        import shapely

        shape = shapely.Polygon(polygon)
        point = shape.centroid if shape.contains(shape.centroid) else shape.representative_point()
        return np.array([point.x, point.y])
    except ImportError:
        return polygon.mean(axis=0)


def plot_layout(layout, ax, labels: bool = True):
    """Draw ``layout`` (a :class:`~topomap.worlds.arena.layouts.Layout`) on ``ax``: the boundary
    and the walls in black, the holes grey, the objects as black stars (in the legend), and with
    ``labels`` each region's name in grey at its centre.  Equal axes, a margin of 4 % around the
    boundary, no ticks.  Returns ``ax``."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Polygon

    ax.add_patch(Polygon(layout.boundary, closed=True, fill=False, ec="black", lw=WALL_WIDTH,
                         joinstyle="miter", zorder=1))
    for hole in layout.holes:
        ax.add_patch(Polygon(hole, closed=True, fc="0.8", ec="black", lw=WALL_WIDTH / 2, zorder=1))
    if len(layout.walls):
        ax.add_collection(LineCollection(layout.walls, colors="black", linewidths=WALL_WIDTH,
                                         capstyle="butt", zorder=1))
    if len(layout.objects):
        ax.scatter(layout.objects[:, 0], layout.objects[:, 1], marker="*", s=60, c="black",
                   zorder=1, label="object")
    if labels:
        for name, polygon in layout.regions:
            x, y = _region_centre(polygon)
            ax.text(x, y, name, ha="center", va="center", fontsize=7, color="0.55", zorder=1)
    x0, x1, y0, y1 = layout.extent
    pad = 0.04 * max(x1 - x0, y1 - y0)
    ax.set_xlim(x0 - pad, x1 + pad)
    ax.set_ylim(y0 - pad, y1 + pad)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    return ax
