"""Distinct observation rows, found by hashing (phase 1 clusters them with their counts)."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["distinct_rows"]

_NEG_ZERO_BITS = np.uint64(1 << 63)


@njit(cache=True)
def _row_hashes(bits):
    """A 64-bit hash of every row of the raw float64 bits (-0.0 counted as 0.0)."""
    T, D = bits.shape
    out = np.empty(T, dtype=np.uint64)
    for t in range(T):
        h = np.uint64(0x9E3779B97F4A7C15)
        for d in range(D):
            v = bits[t, d]
            if v == _NEG_ZERO_BITS:
                v = np.uint64(0)
            h ^= v + np.uint64(0x9E3779B97F4A7C15) + (h << np.uint64(6)) + (h >> np.uint64(2))
            h *= np.uint64(0xBF58476D1CE4E5B9)
            h ^= h >> np.uint64(31)
        out[t] = h
    return out


@njit(cache=True)
def _same_as_representative(Z, rep_of_row):
    for t in range(Z.shape[0]):
        r = rep_of_row[t]
        for d in range(Z.shape[1]):
            if Z[t, d] != Z[r, d]:
                return False
    return True


def distinct_rows(Z: np.ndarray):
    """``(first, inverse, counts)`` of the distinct rows of ``Z`` (rows equal as floats).

    ``Z[first]`` are the distinct rows in order of first appearance, ``Z[first][inverse] == Z``
    and ``counts`` how often each occurs.  Rows are hashed (O(T D) time, O(T) memory) and every
    row is checked against its group's first row; a hash collision (never seen) falls back to
    ``np.unique(Z, axis=0)``.
    """
    Z = np.ascontiguousarray(Z, dtype=np.float64)
    h = _row_hashes(Z.view(np.uint64))
    _, first, inverse, counts = np.unique(h, return_index=True, return_inverse=True,
                                          return_counts=True)
    if not _same_as_representative(Z, first[inverse]):
        _, first, inverse, counts = np.unique(Z, axis=0, return_index=True, return_inverse=True,
                                              return_counts=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return first[order], rank[inverse.ravel()], counts[order]
