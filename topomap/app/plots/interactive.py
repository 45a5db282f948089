"""The interactive map, ``map.html``: one self-contained file (plotly, its JavaScript inlined;
nothing is fetched from the network) to zoom, pan and hover over a learned map.

Each state is a node: at the mean position of its steps when the steps have positions, else where
a graph layout of the map puts it (:func:`~topomap.app.plots.common.node_positions`); nodes that
would overlap at the first view are pushed apart (the hover gives the true mean position).  Up to
:data:`NUMBERED_STATES` states each node carries its number.  Hovering over a node shows its id,
symbol (or GDS), visits, mean position, ground-truth places by name when known and its outgoing
transitions.  The nodes are one trace per kind -- learned, compound (steps of more than one true
place) and GDS states, coloured as in ``fig_map.png`` -- so the legend names each kind; the arcs
are those of ``fig_map.png`` (:func:`~topomap.app.plots.common.map_arcs`: some
``P(x'|x,u) > output.min_prob``, or the moves between states of a map whose steps mostly stay
in their state), each with an arrowhead at 70 % of its length;
a world with a floor plan (the arena's ``wall_segments``) has its walls drawn beneath.

However many states, the figure is a handful of traces: the walls, the arcs (one line, ``None``
between arcs), their arrowheads and the nodes of each kind, so that a browser stays responsive at
thousands of states.  Up to :data:`SVG_MAX_STATES` states they are SVG (``scatter``: every node is
a ``path.point`` element of the page); beyond, WebGL (``scattergl``, drawn on a canvas).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.data.atomic import atomic_write
from .common import compound_mask, map_arcs, node_positions
from .labels import spread

__all__ = ["map_figure", "write_map_html", "node_positions", "SVG_MAX_STATES", "NODE_COLOURS",
           "NODE_KINDS", "NUMBERED_STATES"]

#: most states drawn as SVG markers; larger maps are drawn with WebGL (``scattergl``)
SVG_MAX_STATES = 1000
#: most states whose nodes carry their numbers (larger nodes, the number inside)
NUMBERED_STATES = 100
#: a node's colour by kind: a learned state, a compound state, a state at a GDS (as fig_map.png)
NODE_COLOURS = {"state": "#ffffff", "compound": "#b2abd2", "gds": "gold"}
#: the legend's name of each kind of node
NODE_KINDS = {"state": "learned state", "compound": "compound state (steps of more than one "
              "true place)", "gds": "state at a GDS"}
#: outgoing transitions listed per state on hover (the most probable first)
MAX_HOVER_TRANSITIONS = 12
#: transitions below this probability are not listed on hover
MIN_HOVER_PROB = 0.05
#: the pixels the map's extent is taken to span at first view (a window 1,000 pixels wide)
_VIEW_PIXELS = np.array([900.0, 600.0])


def _hover(m, P, C, s: int, visits: int, where, places) -> str:
    """A node's hover text: id, symbol or GDS, visits, mean position, places, outgoing
    transitions (``P``, ``C``: the map's transition probabilities and counts)."""
    if m.state_gds[s] >= 0:
        kind = f"GDS {m.state_label(s)}"
    else:
        kind = f"symbol {int(m.state_symbol[s])}"
    lines = [f"<b>state {s}</b> ({kind})", f"visits: {visits}"]
    if where is not None:
        lines.append(f"mean position: ({where[0]:.2f}, {where[1]:.2f})")
    if places is not None:
        lines.append("place: " + ", ".join(f"{p} ({share:.0%})" for p, share in places))
    P, C = P[s], C[s]
    arcs = [(P[a, y], a, y) for a, y in zip(*np.nonzero((C > 0) & (P >= MIN_HOVER_PROB)))]
    arcs.sort(key=lambda t: (-t[0], t[1], t[2]))
    if arcs:
        lines.append("outgoing:")
    for p, a, y in arcs[:MAX_HOVER_TRANSITIONS]:
        name = m.action_names[a] if m.action_names else str(a)
        lines.append(f"  {name} \u2192 {m.state_label(int(y))} ({p:.2f})")
    if len(arcs) > MAX_HOVER_TRANSITIONS:
        lines.append(f"  ... {len(arcs) - MAX_HOVER_TRANSITIONS} more")
    return "<br>".join(lines)


def _places_of(labels, places, S, names=None) -> list:
    """Per state, its ground-truth places (by name, when ``names`` are given) with their shares
    of its steps (largest first, those of at least 5 %, at most three), or None for a state
    without steps."""
    out = [None] * S
    if places is None or labels is None:
        return out
    labels, places = np.asarray(labels), np.asarray(places)
    name = (lambda p: str(p)) if names is None else (lambda p: str(names[p]))  # noqa: E731
    for s in np.unique(labels):
        ps, n = np.unique(places[labels == s], return_counts=True)
        order = np.argsort(-n, kind="stable")
        share = n[order] / n.sum()
        out[int(s)] = [(name(int(ps[i])), float(f)) for i, f in zip(order, share)
                       if f >= 0.05][:3] or [(name(int(ps[order[0]])), float(share[0]))]
    return out


def _line(segments) -> tuple[list, list]:
    """x and y of segments ``(K, 2, 2)`` as one line, ``None`` between segments."""
    xs, ys = [], []
    for (x0, y0), (x1, y1) in np.asarray(segments, dtype=float).reshape(-1, 2, 2):
        xs += [float(x0), float(x1), None]
        ys += [float(y0), float(y1), None]
    return xs, ys


def _node_sizes(visits, S) -> np.ndarray:
    """Marker diameters in pixels, by visits: large enough for a number up to
    :data:`NUMBERED_STATES` states, smaller beyond."""
    small, big = (20, 10) if S <= NUMBERED_STATES else (7, 11) if S <= 200 else (3, 6)
    return small + big * np.sqrt(visits / max(int(visits.max()), 1))


def _spread_to_view(P, diameter, walls=None) -> np.ndarray:
    """``P`` with nodes closer than ``diameter`` pixels (plus a gap) at the first view pushed
    apart (the view taken as :data:`_VIEW_PIXELS` over the extent of ``P`` and the walls)."""
    shown = P if walls is None or not len(walls) else np.vstack([P, np.reshape(walls, (-1, 2))])
    extent = np.maximum(np.ptp(shown, axis=0), 1e-9)
    units_per_pixel = float((extent / _VIEW_PIXELS).max())
    return spread(P, (diameter + 3.0) * units_per_pixel)


def _node_traces(Scatter, P, kind, sizes, text, numbered):
    """One trace of nodes per kind present, in the kinds' order, named for the legend."""
    traces = []
    for k, colour in NODE_COLOURS.items():
        pick = np.flatnonzero(kind == k)
        if not pick.size and k != "state":
            continue
        traces.append(Scatter(
            x=P[pick, 0].tolist(), y=P[pick, 1].tolist(),
            mode="markers+text" if numbered else "markers",
            text=[str(s) for s in pick] if numbered else None, textposition="middle center",
            textfont=dict(size=10, color="black"), hovertext=[text[s] for s in pick],
            hoverinfo="text", name=NODE_KINDS[k] + (" (size: visits)" if k == "state" else ""),
            marker=dict(size=sizes[pick].round(1).tolist(), color=colour,
                        line=dict(color="red" if k == "gds" else "black", width=1))))
    return traces


def _arc_traces(Scatter, P, arcs, legend):
    """The arcs as one line and their arrowheads (at 70 % of each arc) as one marker trace."""
    ends = np.array(arcs, dtype=int).reshape(-1, 2)
    xs, ys = _line(np.stack([P[ends[:, 0]], P[ends[:, 1]]], axis=1))
    edge_trace = Scatter(x=xs, y=ys, mode="lines", hoverinfo="skip",
                         line=dict(color="rgba(80,80,80,0.55)", width=1),
                         name=legend)
    d = P[ends[:, 1]] - P[ends[:, 0]]
    head = P[ends[:, 0]] + 0.7 * d
    angle = np.degrees(np.arctan2(d[:, 0], d[:, 1]))  # clockwise from up, as plotly's
    head_trace = Scatter(x=head[:, 0].tolist(), y=head[:, 1].tolist(), mode="markers",
                         hoverinfo="skip", showlegend=False,
                         marker=dict(symbol="triangle-up", size=7, angle=angle.tolist(),
                                     color="rgba(80,80,80,0.8)"))
    return [edge_trace, head_trace]


def map_figure(m, labels=None, positions=None, places=None, *, min_prob: float = 0.8,
               seed: int = 0, place_names=None, walls=None):
    """The interactive map as a ``plotly.graph_objects.Figure`` (see the module docstring):
    ``m`` the :class:`~topomap.TopologicalMap`, ``labels`` the state of every step,
    ``positions`` and ``places`` the steps' ground truth (either may be None), ``place_names``
    the places' names (None: their ids) and ``walls`` the floor plan's walls, ``(W, 2, 2)``
    segments (None: none)."""
    import plotly.graph_objects as go

    S = m.n_states
    means, how = node_positions(m, labels, positions, seed, places)
    if how.startswith("graph layout:"):  # positions, but the states scatter: no floor plan
        walls = None
    Scatter = go.Scatter if S <= SVG_MAX_STATES else go.Scattergl
    visits = np.asarray(m.state_counts)
    sizes = _node_sizes(visits, S)
    numbered = S <= NUMBERED_STATES
    P = _spread_to_view(means, float(sizes.max()), walls) if S <= SVG_MAX_STATES else means
    arcs = map_arcs(m, min_prob)
    traces = []
    if walls is not None and len(walls):
        xs, ys = _line(walls)
        traces.append(Scatter(x=xs, y=ys, mode="lines", hoverinfo="skip", name="wall",
                              line=dict(color="black", width=2.5)))
    traces += _arc_traces(Scatter, P, arcs.between, arcs.legend)
    compound = (compound_mask(labels, places, S) if places is not None and labels is not None
                else np.zeros(S, dtype=bool))
    kind = np.where(m.state_gds >= 0, "gds", np.where(compound, "compound", "state"))
    shares = _places_of(labels, places, S, place_names)
    probs, counts = m.transition_probs, m.transition_counts  # computed once: (S, A, S)
    at = means if how == "mean position" else [None] * S
    text = [_hover(m, probs, counts, s, int(visits[s]), at[s],
                   shares[s] if places is not None else None) for s in range(S)]
    traces += _node_traces(Scatter, P, kind, sizes, text, numbered)
    n_compound = int((kind == "compound").sum())
    detail = f"nodes at their {how}" + (f"; {n_compound} compound state"
                                        f"{'s' if n_compound != 1 else ''}" if n_compound else "")
    shown = P if walls is None or not len(walls) else np.vstack([P, np.reshape(walls, (-1, 2))])
    lo, hi = shown.min(axis=0), shown.max(axis=0)
    pad = 0.04 * max(float((hi - lo).max()), 1e-9) + 0.5 * (hi - lo == 0)
    fig = go.Figure(traces)
    fig.update_layout(
        title=dict(text=f"learned map: {arcs.title(S)}<br><sup>{detail}</sup>",
                   font=dict(size=14), x=0.01,
                   xanchor="left", y=0.98, yanchor="top"),
        dragmode="pan", hovermode="closest", plot_bgcolor="white", template="none",
        margin=dict(l=20, r=20, t=70, b=20), legend=dict(orientation="h", y=-0.02),
        xaxis=dict(visible=False, range=[lo[0] - pad[0], hi[0] + pad[0]]),
        yaxis=dict(visible=False, scaleanchor="x", range=[lo[1] - pad[1], hi[1] + pad[1]]))
    return fig


def write_map_html(path, m, labels=None, positions=None, places=None, *, min_prob: float = 0.8,
                   seed: int = 0, place_names=None, walls=None) -> Path:
    """Write :func:`map_figure` as one self-contained HTML file (plotly's JavaScript inlined),
    atomically.  The same map gives the same file."""
    fig = map_figure(m, labels, positions, places, min_prob=min_prob, seed=seed,
                     place_names=place_names, walls=walls)
    html = fig.to_html(include_plotlyjs=True, full_html=True, div_id="topomap-map",
                       config={"scrollZoom": True, "displaylogo": False, "responsive": True})
    path = Path(path)
    atomic_write(path, lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return path
