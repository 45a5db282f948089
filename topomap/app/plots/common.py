"""What the run's figures share: the room under a figure, where the states sit (the mean position
of their steps, or a layout of the map's graph when the steps have no positions), which steps a
figure draws, and which states are compound (hold steps of more than one true place).

The static figures (:mod:`.run`, :mod:`.graph`, :mod:`.path`) and the interactive map
(:mod:`.interactive`) put a state in the same place.
"""

from __future__ import annotations

import numpy as np

__all__ = ["room", "state_positions", "node_positions", "compound_mask", "pairs", "drawn",
           "jitter", "continuous", "map_arcs", "Arcs", "MAX_POINTS", "STAYING",
           "MIN_LEAVING_SHARE"]

#: most observation points a figure draws; longer runs show every k-th step (all steps still
#: count for the state numbers, rings and legend counts)
MAX_POINTS = 20_000


#: a map whose steps stay in their state more often than this (a log sampled faster than it
#: moves between places: the arena's rat stays in one of 64 places for 90-97 % of its 10 Hz
#: steps) draws the moves between states rather than its transitions above ``min_prob``, which
#: are then nearly all self-loops
STAYING = 0.5
#: an arc of such a map joins x to x' when at least this share of the moves that leave x go to
#: x': a place among places tiling the floor has about six neighbours (a share of 1/6 each),
#: and rarer moves are the noise of view-aliased states
MIN_LEAVING_SHARE = 0.1


class Arcs:
    """The arcs a map figure draws: ``between`` (pairs ``(x, x')``, ``x != x'``), ``loops``
    (the states with a self-loop drawn), ``rule`` (what an arc means, for the title), ``legend``
    (the same, short) and ``staying`` (the share of steps that stay in their state)."""

    def __init__(self, between, loops, rule, staying, legend):
        self.between, self.loops, self.rule, self.staying = between, loops, rule, staying
        self.legend = legend

    def title(self, n_states: int) -> str:
        """``64 states, 3 arcs and 61 self-loops with P(x'|x,u) > 0.8`` (or the moves' rule)."""
        n = len(self.loops)
        loops = f" and {n} self-loop{'s' if n != 1 else ''}" if n else ""
        return f"{n_states} states, {len(self.between)} arcs{loops} {self.rule}"


def map_arcs(m, min_prob: float) -> Arcs:
    """The arcs of the map ``m``: where some ``P(x'|x,u) > min_prob`` (self-loops apart); or,
    when its steps stay in their state more than :data:`STAYING` of the time, the moves
    between states: ``x -> x'`` where at least :data:`MIN_LEAVING_SHARE` of the moves leaving
    ``x`` go (no self-loops: staying is what such a map does)."""
    C = np.asarray(m.transition_counts, dtype=np.float64).sum(axis=1)  # (S, S) over actions
    total = C.sum()
    staying = float(np.trace(C) / total) if total else 0.0
    if staying > STAYING:
        leave = C - np.diag(np.diag(C))
        share = leave / np.maximum(leave.sum(axis=1, keepdims=True), 1.0)
        between = [(int(a), int(b)) for a, b in zip(*np.nonzero(share >= MIN_LEAVING_SHARE))]
        rule = (f"where >= {MIN_LEAVING_SHARE:.0%} of the moves out of a state go "
                f"(steps stay in their state {staying:.0%} of the time)")
        return Arcs(between, [], rule, staying,
                    f"arc: >= {MIN_LEAVING_SHARE:.0%} of the moves out of a state")
    G = m.to_networkx(min_prob=min_prob)
    between = [(a, b) for a, b in G.edges if a != b]
    loops = [a for a, b in G.edges if a == b]
    return Arcs(between, loops, f"with P(x'|x,u) > {min_prob}", staying,
                f"arc: P(x'|x,u) > {min_prob}")


def pairs(labels, places, **kw):
    """``np.unique`` of the (state, place) pairs of the steps, as rows ``[state, place]`` (the
    pairs are coded as one integer first: a 1-D unique is many times faster)."""
    labels, places = np.asarray(labels, dtype=np.int64), np.asarray(places, dtype=np.int64)
    base = int(places.max()) - int(places.min()) + 1
    out = np.unique(labels * base + (places - places.min()), **kw)
    codes = out[0] if kw else out
    rows = np.column_stack([codes // base, codes % base + places.min()])
    return (rows, *out[1:]) if kw else rows


def compound_mask(labels, places, n_states: int) -> np.ndarray:
    """Which of ``n_states`` states hold steps of more than one ground-truth place (the strict
    reading of :func:`topomap.metrics.compound_states`)."""
    rows = pairs(labels, places)
    return np.bincount(rows[:, 0], minlength=n_states)[:n_states] > 1


def continuous(traj) -> bool:
    """Whether the steps have positions but no discrete places (the arena, a robot's log): their
    path is worth drawing, and their map is judged in metres."""
    return traj.positions is not None and traj.places is None


def drawn(n: int) -> np.ndarray:
    """Mask of the steps a figure draws: all of ``n`` up to :data:`MAX_POINTS`, else every
    ``ceil(n / MAX_POINTS)``-th step."""
    keep = np.zeros(n, dtype=bool)
    keep[::max(1, -(-n // MAX_POINTS))] = True
    return keep


def jitter(P, seed=0):
    """Spread points that share a position so that their number shows (fixed seed); the spread
    is 0.75 % of the room's extent, well inside the gap between neighbouring places."""
    span = float(np.ptp(P, axis=0).max()) if len(P) else 0.0
    return P + np.random.default_rng(seed).normal(0, 0.0075 * max(span, 1.0), P.shape)


def room(ax, env, positions, faint=False):
    """The world's room (or bare limits around ``positions``, a margin of 5 % of their extent);
    ``faint`` fades it into a background and drops its legend, so that colours are the
    states'."""
    if env is not None and hasattr(env, "plot_room"):
        env.plot_room(ax, labels=False)
    else:
        ax.set_aspect("equal")
        lo, hi = positions[:, :2].min(axis=0), positions[:, :2].max(axis=0)
        pad = 0.05 * max(float((hi - lo).max()), 1e-9)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
    if faint:
        for artist in [*ax.patches, *ax.images, *ax.collections, *ax.lines, *ax.texts]:
            artist.set_alpha(0.3)
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    ax.set_xticks([])
    ax.set_yticks([])


def state_positions(labels, positions, S):
    """``(S, 2)``: the mean position of each state's steps (NaN for a state without steps)."""
    labels = np.asarray(labels)
    n = np.bincount(labels, minlength=S)[:S].astype(float)
    sums = np.column_stack([np.bincount(labels, positions[:, k], S)[:S] for k in (0, 1)])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n[:, None] > 0, sums / n[:, None], np.nan)


#: a map whose states' steps lie, in the median state, farther than this share of the floor's
#: diagonal from their state's mean position is no map of places (an egocentric robot's view
#: clusters): its nodes are drawn at a layout of its graph, not in a clump at the floor's middle.
#: The arena's places lie 0.03 of the diagonal from their means (``topomap
#: experiment=arena_two_rooms``, seed 0), an egocentric robot's view clusters 0.13
#: (``experiment=arena_robot``, 60 beams) to 0.20 (12 beams); a discrete world's states 0
#: (the median state holds one place).  Steps with discrete places keep their mean positions
SCATTERED = 0.1


def scatter_of_states(labels, positions, means) -> float:
    """The median over states of the median distance of a state's steps from its mean position,
    as a share of the diagonal of the positions' extent."""
    labels, positions = np.asarray(labels), np.asarray(positions, dtype=float)[:, :2]
    d = np.hypot(*(positions - means[labels, :2]).T)
    order = np.argsort(labels, kind="stable")
    bounds = np.flatnonzero(np.diff(labels[order])) + 1
    per_state = [np.median(g) for g in np.split(d[order], bounds) if g.size]
    diagonal = float(np.hypot(*np.ptp(positions, axis=0))) or 1.0
    return float(np.median(per_state)) / diagonal if per_state else 0.0


def node_positions(m, labels=None, positions=None, seed: int = 0,
                   places=None) -> tuple[np.ndarray, str]:
    """``((S, 2) positions, how)``: each state's mean position where the steps have positions
    (``how`` = ``"mean position"``), else -- or when the steps have no discrete ``places`` and
    the states' steps scatter over the floor (:data:`SCATTERED`) -- a layout of the map's graph (``how`` starts ``"graph layout"``: a
    spring layout seeded by ``seed``, from a spectral one beyond 500 states).  A state without
    steps of its own is placed by the layout too."""
    import networkx as nx

    S = m.n_states
    P = np.full((S, 2), np.nan)
    how = "graph layout"
    if positions is not None and labels is not None:
        P = state_positions(np.asarray(labels), np.asarray(positions, dtype=float), S)
        how = "mean position"
        spread = 0.0 if places is not None else scatter_of_states(labels, positions, P)
        if spread > SCATTERED:
            P = np.full((S, 2), np.nan)
            how = (f"graph layout: the states' steps scatter over the floor ({spread:.0%} of "
                   "its diagonal from their mean, in the median state)")
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
