"""A random strongly connected directed graph of places, each emitting one of a few symbols.

``n_places`` places; every place has ``out_degree`` out-edges to distinct other places, labelled
with the actions ``0 .. out_degree - 1`` (action ``a`` from place ``p`` always leads to
``successors[p, a]``, so moves are deterministic and every action is executable everywhere).
Strong connectivity holds by construction: one out-edge of every place follows a random
Hamiltonian cycle (under a random action label), the others go to distinct random places.

Every place emits one of ``n_symbols`` symbols (each used at least once; ``n_symbols < n_places``
gives perceptual aliasing).  The noise-free observation is the symbol's embedding (one-hot, or
random non-negative vectors with ``obs_dim > 0``; see
:func:`topomap.worlds.table.base.symbol_embedding`).

Ground truth: the place (``places``) and a fixed 2-D drawing of the graph (``positions``):
networkx's ``spring_layout`` with ``seed`` (``layout="spring"``) or the places on a circle
(``layout="circular"``), scaled to fit a square of side ``2 * sqrt(n_places)``.
"""

from __future__ import annotations

import math

import numpy as np

from ...core.checks import check_count
from ..checks import check_no_extra_actions
from .base import TableWorld, assign_symbols, symbol_embedding, symbol_legend

__all__ = ["RandomGraphWorld", "random_strong_digraph"]

LAYOUTS = ("spring", "circular")


def random_strong_digraph(n_places: int, out_degree: int, rng: np.random.Generator) -> np.ndarray:
    """Successor table ``(n_places, out_degree)`` of a random strongly connected digraph.

    Out-edges of a place go to distinct places other than itself; one of them (at a random action
    label) follows a random Hamiltonian cycle through all places.
    """
    order = rng.permutation(n_places)
    cycle_next = np.empty(n_places, dtype=np.int64)
    cycle_next[order] = np.roll(order, -1)
    succ = np.empty((n_places, out_degree), dtype=np.int64)
    for p in range(n_places):
        others = np.setdiff1d(np.arange(n_places), [p, cycle_next[p]])
        targets = np.concatenate([[cycle_next[p]], rng.choice(others, out_degree - 1, replace=False)])
        succ[p] = targets[rng.permutation(out_degree)]
    return succ


class RandomGraphWorld(TableWorld):
    """Random walk on a random strongly connected digraph with aliased place symbols.

    A :class:`~topomap.worlds.table.base.TableWorld`: it observes, walks (``simulate``) and gives
    its place graph from its tables.

    Parameters
    ----------
    n_places : int
        Number of places (>= 2).
    out_degree : int
        Out-edges (= actions) per place, ``1 <= out_degree <= n_places - 1``.
    n_symbols : int
        Number of observation symbols, ``1 <= n_symbols <= n_places``.
    obs_dim : int
        0 for one-hot observations, else the dimension of random non-negative symbol vectors.
    layout : {"spring", "circular"}
        How the graph is drawn (``positions`` and figures).
    seed : int
        Seeds the graph, the symbols, the embedding and the layout (not the walk).
    extra_actions : list, optional
        Not supported: a non-empty list raises ValueError.
    """

    def __init__(self, n_places: int = 30, out_degree: int = 4, n_symbols: int = 20,
                 obs_dim: int = 0, layout: str = "spring", seed: int = 0, extra_actions=None):
        self.n_places = check_count(n_places, "n_places", minimum=2)
        self.out_degree = check_count(out_degree, "out_degree")
        if self.out_degree > self.n_places - 1:
            raise ValueError(f"out_degree={out_degree} needs more than {self.n_places} places "
                             "(out-edges go to distinct other places)")
        self.n_symbols = check_count(n_symbols, "n_symbols")
        if self.n_symbols > self.n_places:
            raise ValueError(f"n_symbols={n_symbols} exceeds n_places={self.n_places}")
        self.obs_dim = check_count(obs_dim, "obs_dim", minimum=0)
        if layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
        self.layout = layout
        self.seed = int(seed)
        check_no_extra_actions("random_graph", extra_actions)
        rng = np.random.default_rng(self.seed)
        #: place reached by each action from each place
        self.successors = random_strong_digraph(self.n_places, self.out_degree, rng)
        self.place_symbols = assign_symbols(self.n_places, self.n_symbols, rng)
        self.embedding = symbol_embedding(self.n_symbols, self.obs_dim, rng)
        self.place_positions = self._layout_positions()
        self.action_names = [f"edge {a}" for a in range(self.out_degree)]

    def to_networkx(self):
        """The place graph as an ``nx.DiGraph``; every arc carries its ``action``."""
        import networkx as nx

        G = nx.DiGraph()
        G.add_nodes_from(range(self.n_places))
        for p in range(self.n_places):
            for a, q in enumerate(self.successors[p]):
                G.add_edge(p, int(q), action=a)
        return G

    def _layout_positions(self) -> np.ndarray:
        import networkx as nx

        G = self.to_networkx()
        if self.layout == "spring":
            pos = nx.spring_layout(G.to_undirected(), seed=self.seed)
        else:
            pos = nx.circular_layout(G)
        P = np.array([pos[p] for p in range(self.n_places)], dtype=np.float64)
        lo, hi = P.min(axis=0), P.max(axis=0)
        side = 2.0 * math.sqrt(self.n_places)
        # one scale for both axes, so the drawing keeps its shape (a circle stays a circle)
        return (P - (lo + hi) / 2) / max(float((hi - lo).max()), 1e-12) * side + side / 2

    def meta(self) -> dict:
        """What a walk's trajectory records of the graph: its size, symbols, arcs and seed."""
        return {
            "world": "random_graph", "n_places": self.n_places, "out_degree": self.out_degree,
            "n_symbols": self.n_symbols, "obs_dim": self.obs_dim, "layout": self.layout,
            "seed": self.seed, "place_symbols": self.place_symbols.tolist(),
            "successors": self.successors.tolist(),
        }

    def plot_room(self, ax, labels: bool = False):
        """Draw the place graph: faint arcs, places tinted by symbol (with a legend of the symbols
        beside the graph; ids with ``labels``).  Returns ``ax``."""
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection

        P = self.place_positions
        segs = [(P[p], P[q]) for p in range(self.n_places) for q in self.successors[p]]
        ax.add_collection(LineCollection(segs, colors="lightgray", linewidths=0.6, zorder=0))
        cmap = plt.get_cmap("tab20", 20)
        colours = [cmap(k % 20)[:3] + (0.35,) for k in range(self.n_symbols)]
        ax.scatter(P[:, 0], P[:, 1], s=260, c=[colours[s] for s in self.place_symbols], lw=0,
                   zorder=1)
        if labels:
            for p in range(self.n_places):
                ax.annotate(str(p), P[p], ha="center", va="center", fontsize=6, color="dimgray")
        side = 2.0 * math.sqrt(self.n_places)
        ax.set_xlim(-1.0, side + 1.0)
        ax.set_ylim(-1.0, side + 1.0)
        ax.set_aspect("equal")
        symbol_legend(ax, colours)
        return ax

    def __repr__(self) -> str:
        return (f"RandomGraphWorld(n_places={self.n_places}, out_degree={self.out_degree}, "
                f"n_symbols={self.n_symbols}, obs_dim={self.obs_dim}, layout={self.layout!r}, "
                f"seed={self.seed})")
