"""The symbols :meth:`MapLearner.partial_fit <topomap.MapLearner.partial_fit>` keeps, and how
many it may have while views still appear.

A robot that learns while it walks cannot know how many views its world shows: a cluster count
asked for (``n_clusters``, the number of views of the whole walk, say) may be more than the
distinct observations its window holds so far.  A wider pass then caps the count at what the
window holds (:class:`WindowClusters`: K-means makes one symbol of every distinct view) instead of
failing, and the codebook it learns grows: a view no symbol holds yet gets a symbol of its own as
it appears, until the count asked for is reached (:meth:`Codebook.assign`); after that a new view
takes the symbol of the nearest mean, as every observation does when nothing is capped.  Views
repeat exactly (a noise-free sensor, a grid world), so a view is a row of the observations; rows
that never repeat (a noisy sensor) are never capped.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from sklearn.metrics.pairwise import euclidean_distances

from .phase1.clustering import probe_distinct

__all__ = ["Codebook", "WindowClusters"]


@dataclass(frozen=True)
class Codebook:
    """The fixed symbols: the mean observation of every K-means symbol (K, D).

    While the count is capped below the one asked for (``limit``), every symbol is a view and
    ``views`` maps each view seen (its row's bytes) to its symbol; None when nothing is capped."""

    means: np.ndarray
    views: dict | None = None
    limit: int = 0

    @classmethod
    def from_symbols(cls, X: np.ndarray, sym: np.ndarray, K: int, limit: int = 0) -> "Codebook":
        """The mean of the rows of ``X`` of every symbol ``0..K-1`` of ``sym``; with ``limit``
        (the count asked for, capped at the ``K`` views of ``X``), the views too."""
        sums = np.zeros((K, X.shape[1]))
        np.add.at(sums, sym, X)
        means = sums / np.maximum(np.bincount(sym, minlength=K), 1)[:, None]
        if limit <= K:
            return cls(means)
        rows, first = np.unique(_rows(X), axis=0, return_index=True)
        return cls(means, {r.tobytes(): int(s) for r, s in zip(rows, sym[first])}, int(limit))

    @property
    def size(self) -> int:
        return int(self.means.shape[0])

    def symbols(self, X: np.ndarray) -> np.ndarray:
        """The symbol of every row: its nearest mean (scikit-learn's squared Euclidean
        distances, one matrix product; its ``pairwise_distances_argmin`` gives the same symbols
        but starts OpenMP threads, which on a chunk of a thousand rows cost far more than the
        product)."""
        return euclidean_distances(X, self.means, squared=True).argmin(axis=1).astype(np.int64)

    def assign(self, X: np.ndarray):
        """``(symbols, codebook)``: the symbol of every row of ``X`` and the codebook after
        them.  While capped (``views``), a view seen before keeps its symbol and a new one gets
        the next symbol (in order of appearance) while there are fewer than ``limit``; every
        other row takes its nearest mean (:meth:`symbols`), and so does every row when nothing
        is capped."""
        if self.views is None or X.shape[0] == 0:
            return self.symbols(X), self
        rows, first, inverse = np.unique(_rows(X), axis=0, return_index=True,
                                         return_inverse=True)
        keys = [r.tobytes() for r in rows]
        found = np.array([self.views.get(k, -1) for k in keys], dtype=np.int64)
        new = np.flatnonzero(found < 0)
        room = max(self.limit - self.size, 0)
        grown = self
        if new.size and room:
            new = new[np.argsort(first[new], kind="stable")][:room]  # by first appearance
            found[new] = self.size + np.arange(new.size)
            views = dict(self.views)
            views.update((keys[i], int(found[i])) for i in new)
            grown = replace(self, means=np.vstack([self.means, rows[new]]), views=views)
        sym = found[inverse.ravel()]
        rest = sym < 0
        if rest.any():
            sym[rest] = grown.symbols(X[rest])
        return sym, grown


def _rows(X: np.ndarray) -> np.ndarray:
    """``X`` as contiguous float64 rows with -0.0 made 0.0, so equal views have equal bytes."""
    return np.ascontiguousarray(X, dtype=np.float64) + 0.0


class WindowClusters:
    """A wider pass's cluster-count policy: the learner's own (``policy``), its count capped at
    the distinct observations the pass's window holds (scikit-learn's K-means cannot make more
    clusters than distinct rows).  ``capped`` is ``{"asked": n, "distinct": d}`` after a
    :meth:`choose` that capped, else None; the choice's details say so too (``"capped"``)."""

    def __init__(self, policy):
        self.policy = policy
        self.capped = None

    def choose(self, Z: np.ndarray, random_state: int):
        choice = self.policy.choose(Z, random_state)
        ns, details = choice if isinstance(choice, tuple) else (choice, {})
        _, distinct = probe_distinct(Z, int(ns), random_state)
        if distinct is None or distinct[0].size >= int(ns):
            return ns, details
        self.capped = {"asked": int(ns), "distinct": int(distinct[0].size)}
        return self.capped["distinct"], dict(details, capped=dict(self.capped))

    def __getattr__(self, name):  # min_ns, max_ns, ... of the learner's policy
        if name == "policy":
            raise AttributeError(name)
        return getattr(self.policy, name)

    def __repr__(self) -> str:
        return repr(self.policy)
