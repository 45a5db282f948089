"""Figures of a run, after the paper's Figs. 4-7 (matplotlib, Agg backend, PNG files).

Every ``plot_*`` function draws on the Axes (or Figure) it is given and returns it, so a figure can
be composed and inspected without reading PNG files; :func:`write_figures` writes a run's PNGs.
A state has the same style in every figure (:func:`state_styles`): a colour of :data:`PALETTE`
and, once the palette is used up, the next marker of :data:`MARKERS`.  The style they share with
the sweep figures is in :mod:`topomap.app.plots.style`; the curves (entropies per split, the map's
quality while exploring) are in :mod:`topomap.app.plots.curves`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.progress import report
from .curves import plot_entropy, plot_mapping
from .style import (HALO, LEGEND_SIZE, MAX_MAP_NUMBERS, MAX_STATE_NUMBERS, TITLE_SIZE, pyplot,
                    save_figure, state_styles)

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "compound_mask"]


def _pairs(labels, places, **kw):
    """``np.unique`` of the (state, place) pairs of the steps, as rows ``[state, place]`` (the
    pairs are coded as one integer first: a 1-D unique is many times faster)."""
    labels, places = np.asarray(labels, dtype=np.int64), np.asarray(places, dtype=np.int64)
    base = int(places.max()) - int(places.min()) + 1
    out = np.unique(labels * base + (places - places.min()), **kw)
    codes = out[0] if kw else out
    pairs = np.column_stack([codes // base, codes % base + places.min()])
    return (pairs, *out[1:]) if kw else pairs


def compound_mask(labels, places, n_states: int) -> np.ndarray:
    """Which of ``n_states`` states hold steps of more than one ground-truth place (the strict
    reading of :func:`topomap.core.metrics.compound_states`)."""
    pairs = _pairs(labels, places)
    return np.bincount(pairs[:, 0], minlength=n_states)[:n_states] > 1


#: most observation points a figure draws; longer runs show every k-th step (all steps still
#: count for the state numbers, rings and legend counts)
MAX_POINTS = 20_000


def _drawn(n: int) -> np.ndarray:
    """Mask of the steps a figure draws: all of ``n`` up to :data:`MAX_POINTS`, else every
    ``ceil(n / MAX_POINTS)``-th step."""
    keep = np.zeros(n, dtype=bool)
    keep[::max(1, -(-n // MAX_POINTS))] = True
    return keep


def _jitter(P, seed=0):
    """Spread points that share a position so that their number shows (fixed seed); the spread
    is 0.75 % of the room's extent, well inside the gap between neighbouring places."""
    span = float(np.ptp(P, axis=0).max()) if len(P) else 0.0
    return P + np.random.default_rng(seed).normal(0, 0.0075 * max(span, 1.0), P.shape)


def _room(ax, env, positions, faint=False):
    """The world's room (or bare limits around ``positions``); ``faint`` fades it into a
    background and drops its legend, so that colours are the states'."""
    if env is not None and hasattr(env, "plot_room"):
        env.plot_room(ax, labels=False)
    else:
        ax.set_aspect("equal")
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        pad = 0.05 * (hi - lo).max() + 0.5
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
    if faint:
        for artist in [*ax.patches, *ax.images, *ax.collections, *ax.lines, *ax.texts]:
            artist.set_alpha(0.3)
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    ax.set_xticks([])
    ax.set_yticks([])


def _state_positions(labels, positions, S):
    """``(S, 2)``: the mean position of each state's steps (NaN for a state without steps)."""
    n = np.bincount(labels, minlength=S)[:S].astype(float)
    sums = np.column_stack([np.bincount(labels, positions[:, k], S)[:S] for k in (0, 1)])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n[:, None] > 0, sums / n[:, None], np.nan)


def _data_per_point(ax) -> float:
    """Data units per typographic point along x (the Axes' aspect applied)."""
    ax.apply_aspect()
    x0, x1 = ax.get_xlim()
    return abs(x1 - x0) / max(ax.bbox.width * 72.0 / ax.figure.dpi, 1e-9)


def _close_pairs(Q, d) -> np.ndarray:
    """``(k, 2)`` indices of the points of ``Q`` closer than ``d`` (a sweep along x, so that
    thousands of points cost little)."""
    order = np.argsort(Q[:, 0], kind="stable")
    R = Q[order]
    pairs = [np.empty((0, 2), dtype=int)]
    for k in range(1, len(R)):
        i = np.flatnonzero(R[k:, 0] - R[:-k, 0] < d)
        if not i.size:
            break
        near = np.hypot(*(R[i + k] - R[i]).T) < d
        pairs.append(np.column_stack([order[i[near]], order[i[near] + k]]))
    return np.concatenate(pairs)


def _spread(P, d, iters=40):
    """``P`` with points closer than ``d`` pushed apart (deterministic; coincident points leave in
    fixed directions), so that numbers or nodes at one position stay readable."""
    angle = np.arange(len(P)) * 2.399963  # the golden angle: a different direction for each point
    Q = P + 1e-3 * d * np.column_stack([np.cos(angle), np.sin(angle)])
    for _ in range(iters):
        pairs = _close_pairs(Q, d)
        if not len(pairs):
            break
        diff = Q[pairs[:, 0]] - Q[pairs[:, 1]]
        dist = np.hypot(*diff.T)[:, None]
        push = diff / np.maximum(dist, 1e-12) * (d - dist) / 2
        np.add.at(Q, pairs[:, 0], push)
        np.add.at(Q, pairs[:, 1], -push)
    return Q


def _numbers(ax, P, states, fontsize):
    """Write each state's number at its point of ``P`` in bold with a white outline (points too
    close for two numbers are spread apart first)."""
    import matplotlib.patheffects as pe

    halo = [pe.withStroke(linewidth=HALO, foreground="white")]
    Q = _spread(P, 1.4 * fontsize * _data_per_point(ax)) if len(P) > 1 else P
    for s, (x, y) in zip(states, Q):
        ax.text(x, y, str(s), ha="center", va="center", fontsize=fontsize, zorder=6,
                fontweight="bold", path_effects=halo, clip_on=True)


def _spots(labels, positions, places, S, min_share=0.1):
    """Where the states figure numbers each state: ``(states, points, compound)``.

    A state of one true place (or any state when ``places`` is None) is numbered once, at its
    mean position; a compound state at the mean position of each of its places that holds at least
    ``min_share`` of its steps (its main place at least), so that its number sits on each of its
    point clouds rather than between them.
    """
    if places is None:
        means = _state_positions(labels, positions, S)
        states = np.flatnonzero(np.isfinite(means).all(axis=1))
        return states, means[states], np.zeros(len(states), dtype=bool)
    pairs, inverse, counts = _pairs(labels, places, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.column_stack([np.bincount(inverse, positions[:, k], len(pairs)) for k in (0, 1)])
    state = pairs[:, 0]
    total = np.bincount(state, counts, S)
    main = np.zeros(len(pairs), dtype=bool)
    order = np.lexsort((-counts, state))  # each state's biggest place first
    main[order[np.r_[True, state[order][1:] != state[order][:-1]]]] = True
    keep = main | (counts >= min_share * total[state])
    compound = compound_mask(labels, places, S)
    return state[keep], sums[keep] / counts[keep, None], compound[state[keep]]


def plot_states(ax, traj, labels, env=None, title=""):
    """Observation points (jittered positions) in the style of their state, with each state's
    number at its mean position; a compound state (steps of more than one ground-truth place) is
    ringed and numbered at each of its places (see :func:`_spots`).  Numbers and rings are left
    out beyond :data:`MAX_STATE_NUMBERS` numbers.  Returns ``ax``."""
    labels = np.asarray(labels)
    S = int(labels.max()) + 1
    _room(ax, env, traj.positions, faint=True)
    P = _jitter(traj.positions)
    styles = state_styles(S)
    colours = np.array([c for c, _ in styles])
    keep = _drawn(labels.size)
    for marker in dict.fromkeys(m for _, m in styles):
        sel = keep & np.isin(labels, [s for s in range(S) if styles[s][1] == marker])
        ax.scatter(P[sel, 0], P[sel, 1], c=colours[labels[sel]], marker=marker, s=9, lw=0,
                   alpha=0.85, zorder=3)
    states, spots, ringed = _spots(labels, traj.positions, traj.places, S)
    title = title or f"observation points by state ({S} states)"
    if not keep.all():
        title += f" (every {labels.size // keep.sum()}th step drawn)"
    if len(states) > MAX_STATE_NUMBERS:
        ax.set_title(f"{title}\n(numbers and compound-state rings left out: {len(states)} numbers "
                     "would not be legible)", fontsize=TITLE_SIZE)
        return ax
    size = 6.5 if len(states) <= 60 else 5.5  # of the numbers, points
    if traj.places is not None:
        n = len(np.unique(states[ringed]))
        ax.scatter(spots[ringed, 0], spots[ringed, 1], s=(2.1 * size) ** 2, facecolors="none",
                   edgecolors="black", lw=1.2, zorder=5,
                   label=f"compound state ({n}): steps of more than one true place, "
                         "numbered at each")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), fontsize=LEGEND_SIZE,
                  frameon=False, handletextpad=0.3)
    _numbers(ax, spots, states, fontsize=size)
    ax.set_title(title, fontsize=TITLE_SIZE)
    return ax


def _table(ax, m, s, title):
    """P(x'|x=s, u) for the actions state ``s`` took, as a text table."""
    P = m.transition_probs[s]
    C = m.transition_counts[s]
    rows = []
    for a in np.flatnonzero(C.sum(axis=1)):
        nxt = np.flatnonzero(C[a])
        order = nxt[np.argsort(-P[a, nxt], kind="stable")]
        name = m.action_names[a] if m.action_names else str(a)
        rows.append([name[:22], ", ".join(f"{m.state_label(y)}:{P[a, y]:.2f}" for y in order[:4])])
    ax.axis("off")
    ax.set_title(title, fontsize=TITLE_SIZE)
    if rows:
        tab = ax.table(cellText=rows, colLabels=["u", "P(x'|x,u)"], loc="upper center",
                       cellLoc="left", colWidths=[0.4, 0.6])
        tab.auto_set_font_size(False)
        tab.set_fontsize(6)
        tab.scale(1, 1.1)


def _clouds(ax, traj, P, labels, sel, names):
    """The steps ``sel`` at their jittered positions ``P`` in the style of their state of
    ``labels``, numbered at each of their places (as in :func:`plot_states`); one legend entry
    per state, named by ``names``."""
    shown = np.unique(labels[sel])
    styles = state_styles(int(shown.max()) + 1)
    keep = _drawn(labels.size)
    for s in shown:
        pick = sel & (labels == s)
        ax.scatter(P[pick & keep, 0], P[pick & keep, 1], s=14, color=styles[s][0],
                   marker=styles[s][1], lw=0, zorder=3, label=f"{names(s)} ({pick.sum()})")
    places = None if traj.places is None else traj.places[sel]
    states, spots, _ = _spots(labels[sel], traj.positions[sel], places, int(shown.max()) + 1)
    _numbers(ax, spots, states, fontsize=7)
    ax.legend(fontsize=LEGEND_SIZE, loc="upper center", bbox_to_anchor=(0.5, 0.0), frameon=False,
              ncol=min(len(shown), 6), markerscale=1.5, title="state (steps)",
              title_fontsize=LEGEND_SIZE, columnspacing=1.0, handletextpad=0.2)


def _split_stage(learner):
    """``(labels, map)`` right after splitting: ``labels_split_`` and ``map_split_`` when the
    learner refined its map afterwards, else its final ``labels_`` and ``map_``."""
    if _refined(learner):
        return learner.labels_split_, learner.map_split_
    return learner.labels_, learner.map_


def _refined(learner) -> bool:
    """Whether the learner's final map is a refinement of its split map (``refine``, kept)."""
    split = getattr(learner, "map_split_", None)
    return split is not None and learner.map_ is not split


def _table_rows(m, s) -> int:
    """The rows of the transition table of state ``s`` of map ``m`` (the actions it took)."""
    return int(np.count_nonzero(m.transition_counts[s].sum(axis=1)))


def plot_split(fig, traj, learner, env=None, state=None):
    """A compound phase-1 state (left) and the states the split made of it (right), each in its
    style of :func:`plot_states`, with their transition tables below (the split, not a later
    refinement: :func:`_split_stage`).  The tables' row is as tall as the longest table needs.
    Returns False when nothing split."""
    hist = learner.split_history_
    if state is None:
        if not hist:
            return False
        state = hist[0]["state"]
    m0 = learner.map_phase1_
    labels1, m1 = _split_stage(learner)
    if not 0 <= state < m0.n_states:
        raise ValueError(f"output.compound_state={state} is not a phase-1 state (0..{m0.n_states - 1})")
    sel = learner.labels_phase1_ == state
    after = np.unique(labels1[sel])
    rows = max([_table_rows(m0, state)] + [_table_rows(m1, s) for s in after[:2]])
    width, height = fig.get_size_inches()
    table_height = 0.45 + 0.2 * (rows + 1)  # inches: a title, the header and the rows
    fig.set_size_inches(width, height * 3 / 4.4 + table_height)
    grid = fig.add_gridspec(2, 6, height_ratios=[height * 3 / 4.4, table_height], hspace=0.5)
    top = [fig.add_subplot(grid[0, :3]), fig.add_subplot(grid[0, 3:])]
    P = _jitter(traj.positions)
    for ax, labels, m in zip(top, (learner.labels_phase1_, labels1), (m0, m1)):
        _room(ax, env, traj.positions, faint=True)
        _clouds(ax, traj, P, labels, sel, m.state_label)
    top[0].set_title(f"state {state} after clustering ({sel.sum()} steps)", fontsize=TITLE_SIZE)
    top[1].set_title(f"after splitting: states {', '.join(map(str, after))}", fontsize=TITLE_SIZE)
    _table(fig.add_subplot(grid[1, :2]), m0, state, f"P(x'|x={state}, u) before")
    for k, s in enumerate(after[:2]):
        _table(fig.add_subplot(grid[1, 2 + 2 * k:4 + 2 * k]), m1, s, f"P(x'|x={s}, u) after")
    return True


def _arcs(ax, G, pos, diameter):
    """Draw the map's arcs as thin grey curves that bend to the right of their direction (so the
    arcs x -> x' and x' -> x stay apart), ending at the nodes' rims (``diameter`` points) in an
    arrowhead; a self-loop is a small circle above its node.  Two collections, so that maps
    of thousands of arcs draw quickly."""
    from matplotlib.collections import LineCollection, PolyCollection

    unit = _data_per_point(ax)
    edges = np.array([(a, b) for a, b in G.edges if a != b], dtype=int).reshape(-1, 2)
    loops = [a for a, b in G.edges if a == b]
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
    circle = 3.0 * unit * np.column_stack([np.cos(angle), np.sin(angle) + 1.0])
    circles = [pos[a] + (0.5 * diameter * unit) * np.array([0, 1]) + circle for a in loops]
    ax.add_collection(LineCollection([*curves, *circles], colors="0.3", linewidths=0.6,
                                     alpha=0.6, zorder=2), autolim=False)
    ax.add_collection(PolyCollection(heads, facecolors="0.3", edgecolors="none", alpha=0.7,
                                     zorder=2), autolim=False)


#: how the map draws a plain, a compound and a GDS state: (fill, edge, area factor, legend)
_NODE_KINDS = (("white", "black", 1.0, "learned state"),
               ("#b2abd2", "black", 1.0, "compound state (steps of more than one true place)"),
               ("gold", "red", 1.3, "state at a GDS"))


def _nodes(ax, P, states, kinds, diameter, numbered):
    """The map's states at ``P`` in the style of their kind (0 plain, 1 compound, 2 GDS), with
    their numbers when ``numbered``."""
    for k, (face, edge, area, label) in enumerate(_NODE_KINDS):
        pick = kinds == k
        if pick.any():
            ax.scatter(P[pick, 0], P[pick, 1], s=area * diameter ** 2, c=face, edgecolors=edge,
                       lw=0.8, zorder=4, label=label)
    if numbered:
        for s, (x, y) in zip(states, P):
            ax.text(x, y, str(s), ha="center", va="center", fontsize=5.5, zorder=5)


def plot_map(ax, traj, learner, env=None, min_prob=0.8):
    """The learned map at the states' mean positions, arcs where some P(x'|x,u) > min_prob;
    numbered nodes (spread apart where they coincide) up to :data:`MAX_MAP_NUMBERS` states, small
    dots beyond; compound states lavender (when the ground truth is known), GDS states gold.  One legend
    beside the map: the room's entries (if any), then the nodes'.  Returns ``ax``."""
    m = learner.map_
    G = m.to_networkx(min_prob=min_prob)
    means = _state_positions(learner.labels_, traj.positions, m.n_states)
    _room(ax, env, traj.positions)
    room_legend = ax.get_legend()
    keep = np.array([s for s in G.nodes if np.isfinite(means[s]).all()], dtype=int)
    G = G.subgraph(keep.tolist())
    numbered = len(keep) <= MAX_MAP_NUMBERS
    diameter = 11.0 if numbered else 4.0  # points
    P = _spread(means[keep], 1.1 * diameter * _data_per_point(ax)) if numbered else means[keep]
    _arcs(ax, G, dict(zip(keep.tolist(), P)), diameter)
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
    ax.set_title(f"learned map: {m.n_states} states, {G.number_of_edges()} arcs with "
                 f"P(x'|x,u) > {min_prob}" + ("" if numbered else "; numbers omitted"),
                 fontsize=TITLE_SIZE)
    return ax


def write_figures(out: Path, traj, learner, env=None, *, min_prob=0.8, compound_state=None):
    """Write the figures of :data:`topomap.app.results.FIGURE_FILES` that the data allows
    (the room figures need ground-truth positions); the drawing's progress is reported as
    ``"drawing figures"`` (:mod:`topomap.core.progress`)."""
    plt = pyplot()
    out = Path(out)
    written = []
    curve = ((traj.meta or {}).get("mapping") or {}).get("curve")
    total = (3 if traj.positions is not None else 0) + 1 + bool(curve)
    done = 0

    def drawn(fig, name):
        nonlocal done
        if fig is not None:
            save_figure(fig, out / name)
            written.append(name)
        done += 1
        report("drawing figures", done, total)

    report("drawing figures", 0, total)
    if traj.positions is not None:
        refined = _refined(learner)
        fig, axes = plt.subplots(1, 3 if refined else 2, figsize=(18 if refined else 12, 4.9))
        plot_states(axes[0], traj, learner.labels_phase1_, env,
                    f"after clustering: {learner.map_phase1_.n_states} states")
        split_labels, split_map = _split_stage(learner)
        plot_states(axes[1], traj, split_labels, env,
                    f"after splitting: {split_map.n_states} states")
        if refined:
            plot_states(axes[2], traj, learner.labels_, env,
                        f"after the refinement: {learner.map_.n_states} states")
        drawn(fig, "fig_states.png")
        fig = plt.figure(figsize=(13, 6.6))
        if not plot_split(fig, traj, learner, env, compound_state):
            plt.close(fig)
            fig = None
        drawn(fig, "fig_split.png")
        fig, ax = plt.subplots(figsize=(8, 6))
        plot_map(ax, traj, learner, env, min_prob)
        drawn(fig, "fig_map.png")
    fig, ax = plt.subplots(figsize=(6.5, 3.5))
    plot_entropy(ax, learner)
    drawn(fig, "fig_entropy.png")
    if curve:
        fig, ax = plt.subplots(figsize=(5, 3.5))
        plot_mapping(ax, curve, traj.meta["mapping"].get("explorer", ""))
        drawn(fig, "fig_mapping.png")
    return written

