"""The interactive map, ``map.html``: one self-contained file (plotly, its JavaScript inlined;
nothing is fetched from the network) to zoom, pan and hover over a learned map.

Each state is a node: at the mean position of its steps when the world has positions, else where a
graph layout of the map puts it (:func:`node_positions`).  Hovering over a node shows its id,
symbol (or GDS), visits, ground-truth place(s) when known and its outgoing transitions; compound
states (steps of more than one place) are coloured, as in ``fig_map.png``; the arcs are those with
some ``P(x'|x,u) > output.min_prob``, each with an arrowhead at 70 % of its length.

However many states, the figure is three traces: the arcs (one line, ``None`` between arcs), their
arrowheads and the nodes (one marker each), so that a browser stays responsive at thousands of
states.  Up to :data:`SVG_MAX_STATES` states they are SVG (``scatter``: every node is a
``path.point`` element of the page); beyond, WebGL (``scattergl``, drawn on a canvas).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.data.atomic import atomic_write
from .run import _state_positions, compound_mask

__all__ = ["map_figure", "write_map_html", "node_positions", "SVG_MAX_STATES", "NODE_COLOURS"]

#: most states drawn as SVG markers; larger maps are drawn with WebGL (``scattergl``)
SVG_MAX_STATES = 1000
#: a node's colour by kind: a learned state, a compound state, a state at a GDS (as fig_map.png)
NODE_COLOURS = {"state": "#ffffff", "compound": "#b2abd2", "gds": "gold"}
#: outgoing transitions listed per state on hover (the most probable first)
MAX_HOVER_TRANSITIONS = 12
#: transitions below this probability are not listed on hover
MIN_HOVER_PROB = 0.05


def node_positions(m, labels=None, positions=None, seed: int = 0) -> tuple[np.ndarray, str]:
    """``((S, 2) positions, how)``: each state's mean position where the world gives positions
    (``how`` = ``"mean position"``), else a layout of the map's graph (``"graph layout"``: a
    spring layout seeded by ``seed``, from a spectral one beyond 500 states).  A state without
    steps of its own is placed by the layout too."""
    import networkx as nx

    S = m.n_states
    P = np.full((S, 2), np.nan)
    how = "graph layout"
    if positions is not None and labels is not None:
        P = _state_positions(np.asarray(labels), np.asarray(positions, dtype=float), S)
        how = "mean position"
    missing = ~np.isfinite(P).all(axis=1)
    if missing.any():
        G = nx.Graph(m.to_networkx(min_prob=0.0))
        start = nx.spectral_layout(G) if S > 500 else None
        layout = nx.spring_layout(G, seed=seed, pos=start, iterations=50 if S <= 500 else 20)
        L = np.array([layout[s] for s in range(S)])
        if how == "mean position":  # scale the layout into the room, for the few left over
            lo, hi = np.nanmin(P, axis=0), np.nanmax(P, axis=0)
            L = lo + (L - L.min(axis=0)) / np.maximum(np.ptp(L, axis=0), 1e-12) * (hi - lo)
        P[missing] = L[missing]
    return P, how


def _hover(m, P, C, s: int, visits: int, places) -> str:
    """A node's hover text: id, symbol or GDS, visits, places, outgoing transitions (``P``, ``C``:
    the map's transition probabilities and counts)."""
    if m.state_gds[s] >= 0:
        kind = f"GDS {m.state_label(s)}"
    else:
        kind = f"symbol {int(m.state_symbol[s])}"
    lines = [f"<b>state {s}</b> ({kind})", f"visits: {visits}"]
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


def _places_of(labels, places, S) -> list:
    """Per state, its ground-truth places with their shares of its steps (largest first, those
    of at least 5 %, at most three), or None for a state without steps."""
    out = [None] * S
    if places is None or labels is None:
        return out
    labels, places = np.asarray(labels), np.asarray(places)
    for s in np.unique(labels):
        ps, n = np.unique(places[labels == s], return_counts=True)
        order = np.argsort(-n, kind="stable")
        share = n[order] / n.sum()
        out[int(s)] = [(int(ps[i]), float(f)) for i, f in zip(order, share) if f >= 0.05][:3] \
            or [(int(ps[order[0]]), float(share[0]))]
    return out


def map_figure(m, labels=None, positions=None, places=None, *, min_prob: float = 0.8,
               seed: int = 0):
    """The interactive map as a ``plotly.graph_objects.Figure`` (see the module docstring):
    ``m`` the :class:`~topomap.TopologicalMap`, ``labels`` the state of every step, ``positions``
    and ``places`` the steps' ground truth (either may be None)."""
    import plotly.graph_objects as go

    S = m.n_states
    P, how = node_positions(m, labels, positions, seed)
    G = m.to_networkx(min_prob=min_prob)
    svg = S <= SVG_MAX_STATES
    Scatter = go.Scatter if svg else go.Scattergl
    arcs = [(a, b) for a, b in G.edges if a != b]
    xs = np.full(3 * len(arcs), np.nan)
    ys = np.full(3 * len(arcs), np.nan)
    if arcs:
        ends = np.array(arcs)
        xs[0::3], xs[1::3] = P[ends[:, 0], 0], P[ends[:, 1], 0]
        ys[0::3], ys[1::3] = P[ends[:, 0], 1], P[ends[:, 1], 1]
    to_list = lambda v: [None if np.isnan(x) else float(x) for x in v]  # noqa: E731
    edge_trace = Scatter(x=to_list(xs), y=to_list(ys), mode="lines", hoverinfo="skip",
                         line=dict(color="rgba(80,80,80,0.55)", width=1),
                         name=f"arc: P(x'|x,u) > {min_prob}")
    head = np.empty((len(arcs), 2))
    angle = np.empty(len(arcs))
    if arcs:
        d = P[ends[:, 1]] - P[ends[:, 0]]
        head = P[ends[:, 0]] + 0.7 * d
        angle = np.degrees(np.arctan2(d[:, 0], d[:, 1]))  # clockwise from up, as plotly's
    head_trace = Scatter(x=head[:, 0].tolist(), y=head[:, 1].tolist(), mode="markers",
                         hoverinfo="skip", showlegend=False,
                         marker=dict(symbol="triangle-up", size=7, angle=angle.tolist(),
                                     color="rgba(80,80,80,0.8)"))
    visits = np.asarray(m.state_counts)
    compound = (compound_mask(labels, places, S) if places is not None and labels is not None
                else np.zeros(S, dtype=bool))
    kind = np.where(m.state_gds >= 0, "gds", np.where(compound, "compound", "state"))
    shares = _places_of(labels, places, S)
    probs, counts = m.transition_probs, m.transition_counts  # computed once: (S, A, S)
    text = [_hover(m, probs, counts, s, int(visits[s]), shares[s] if places is not None else None)
            for s in range(S)]
    small, big = (7, 11) if S <= 200 else (3, 6)  # marker diameters in pixels, by visits
    size = small + big * np.sqrt(visits / max(int(visits.max()), 1))
    node_trace = Scatter(
        x=P[:, 0].tolist(), y=P[:, 1].tolist(), mode="markers" + ("+text" if S <= 60 else ""),
        text=[str(s) for s in range(S)] if S <= 60 else None, textfont=dict(size=8),
        hovertext=text, hoverinfo="text", name="state (size: visits)",
        marker=dict(size=size.round(1).tolist(), color=[NODE_COLOURS[k] for k in kind],
                    line=dict(color=["red" if k == "gds" else "black" for k in kind], width=1)))
    n_compound = int((kind == "compound").sum())
    title = (f"learned map: {S} states, {G.number_of_edges()} arcs with P(x'|x,u) > {min_prob}; "
             f"nodes at their {how}" + (f"; {n_compound} compound states (lavender)"
                                        if places is not None else ""))
    fig = go.Figure([edge_trace, head_trace, node_trace])
    fig.update_layout(title=dict(text=title, font=dict(size=13)), dragmode="pan",
                      hovermode="closest", plot_bgcolor="white", template="none",
                      margin=dict(l=20, r=20, t=50, b=20),
                      legend=dict(orientation="h", y=-0.02),
                      xaxis=dict(visible=False), yaxis=dict(visible=False, scaleanchor="x"))
    return fig


def write_map_html(path, m, labels=None, positions=None, places=None, *, min_prob: float = 0.8,
                   seed: int = 0) -> Path:
    """Write :func:`map_figure` as one self-contained HTML file (plotly's JavaScript inlined),
    atomically.  The same map gives the same file."""
    fig = map_figure(m, labels, positions, places, min_prob=min_prob, seed=seed)
    html = fig.to_html(include_plotlyjs=True, full_html=True, div_id="topomap-map",
                       config={"scrollZoom": True, "displaylogo": False, "responsive": True})
    path = Path(path)
    atomic_write(path, lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return path
