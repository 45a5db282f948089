"""Means and scatter of groups of observations, gathered chunk by chunk and combined.

A chunk gives, for every group (a K-means symbol, a GDS id, or all rows), its count, mean and
sum of squared deviations from that mean (``m2``: per feature, or the (D, D) scatter matrix);
two such summaries combine exactly in real arithmetic (Chan, Golub & LeVeque's pairwise update),
so that the Gaussian observation models of phase 1 and the data's feature variance come from
sums over steps without holding the steps.  Summaries are combined in the order of the chunks
(the logs' order), whichever worker computed them, so a streamed fit gives the same floats on
one process as on many.  Against the two passes over all rows of an in-memory fit they differ
by rounding only (about 1e-15 relative).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["Moments", "chunk_moments", "combine", "keyed_combine"]


@dataclass
class Moments:
    """Counts ``n`` (K,), means ``mean`` (K, D) and squared deviations ``m2`` (K, D) or
    (K, D, D) of K groups of rows."""

    n: np.ndarray
    mean: np.ndarray
    m2: np.ndarray

    @classmethod
    def empty(cls, K: int, D: int, full: bool) -> "Moments":
        return cls(np.zeros(K), np.zeros((K, D)), np.zeros((K, D, D) if full else (K, D)))

    def take(self, rows) -> "Moments":
        return Moments(self.n[rows], self.mean[rows], self.m2[rows])


@njit(cache=True, nogil=True)
def _diag_moments(X, group, K):
    """Counts, means and per-feature squared deviations of the rows of every group (two passes
    over the rows, in order)."""
    D = X.shape[1]
    n, mean, m2 = np.zeros(K), np.zeros((K, D)), np.zeros((K, D))
    for t in range(X.shape[0]):
        g = group[t]
        n[g] += 1.0
        for d in range(D):
            mean[g, d] += X[t, d]
    for g in range(K):
        if n[g] > 0:
            for d in range(D):
                mean[g, d] /= n[g]
    for t in range(X.shape[0]):
        g = group[t]
        for d in range(D):
            r = X[t, d] - mean[g, d]
            m2[g, d] += r * r
    return n, mean, m2


def chunk_moments(X: np.ndarray, group: np.ndarray, K: int, full: bool = False) -> Moments:
    """The :class:`Moments` of the rows of ``X`` in each of the groups ``group`` (ids in
    ``[0, K)``); ``full``: (D, D) scatter matrices, else per-feature sums of squares."""
    group = np.ascontiguousarray(group, dtype=np.int64)
    n, mean, m2 = _diag_moments(np.ascontiguousarray(X), group, int(K))
    if not full:
        return Moments(n, mean, m2)
    scatter = np.zeros((K, X.shape[1], X.shape[1]))
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(group[order], np.arange(K + 1))
    for g in np.flatnonzero(n):
        r = X[order[bounds[g]:bounds[g + 1]]] - mean[g]
        scatter[g] = r.T @ r
    return Moments(n, mean, scatter)


def combine(a: Moments, b: Moments) -> Moments:
    """The moments of the union of the rows behind ``a`` and ``b`` (group by group)."""
    n = a.n + b.n
    safe = np.maximum(n, 1.0)
    delta = b.mean - a.mean
    weight = a.n * b.n / safe
    mean = np.where(n[:, None] > 0, (a.n[:, None] * a.mean + b.n[:, None] * b.mean)
                    / safe[:, None], 0.0)
    if a.m2.ndim == 3:
        m2 = a.m2 + b.m2 + weight[:, None, None] * delta[:, :, None] * delta[:, None, :]
    else:
        m2 = a.m2 + b.m2 + weight[:, None] * delta * delta
    return Moments(n, mean, m2)


def keyed_combine(a: tuple[np.ndarray, Moments], b: tuple[np.ndarray, Moments]):
    """:func:`combine` of two summaries of groups named by sorted ``keys`` (GDS ids): the union
    of the keys, sorted, and their moments."""
    keys = np.union1d(a[0], b[0])
    D = a[1].mean.shape[1]
    full = a[1].m2.ndim == 3
    out = []
    for k, m in (a, b):
        wide = Moments.empty(keys.size, D, full)
        rows = np.searchsorted(keys, k)
        wide.n[rows], wide.mean[rows], wide.m2[rows] = m.n, m.mean, m.m2
        out.append(wide)
    return keys, combine(*out)
