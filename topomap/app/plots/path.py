"""``fig_path.png``: the path of a walk with continuous positions (the arena, a robot's log), over
the floor plan when the world has one: one line coloured by time, the start and the end marked.
"""

from __future__ import annotations

import numpy as np

from .common import MAX_POINTS, room
from .style import LEGEND_SIZE, TITLE_SIZE

__all__ = ["plot_path"]


def plot_path(ax, traj, env=None, title=""):
    """The steps' positions joined in order, coloured from dark (the first step) to light (the
    last) with a colour bar in steps, over the world's room (or bare limits around the
    positions); a new episode (``traj.lengths``) starts a new line.  Beyond :data:`MAX_POINTS`
    steps every k-th position is drawn.  Returns ``ax``."""
    from matplotlib.collections import LineCollection

    P = np.asarray(traj.positions, dtype=float)[:, :2]
    room(ax, env, P)
    step = max(1, -(-len(P) // MAX_POINTS))
    lengths = traj.lengths if traj.lengths is not None else [len(P)]
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(int)
    segments, times = [], []
    for first, n in zip(starts, lengths):
        idx = np.arange(first, first + n, step)
        if idx[-1] != first + n - 1:
            idx = np.append(idx, first + n - 1)
        segments.append(np.stack([P[idx[:-1]], P[idx[1:]]], axis=1))
        times.append(idx[:-1])
    lines = LineCollection(np.concatenate(segments), cmap="viridis", linewidths=0.6,
                           alpha=0.8, zorder=2)
    lines.set_array(np.concatenate(times).astype(float))
    ax.add_collection(lines, autolim=False)
    ax.scatter(*P[0], marker="o", s=40, c="white", edgecolors="black", zorder=4,
               label="first step")
    ax.scatter(*P[-1], marker="s", s=40, c="black", zorder=4, label="last step")
    bar = ax.figure.colorbar(lines, ax=ax, fraction=0.035, pad=0.02)
    bar.set_label("step", fontsize=LEGEND_SIZE)
    bar.ax.tick_params(labelsize=LEGEND_SIZE)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.01), ncol=2, fontsize=LEGEND_SIZE,
              frameon=False)
    seconds = (traj.meta or {}).get("dt")
    span = f", {len(P) * seconds / 60:.0f} minutes" if seconds else ""
    ax.set_title(title or f"the path learned from: {len(P)} steps{span}", fontsize=TITLE_SIZE)
    return ax
