"""Figures of a run, after the paper's Figs. 4-7 (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.files import atomic_write

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "plot_entropy"]


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _colours(n):
    plt = _plt()
    cmap = plt.get_cmap("tab20" if n <= 20 else "gist_ncar", max(n, 1))
    return [cmap(i % cmap.N) for i in range(n)]


def _jitter(P, scale=0.15, seed=0):
    """Spread points that share a position so that their number shows (fixed seed)."""
    return P + np.random.default_rng(seed).normal(0, scale, P.shape)


def _room(ax, world, positions):
    if world is not None and hasattr(world, "plot_room"):
        world.plot_room(ax, labels=False)
    else:
        ax.set_aspect("equal")
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        pad = 0.05 * (hi - lo).max() + 0.5
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_xticks([])
    ax.set_yticks([])


def _state_positions(labels, positions, S):
    P = np.full((S, 2), np.nan)
    for s in range(S):
        sel = labels == s
        if sel.any():
            P[s] = positions[sel].mean(axis=0)
    return P


def plot_states(ax, traj, labels, world=None, title=""):
    """Observation points (jittered positions) coloured by state."""
    S = int(labels.max()) + 1
    _room(ax, world, traj.positions)
    P = _jitter(traj.positions)
    cols = np.array(_colours(S))
    ax.scatter(P[:, 0], P[:, 1], c=cols[labels], s=6, lw=0, alpha=0.8, zorder=3)
    ax.set_title(title or f"observation points by state ({S} states)", fontsize=9)


def _table(ax, m, s, title):
    """P(x'|x=s, u) for the actions state ``s`` took, as a text table."""
    P = m.transition_probs_[s]
    C = m.transition_counts_[s]
    rows = []
    for a in np.flatnonzero(C.sum(axis=1)):
        nxt = np.flatnonzero(C[a])
        order = nxt[np.argsort(-P[a, nxt], kind="stable")]
        name = m.action_names[a] if m.action_names else str(a)
        rows.append([name[:22], ", ".join(f"{m.state_label(y)}:{P[a, y]:.2f}" for y in order[:4])])
    ax.axis("off")
    ax.set_title(title, fontsize=9)
    if rows:
        tab = ax.table(cellText=rows, colLabels=["u", "P(x'|x,u)"], loc="upper center",
                       cellLoc="left", colWidths=[0.4, 0.6])
        tab.auto_set_font_size(False)
        tab.set_fontsize(6)
        tab.scale(1, 1.1)


def plot_split(fig, traj, learner, world=None, state=None):
    """A compound phase-1 state (left column) and the states it became (right column)."""
    hist = learner.split_history_
    if state is None:
        if not hist:
            return False
        state = hist[0]["state"]
    m0, m1 = learner.map_phase1_, learner.map_
    if not 0 <= state < m0.n_states:
        raise ValueError(f"output.compound_state={state} is not a phase-1 state (0..{m0.n_states - 1})")
    sel = learner.labels_phase1_ == state
    after = np.unique(learner.labels_[sel])
    grid = fig.add_gridspec(2, 6, height_ratios=[3, 2])
    top = [fig.add_subplot(grid[0, :3]), fig.add_subplot(grid[0, 3:])]
    for ax in top:
        _room(ax, world, traj.positions)
    P = _jitter(traj.positions)
    top[0].scatter(P[sel, 0], P[sel, 1], s=8, c="tab:blue", zorder=3)
    top[0].set_title(f"state {state} after clustering ({sel.sum()} steps)", fontsize=9)
    cols = _colours(max(len(after), 2))
    for k, s in enumerate(after):
        pick = sel & (learner.labels_ == s)
        top[1].scatter(P[pick, 0], P[pick, 1], s=8, color=cols[k], zorder=3,
                       label=f"{m1.state_label(s)} ({pick.sum()})")
    top[1].legend(fontsize=6, loc="upper right")
    top[1].set_title(f"after splitting: states {', '.join(map(str, after))}", fontsize=9)
    _table(fig.add_subplot(grid[1, :2]), m0, state, f"P(x'|x={state}, u) before")
    for k, s in enumerate(after[:2]):
        _table(fig.add_subplot(grid[1, 2 + 2 * k:4 + 2 * k]), m1, s, f"P(x'|x={s}, u) after")
    return True


def plot_map(ax, traj, learner, world=None, min_prob=0.8):
    """The learned map at the states' mean positions; arcs where some P(x'|x,u) > min_prob."""
    import networkx as nx

    m = learner.map_
    G = m.to_networkx(min_prob=min_prob)
    pos_arr = _state_positions(learner.labels_, traj.positions, m.n_states)
    pos = {s: pos_arr[s] for s in G.nodes if np.isfinite(pos_arr[s]).all()}
    G = G.subgraph(pos)
    _room(ax, world, traj.positions)
    gds = [s for s in G.nodes if m.state_gds_[s] >= 0]
    nx.draw_networkx_edges(G, pos, ax=ax, arrowsize=7, width=0.8, alpha=0.7,
                           connectionstyle="arc3,rad=0.1", node_size=120)
    nx.draw_networkx_nodes(G, pos, ax=ax, node_size=120, node_color="white", edgecolors="black")
    nx.draw_networkx_nodes(G, pos, nodelist=gds, ax=ax, node_size=160, node_color="gold",
                           edgecolors="red")
    nx.draw_networkx_labels(G, pos, {s: str(s) for s in G.nodes}, ax=ax, font_size=6)
    ax.set_title(f"learned map: {m.n_states} states, {G.number_of_edges()} arcs with "
                 f"P(x'|x,u) > {min_prob}", fontsize=9)


def plot_entropy(ax, learner):
    e = learner.entropies_
    it = [r["n_states"] for r in e]
    hu = np.array([r["H_u"] for r in e])
    hx = np.array([r["H_x"] for r in e])
    ax.plot(it, hu, "o-", ms=3, label="H(u|x)")
    ax.plot(it, hx, "s-", ms=3, label="H(x'|x,u)")
    ax.plot(it, hu + hx, "k^-", ms=3, label="sum")
    ax.set_xlabel("number of states")
    ax.set_ylabel("bits")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title("entropies after each split", fontsize=9)


def _save(fig, path: Path):
    plt = _plt()
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png"))
    plt.close(fig)


def write_figures(out: Path, traj, learner, world=None, *, min_prob=0.8, compound_state=None):
    """Write the figures of :data:`topomap.app.outputs.FIGURE_FILES` that the data allows
    (the room figures need ground-truth positions)."""
    plt = _plt()
    out = Path(out)
    written = []
    if traj.positions is not None:
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
        plot_states(axes[0], traj, learner.labels_phase1_, world,
                    f"after clustering: {learner.map_phase1_.n_states} states")
        plot_states(axes[1], traj, learner.labels_, world,
                    f"after splitting: {learner.map_.n_states} states")
        _save(fig, out / "fig_states.png")
        written.append("fig_states.png")
        fig = plt.figure(figsize=(13, 7.5))
        if plot_split(fig, traj, learner, world, compound_state):
            _save(fig, out / "fig_split.png")
            written.append("fig_split.png")
        else:
            plt.close(fig)
        fig, ax = plt.subplots(figsize=(8, 6))
        plot_map(ax, traj, learner, world, min_prob)
        _save(fig, out / "fig_map.png")
        written.append("fig_map.png")
    fig, ax = plt.subplots(figsize=(5, 3.5))
    plot_entropy(ax, learner)
    _save(fig, out / "fig_entropy.png")
    written.append("fig_entropy.png")
    return written
