"""``fig_map.png``: the learned map as a graph, after the paper's Fig. 7.

Each state is a node at the mean position of its steps over the world's room (or, when the steps
have no positions, where a seeded layout of the map's graph puts it:
:func:`~topomap.app.plots.common.node_positions`, as ``map.html`` does); an arc joins two states
where some ``P(x'|x,u)`` exceeds ``min_prob`` -- or, for a map whose steps mostly stay in their
state (a log sampled faster than it moves), where a share of the moves leaving a state go
(:func:`~topomap.app.plots.common.map_arcs`).  The room's own point markers (the office's corner
places) are drawn larger than the nodes and beneath them, so that a node standing on one leaves
its arms showing.
"""

from __future__ import annotations

import numpy as np

from .common import compound_mask, map_arcs, node_positions, room
from .labels import data_per_point, spread
from .style import MAX_MAP_NUMBERS, TITLE_SIZE

__all__ = ["plot_map", "NODE_KINDS"]

#: how the map draws a plain, a compound and a GDS state: (fill, edge, area factor, legend)
NODE_KINDS = (("white", "black", 1.0, "learned state"),
              ("#b2abd2", "black", 1.0, "compound state (steps of more than one true place)"),
              ("gold", "red", 1.3, "state at a GDS"))


def _arcs(ax, arcs, pos, diameter):
    """Draw the map's arcs (:func:`~.common.map_arcs`) as thin grey curves that bend to the
    right of their direction (so the arcs x -> x' and x' -> x stay apart), ending at the nodes'
    rims (``diameter`` points) in an arrowhead; a self-loop is a small circle above its node.
    Two collections, so that maps of thousands of arcs draw quickly; a legend entry for each
    kind drawn."""
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.lines import Line2D

    unit = data_per_point(ax)[0]
    edges = np.array(arcs.between, dtype=int).reshape(-1, 2)
    loops = list(arcs.loops)
    t = np.linspace(0.0, 1.0, 12)[:, None, None]
    p = np.array([pos[a] for a in edges[:, 0]]).reshape(-1, 2)
    q = np.array([pos[b] for b in edges[:, 1]]).reshape(-1, 2)
    d = q - p
    normal = np.column_stack([d[:, 1], -d[:, 0]])
    c = (p + q) / 2 + 0.15 * normal

    def rim(x):
        """From the nodes ``x`` towards the arcs' control points, out to the nodes' rims."""
        v = c - x
        return x + (0.5 * diameter + 1.0) * unit * v / np.maximum(np.hypot(*v.T), 1e-12)[:, None]

    s, e = rim(p), rim(q)
    curves = ((1 - t) ** 2 * s + 2 * (1 - t) * t * c + t ** 2 * e).transpose(1, 0, 2)
    u = (e - c) / np.maximum(np.hypot(*(e - c).T), 1e-12)[:, None]
    side = np.column_stack([-u[:, 1], u[:, 0]]) * 1.8 * unit
    back = e - 5.0 * u * unit
    heads = np.stack([e, back + side, back - side], axis=1)
    angle = np.linspace(0, 2 * np.pi, 12)
    loop = min(3.0, 0.3 * diameter)  # a loop's radius (points): never larger than its node
    circle = loop * unit * np.column_stack([np.cos(angle), np.sin(angle) + 1.0])
    circles = [pos[a] + (0.5 * diameter * unit) * np.array([0, 1]) + circle for a in loops]
    ax.add_collection(LineCollection([*curves, *circles], colors="0.3", linewidths=0.6,
                                     alpha=0.6, zorder=2), autolim=False)
    ax.add_collection(PolyCollection(heads, facecolors="0.3", edgecolors="none", alpha=0.7,
                                     zorder=2), autolim=False)
    if len(edges):
        ax.add_line(Line2D([], [], color="0.3", lw=0.8, label=arcs.legend))
    if loops:
        ax.add_line(Line2D([], [], color="0.3", lw=0, marker="o", mfc="none", ms=5,
                           label="self-loop (small circle): stays in the state"))


def _nodes(ax, P, states, kinds, diameter, numbered):
    """The map's states at ``P`` in the style of their kind (0 plain, 1 compound, 2 GDS), with
    their numbers when ``numbered``."""
    for k, (face, edge, area, label) in enumerate(NODE_KINDS):
        pick = kinds == k
        if pick.any():
            ax.scatter(P[pick, 0], P[pick, 1], s=area * diameter ** 2, c=face, edgecolors=edge,
                       lw=0.8, zorder=4, label=label)
    if numbered:
        for s, (x, y) in zip(states, P):
            ax.text(x, y, str(s), ha="center", va="center", fontsize=5.5, zorder=5)


def _room_markers_around_nodes(ax, diameter) -> None:
    """The room's point markers (lines drawn with a marker and no line, such as the office's
    corner places) drawn grey, 1.8 times the nodes' ``diameter`` and beneath them, so that a
    node standing on one leaves its arms showing."""
    for line in ax.lines:
        if line.get_linestyle() in ("None", "none", "") and line.get_marker() not in (None, "None"):
            line.set_markersize(1.8 * diameter)
            line.set_markeredgewidth(1.0)
            line.set_color("0.35")
            line.set_zorder(3)


def _layout_axes(ax, P):
    """Equal axes around a graph layout ``P``, a margin of 8 % of its extent, no ticks."""
    lo, hi = P.min(axis=0), P.max(axis=0)
    pad = 0.08 * max(float((hi - lo).max()), 1e-9)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])


def plot_map(ax, traj, learner, env=None, min_prob=0.8, seed=0):
    """The learned map at the states' mean positions over the room (or at a graph layout seeded
    by ``seed`` when the steps have no positions), arcs where some P(x'|x,u) > min_prob;
    numbered nodes (spread apart where they coincide) up to :data:`MAX_MAP_NUMBERS` states, small
    dots beyond; compound states lavender (when the ground truth is known), GDS states gold.  One
    legend beside the map: the room's entries (if any), then the nodes'.  Returns ``ax``."""
    m = learner.map_
    arcs = map_arcs(m, min_prob)
    means, how = node_positions(m, learner.labels_, traj.positions, seed, traj.places)
    if how != "mean position":
        _layout_axes(ax, means)
    else:
        room(ax, env, traj.positions)
    room_legend = ax.get_legend()
    keep = np.flatnonzero(np.isfinite(means).all(axis=1))
    kept = set(keep.tolist())
    arcs.between = [(a, b) for a, b in arcs.between if a in kept and b in kept]
    arcs.loops = [a for a in arcs.loops if a in kept]
    numbered = len(keep) <= MAX_MAP_NUMBERS
    diameter = 11.0 if numbered else 4.0  # points
    _room_markers_around_nodes(ax, diameter)
    unit = data_per_point(ax)[0]
    P = spread(means[keep], 1.1 * diameter * unit) if numbered else means[keep]
    _arcs(ax, arcs, dict(zip(keep.tolist(), P)), diameter)
    kinds = np.where(m.state_gds[keep] >= 0, 2, 0)
    if traj.places is not None:
        compound = compound_mask(learner.labels_, traj.places, m.n_states)
        kinds[(kinds == 0) & compound[keep]] = 1
    _nodes(ax, P, keep, kinds, diameter, numbered)
    handles, names = ax.get_legend_handles_labels()
    if room_legend is not None:  # one legend: the room's entries, then the map's
        handles = [*room_legend.legend_handles, *handles]
        names = [*(t.get_text() for t in room_legend.get_texts()), *names]
    ax.legend(handles, names, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
              frameon=False)
    where = ("" if how == "mean position" else "\nnodes at a " + how if traj.positions is not None
             else "; no positions: nodes at a layout of the graph")
    ax.set_title("learned map: " + arcs.title(m.n_states)
                 + ("" if numbered else "; numbers omitted") + where, fontsize=TITLE_SIZE)
    return ax
