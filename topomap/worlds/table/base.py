"""Worlds given by tables, and the symbols their places show.

A *table-driven* world (:class:`TableWorld`) has ``successors[p, a]`` (the place action ``a``
leads to from place ``p``, -1 where it is not executable), ``place_symbols`` (the symbol each
place shows), an ``embedding`` of the symbols as observation vectors, ``place_positions`` and
``action_names``.  From these alone it observes, walks (``simulate``) and gives its true topology
(``place_graph``); a world on this base only builds its tables and says what its trajectories
record of it (``meta``).
"""

from __future__ import annotations

import numpy as np

from ...core.data.trajectory import Trajectory
from ..checks import check_choice, check_simulate_args
from ..explorers import show
from ..navigation import PlaceGraph, largest_component

__all__ = ["TableWorld", "symbol_embedding", "assign_symbols", "symbol_legend",
           "MAX_LEGEND_SYMBOLS"]


class TableWorld:
    """The base of the worlds given by tables (see the module docstring).

    A world on it sets ``successors``, ``place_symbols``, ``embedding``, ``place_positions`` and
    ``action_names`` when it is made, and defines :meth:`meta`.
    """

    successors: np.ndarray
    place_symbols: np.ndarray
    embedding: np.ndarray
    place_positions: np.ndarray
    action_names: list

    @property
    def n_actions(self) -> int:
        return len(self.action_names)

    def meta(self) -> dict:
        """What a trajectory of the world records of it (``Trajectory.meta``)."""
        raise NotImplementedError

    def executable_mask(self, place: int) -> np.ndarray:
        """Which actions can be started at ``place``."""
        return self.successors[place] >= 0

    def observe(self, place: int) -> np.ndarray:
        """Noise-free observation at ``place``."""
        return self.embedding[self.place_symbols[place]].copy()

    def place_graph(self) -> PlaceGraph:
        """The true topology, for navigation (:mod:`topomap.worlds.navigation`)."""
        n = self.successors.shape[0]
        return PlaceGraph(self.successors.copy(), self.embedding[self.place_symbols],
                          np.full(n, -1, dtype=np.int64),
                          largest_component(self.successors, range(n)))

    def simulate(self, n_steps: int, explorer, rng: np.random.Generator) -> Trajectory:
        """A walk of ``n_steps`` steps from a place drawn with ``rng``.

        At each step the explorer picks one of the actions executable there
        (``explorer.choose(mask, rng)``, called exactly once per step, after ``see`` if it has
        it); the last step's action is chosen but not executed.  Returns a noise-free
        :class:`Trajectory` with ``places`` and ``positions``.
        """
        n_steps = check_simulate_args(n_steps, explorer)
        masks = self.successors >= 0
        places = np.empty(n_steps, dtype=np.int64)
        actions = np.empty(n_steps, dtype=np.int64)
        p = int(rng.integers(self.successors.shape[0]))
        sees = hasattr(explorer, "see")
        for t in range(n_steps):
            places[t] = p
            mask = masks[p].copy()
            if sees:
                show(explorer, self.embedding[self.place_symbols[p]], mask, -1, t)
            a = check_choice(explorer.choose(mask, rng), mask, t)
            actions[t] = a
            p = int(self.successors[p, a])
        return Trajectory(
            observations=self.embedding[self.place_symbols[places]], actions=actions,
            places=places, positions=self.place_positions[places],
            action_names=list(self.action_names), meta=self.meta(),
        )


def symbol_embedding(n_symbols: int, obs_dim: int, rng: np.random.Generator) -> np.ndarray:
    """Observation vector of every symbol, ``(n_symbols, D)``, all entries in ``[0, 1]``.

    ``obs_dim == 0`` gives one-hot vectors (``D = n_symbols``); ``obs_dim > 0`` draws each symbol's
    vector uniformly from ``[0, 1]^obs_dim`` with ``rng`` (distinct with probability one, but
    nothing keeps two of them far apart).
    """
    if obs_dim == 0:
        return np.eye(n_symbols)
    return rng.uniform(0.0, 1.0, size=(n_symbols, obs_dim))


def assign_symbols(n_places: int, n_symbols: int, rng: np.random.Generator) -> np.ndarray:
    """A symbol for every place: each symbol at least once, the rest uniform, shuffled."""
    sym = np.concatenate([np.arange(n_symbols), rng.integers(0, n_symbols, n_places - n_symbols)])
    return rng.permutation(sym).astype(np.int64)


#: most symbols listed in a room's legend (more are told apart by their labels only)
MAX_LEGEND_SYMBOLS = 20


def symbol_legend(ax, colours) -> None:
    """A legend of the symbols' tints (one entry per colour) beside the room, for at most
    :data:`MAX_LEGEND_SYMBOLS` symbols."""
    from matplotlib.patches import Patch

    if len(colours) > MAX_LEGEND_SYMBOLS:
        return
    handles = [Patch(fc=c, ec="0.5", lw=0.5, label=f"symbol {k}") for k, c in enumerate(colours)]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
              title="observed symbol", title_fontsize=7, frameon=False)
