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
from .common import compound_mask, continuous, drawn, jitter, pairs, room
from .common import state_positions as _state_positions
from .curves import plot_entropy, plot_mapping
from .graph import plot_map
from .labels import write_numbers
from .path import plot_path
from .style import LEGEND_SIZE, MAX_STATE_NUMBERS, TITLE_SIZE, pyplot, save_figure, state_styles

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "plot_path",
           "compound_mask"]


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
    rows, inverse, counts = pairs(labels, places, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    sums = np.column_stack([np.bincount(inverse, positions[:, k], len(rows)) for k in (0, 1)])
    state = rows[:, 0]
    total = np.bincount(state, counts, S)
    main = np.zeros(len(rows), dtype=bool)
    order = np.lexsort((-counts, state))  # each state's biggest place first
    main[order[np.r_[True, state[order][1:] != state[order][:-1]]]] = True
    keep = main | (counts >= min_share * total[state])
    compound = compound_mask(labels, places, S)
    return state[keep], sums[keep] / counts[keep, None], compound[state[keep]]


def _ordinal(k: int) -> str:
    """``1st``, ``2nd``, ``3rd``, ``4th``, ..., ``11th``, ``12th``, ``13th``, ``21st``, ..."""
    suffix = "th" if 10 <= k % 100 <= 13 else {1: "st", 2: "nd", 3: "rd"}.get(k % 10, "th")
    return f"{k}{suffix}"


def plot_states(ax, traj, labels, env=None, title=""):
    """Observation points (at their positions, jittered where places share them) in the style of
    their state, with each state's number at its mean position; a compound state (steps of more
    than one ground-truth place) is ringed and numbered at each of its places (see
    :func:`_spots`).  Numbers and rings are left
    out beyond :data:`MAX_STATE_NUMBERS` numbers.  Returns ``ax``."""
    labels = np.asarray(labels)
    S = int(labels.max()) + 1
    room(ax, env, traj.positions, faint=True)
    P = traj.positions if continuous(traj) else jitter(traj.positions)
    styles = state_styles(S)
    colours = np.array([c for c, _ in styles])
    keep = drawn(labels.size)
    for marker in dict.fromkeys(m for _, m in styles):
        sel = keep & np.isin(labels, [s for s in range(S) if styles[s][1] == marker])
        ax.scatter(P[sel, 0], P[sel, 1], c=colours[labels[sel]], marker=marker, s=9, lw=0,
                   alpha=0.85, zorder=3)
    states, spots, ringed = _spots(labels, traj.positions, traj.places, S)
    title = title or f"observation points by state ({S} states)"
    if not keep.all():
        title += f" (every {_ordinal(labels.size // keep.sum())} step drawn)"
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
    write_numbers(ax, spots, states, fontsize=size)
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
    keep = drawn(labels.size)
    for s in shown:
        pick = sel & (labels == s)
        ax.scatter(P[pick & keep, 0], P[pick & keep, 1], s=14, color=styles[s][0],
                   marker=styles[s][1], lw=0, zorder=3, label=f"{names(s)} ({pick.sum()})")
    places = None if traj.places is None else traj.places[sel]
    states, spots, _ = _spots(labels[sel], traj.positions[sel], places, int(shown.max()) + 1)
    write_numbers(ax, spots, states, fontsize=7)
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
    """Whether the learner's final map replaced its split map: a refinement (``refine``,
    kept), or the places or view clusters of a continuous log (:func:`final_stage`)."""
    split = getattr(learner, "map_split_", None)
    return split is not None and learner.map_ is not split


def final_stage(learner) -> str:
    """What the learner's final map is when it replaced the split map: ``"the places (views and
    motion)"`` or ``"the view clusters"`` for a continuous log (``motion_info_["chosen"]``),
    ``"after the refinement"`` otherwise."""
    chosen = (getattr(learner, "motion_info_", None) or {}).get("chosen")
    if chosen == "places":
        return "the places (views and motion), in place of the split"
    if chosen == "views":
        return "the view clusters, in place of the split (the places lost the check)"
    return "after the refinement"


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
    P = traj.positions if continuous(traj) else jitter(traj.positions)
    for ax, labels, m in zip(top, (learner.labels_phase1_, labels1), (m0, m1)):
        room(ax, env, traj.positions, faint=True)
        _clouds(ax, traj, P, labels, sel, m.state_label)
    top[0].set_title(f"state {state} after clustering ({sel.sum()} steps)", fontsize=TITLE_SIZE)
    top[1].set_title(f"after splitting: states {', '.join(map(str, after))}", fontsize=TITLE_SIZE)
    _table(fig.add_subplot(grid[1, :2]), m0, state, f"P(x'|x={state}, u) before")
    for k, s in enumerate(after[:2]):
        _table(fig.add_subplot(grid[1, 2 + 2 * k:4 + 2 * k]), m1, s, f"P(x'|x={s}, u) after")
    return True


def _aspect(traj, env) -> float:
    """Height over width of what a room figure shows: the world's room, else the positions."""
    layout = getattr(env, "layout", None)
    if hasattr(layout, "extent"):
        x0, x1, y0, y1 = layout.extent
    else:
        (x0, y0), (x1, y1) = traj.positions[:, :2].min(axis=0), traj.positions[:, :2].max(axis=0)
    return float(np.clip((y1 - y0) / max(x1 - x0, 1e-9), 0.35, 1.5))


def _room_figures(plt, traj, learner, env, compound_state):
    """``(name, figure or None)`` of the figures over the room: the states, a split, the path."""
    refined = _refined(learner)
    n, aspect = 2 + refined, _aspect(traj, env) if continuous(traj) else None
    if aspect is not None and aspect < 0.6:  # a wide floor plan: the panels one above another
        fig, axes = plt.subplots(n, 1, figsize=(11, n * (10 * aspect + 0.9)))
    else:
        fig, axes = plt.subplots(1, n, figsize=(6 * n, 4.9))
    plot_states(axes[0], traj, learner.labels_phase1_, env,
                f"after clustering: {learner.map_phase1_.n_states} states")
    split_labels, split_map = _split_stage(learner)
    plot_states(axes[1], traj, split_labels, env, f"after splitting: {split_map.n_states} states")
    if refined:
        plot_states(axes[2], traj, learner.labels_, env,
                    f"{final_stage(learner)}: {learner.map_.n_states} states")
    yield "fig_states.png", fig
    top = 4.5 if aspect is None else 6.0 * min(aspect, 0.75) + 1.1  # inches above the tables
    fig = plt.figure(figsize=(13, top * 4.4 / 3))
    if not plot_split(fig, traj, learner, env, compound_state):
        plt.close(fig)
        fig = None
    yield "fig_split.png", fig
    if continuous(traj):
        fig, ax = plt.subplots(figsize=(8, 1.2 + 6.4 * _aspect(traj, env)))
        plot_path(ax, traj, env)
        yield "fig_path.png", fig


def write_figures(out: Path, traj, learner, env=None, *, min_prob=0.8, compound_state=None,
                  seed=0):
    """Write the figures of :data:`topomap.app.results.FIGURE_FILES` that the data allows: the
    states and a split need positions, the path continuous positions (no places); the map is
    drawn at a graph layout (seeded by ``seed``) where the steps have no positions.  The
    drawing's progress is reported as ``"drawing figures"`` (:mod:`topomap.core.progress`)."""
    plt = pyplot()
    out = Path(out)
    curve = ((traj.meta or {}).get("mapping") or {}).get("curve")
    total = (2 + continuous(traj) if traj.positions is not None else 0) + 2 + bool(curve)
    written, tried = [], []

    def save(name, fig):
        if fig is not None:
            save_figure(fig, out / name)
            written.append(name)
        tried.append(name)
        report("drawing figures", len(tried), total)

    report("drawing figures", 0, total)
    if traj.positions is not None:
        for name, fig in _room_figures(plt, traj, learner, env, compound_state):
            save(name, fig)
    tall = 1.0 + 6.0 * _aspect(traj, env) if continuous(traj) else 6.0
    fig, ax = plt.subplots(figsize=(8, min(max(tall, 3.5), 7.0)))
    plot_map(ax, traj, learner, env, min_prob, seed=seed)
    save("fig_map.png", fig)
    fig, ax = plt.subplots(figsize=(6.5, 3.5))
    plot_entropy(ax, learner)
    save("fig_entropy.png", fig)
    if curve:
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        mapping = traj.meta["mapping"]
        plot_mapping(ax, curve, mapping.get("component") or mapping.get("explorer", ""))
        save("fig_mapping.png", fig)
    return written
