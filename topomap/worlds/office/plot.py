"""Drawing the office room with matplotlib."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_room"]


def plot_room(world, ax, labels: bool = True, show_corners: bool = True):
    """Draw ``world``'s room on a matplotlib Axes: walls, objects coloured by type, GDS dashed
    circles.  Returns ``ax``."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    w = world
    ax.add_patch(Rectangle((0, 0), w.width, w.height, fill=False, lw=2.5, ec="black"))
    cmap = plt.get_cmap("tab20", max(w.n_types, 1))
    for i in range(w.n_objects):
        t = int(w.object_types[i])
        c, r = w.object_positions[i], w.object_radii[i]
        ax.add_patch(Circle(c, r, fc=cmap(t), ec="black", lw=0.8))
        if labels:
            ax.annotate(w.place_names[i].split(" (")[0], c, xytext=(0, r * 12 + 6),
                        textcoords="offset points", ha="center", fontsize=6)
    for k, i in enumerate(w.gds_places):
        c, r = w.object_positions[i], w.object_radii[i]
        ax.add_patch(Circle(c, r + w.reach, fill=False, ls="--", lw=1.2, ec="red"))
        ax.annotate(w.gds_names[k], c + np.array([0, -(r + w.reach) - 0.5]), ha="center",
                    fontsize=7, color="red")
    if show_corners:
        corners = w.place_positions[w.n_objects:]
        ax.plot(corners[:, 0], corners[:, 1], "k+", ms=6)
    ax.set_xlim(-0.5, w.width + 0.5)
    ax.set_ylim(-0.5, w.height + 0.5)
    ax.set_aspect("equal")
    return ax
