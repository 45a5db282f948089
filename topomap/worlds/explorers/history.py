"""The history policy: the action least taken from the robot's recent past, read through the
map's symbols (``explorer=active``, its default route)."""

from __future__ import annotations

import numpy as np

from ...core.checks import check_count
from .base import MapExplorer, View, check_mask, pick

__all__ = ["HistoryExplorer", "symbol_means"]


def symbol_means(m) -> np.ndarray:
    """``(K, D)``: the mean observation of every K-means symbol of the map ``m``, in symbol order.

    A map ties the observation model of the states split from one symbol: they share the mean of
    all the steps of that symbol (``TopologicalMap.means``), which is the symbol's.  GDS states
    have no symbol and are left out."""
    plain = m.state_symbol >= 0
    first = np.unique(m.state_symbol[plain], return_index=True)[1]
    return m.means[plain][first]


class HistoryExplorer(MapExplorer):
    """Take the executable action least taken from the robot's recent past.

    A *state* is the robot's recent past read through the map's symbols: the symbols of the last
    ``context`` views, the actions between them and the symbol of the current view.  A view's
    symbol is its GDS if it recognises one, else the symbol of the nearest mean observation
    (:func:`symbol_means`).  Each step it takes the executable action it has taken least often
    from that state (ties at random); with probability ``epsilon`` a random one.  No belief is
    tracked, so no belief can be wrong.

    The symbols are read off the first map and kept: the counts are keyed by them, so they keep
    their meaning from one map to the next (a later map may number its symbols otherwise).

    Parameters
    ----------
    update_every : int
        Steps between two updates of the map.
    context : int
        The past views that make a state, besides the current one.
    epsilon : float
        Share of random actions, in [0, 1].
    """

    def __init__(self, update_every: int = 250, context: int = 3, epsilon: float = 0.0):
        super().__init__(update_every, epsilon)
        self.context = check_count(context, "context", minimum=0)
        self._symbols = None       # (K, D) the first map's symbol means
        self._past = []            # symbols and actions of the last steps, oldest first
        self._counts = {}          # times each action was taken from each state

    def update(self, learner) -> None:
        """Take the map the learner has now: its symbols, the first time."""
        if self._symbols is None:
            self._symbols = symbol_means(learner.map_)

    def symbol_of(self, view: View) -> int:
        """The view's symbol: its GDS (as ``-1 - gds``), else the nearest symbol mean."""
        if view.gds >= 0:
            return -1 - int(view.gds)
        d = ((self._symbols - view.observation[None, :]) ** 2).sum(1)
        return int(np.argmin(d))

    def choose(self, executable, rng: np.random.Generator) -> int:
        """The executable action least taken from the current state (see the class docstring)."""
        idx = np.flatnonzero(check_mask(executable))
        if self._symbols is None or self._view is None:
            return pick(idx, rng)
        sym = self.symbol_of(self._view)
        # while fewer than 2 * context entries are kept, the slice keeps the last
        # 2 * context - len of them (all, if there are fewer)
        state = (*self._past[len(self._past) - 2 * self.context:], sym) if self.context else (sym,)
        if rng.random() < self.epsilon:
            a = pick(idx, rng)
        else:
            tried = np.array([self._counts.get((state, int(b)), 0) for b in idx])
            a = pick(idx[tried == tried.min()], rng)
        self._counts[(state, a)] = self._counts.get((state, a), 0) + 1
        self._past += [sym, a]
        del self._past[:-2 * max(self.context, 1)]
        return a

    def __repr__(self) -> str:
        return (f"HistoryExplorer(update_every={self.update_every}, context={self.context}, "
                f"epsilon={self.epsilon})")
