"""The discrete input of the refinements: :class:`SymbolSequence`, the steps as symbol ids.

``sym[t]`` is the K-means symbol of step ``t`` (``0..n_symbols-1``) or ``n_symbols + g`` for a
step recognised as GDS ``g`` (``labels_phase1_`` of :class:`topomap.MapLearner`), with the
actions and the episode lengths.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..stats import episode_masks
from .clones import Layout, make_layout

__all__ = ["SymbolSequence"]


@dataclass(frozen=True)
class SymbolSequence:
    """The discrete input of the EM phases.

    ``sym`` (T,) symbol ids (K-means symbols ``0..n_symbols-1``, then GDS ids), ``u`` (T,) actions,
    ``lengths`` episode lengths, ``n_ids`` the number of symbol ids (K-means symbols + GDS).
    """

    sym: np.ndarray
    u: np.ndarray
    lengths: np.ndarray
    n_actions: int
    n_ids: int
    n_symbols: int

    @classmethod
    def build(cls, sym, u, lengths, n_actions: int, n_symbols: int) -> "SymbolSequence":
        """From array-likes; symbol ids past ``n_symbols`` are GDS ids."""
        sym = np.asarray(sym, dtype=np.int64)
        return cls(sym, np.asarray(u, dtype=np.int64), np.asarray(lengths, dtype=np.int64),
                   int(n_actions), max(int(sym.max()) + 1, int(n_symbols)), int(n_symbols))

    @property
    def T(self) -> int:
        """Number of steps."""
        return int(self.sym.size)

    @property
    def n_gds(self) -> int:
        """Number of GDS ids (symbol ids from ``n_symbols`` on)."""
        return self.n_ids - self.n_symbols

    def head(self, n_steps: int) -> "SymbolSequence":
        """The first ``n_steps`` steps (the last episode cut short)."""
        if n_steps >= self.T:
            return self
        ends = np.cumsum(self.lengths)
        k = int(np.searchsorted(ends, n_steps))
        lengths = self.lengths[:k + 1].copy()
        lengths[-1] -= ends[k] - n_steps
        return SymbolSequence(self.sym[:n_steps], self.u[:n_steps], lengths, self.n_actions,
                              self.n_ids, self.n_symbols)

    def layout(self, budget) -> Layout:
        """The sequence bound to ``budget`` clones per symbol id."""
        return make_layout(self.sym, self.u, self.lengths, budget, self.n_actions)

    def masks(self):
        """``(has_prev, has_next)`` of every step."""
        return episode_masks(self.T, self.lengths)
