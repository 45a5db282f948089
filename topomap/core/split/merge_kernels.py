"""Compiled parts of proposing a split: the bottom-up merge of count rows and the entropy gain
(bit for bit as numpy: every logarithm read from a table numpy computed, every sum in numpy's
pairwise order), and a state's count matrix from its instance table."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..sums import _BLOCK, pairwise_sum

__all__ = ["merge_groups_kernel", "gain_kernel", "merge_gain_kernel", "count_range",
           "count_matrix_kernel"]


@njit(cache=True)
def _round(x, scale):
    """``np.round(x, decimals)`` for ``scale = 10.0 ** decimals``."""
    return np.rint(x * scale) / scale


@njit(cache=True)
def _merged_sum(work, table, a, b, buf):
    """``table[work[a] + work[b]].sum()`` in numpy's order: up to 128 columns (one block of
    numpy's pairwise sum) read straight into its eight accumulators, more through ``buf``."""
    K = work.shape[1]
    if K > _BLOCK:
        for k in range(K):
            buf[k] = table[work[a, k] + work[b, k]]
        return 0.0 + pairwise_sum(buf, 0, K)
    wa, wb = work[a], work[b]
    if K < 8:
        res = -0.0
        for k in range(K):
            res += table[wa[k] + wb[k]]
        return 0.0 + res
    r0, r1 = table[wa[0] + wb[0]], table[wa[1] + wb[1]]
    r2, r3 = table[wa[2] + wb[2]], table[wa[3] + wb[3]]
    r4, r5 = table[wa[4] + wb[4]], table[wa[5] + wb[5]]
    r6, r7 = table[wa[6] + wb[6]], table[wa[7] + wb[7]]
    m = K - K % 8
    for i in range(8, m, 8):
        r0 += table[wa[i] + wb[i]]
        r1 += table[wa[i + 1] + wb[i + 1]]
        r2 += table[wa[i + 2] + wb[i + 2]]
        r3 += table[wa[i + 3] + wb[i + 3]]
        r4 += table[wa[i + 4] + wb[i + 4]]
        r5 += table[wa[i + 5] + wb[i + 5]]
        r6 += table[wa[i + 6] + wb[i + 6]]
        r7 += table[wa[i + 7] + wb[i + 7]]
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(m, K):
        res += table[wa[i] + wb[i]]
    return 0.0 + res


@njit(cache=True)
def _row_weight(work, table, n, a, buf):
    """``W[a] = table[n[a]] - table[work[a]].sum()``."""
    K = work.shape[1]
    for k in range(K):
        buf[k] = table[work[a, k]]
    return table[n[a]] - (0.0 + pairwise_sum(buf, 0, K))


@njit(cache=True)
def _initial_costs(work, table, n, W, scale, buf):
    """Upper triangle ``cost[a, b] = round(table[n_a + n_b] - s_ab - W_a - W_b)``, inf elsewhere."""
    G = work.shape[0]
    cost = np.full((G, G), np.inf)
    for a in range(G):
        for b in range(a + 1, G):
            s = _merged_sum(work, table, a, b, buf)
            cost[a, b] = _round(table[n[a] + n[b]] - s - W[a] - W[b], scale)
    return cost


@njit(cache=True)
def _row_min(cost, i, rmin, rarg):
    """First smallest entry of row ``i`` right of the diagonal (-1 when all are inf)."""
    rmin[i], rarg[i] = np.inf, -1
    for j in range(i + 1, cost.shape[0]):
        if cost[i, j] < rmin[i]:
            rmin[i], rarg[i] = cost[i, j], j


@njit(cache=True)
def _argmin(rmin, rarg):
    """Row-major index of the first smallest cost (``np.argmin`` of the flattened matrix): the
    first row holding the smallest row minimum, at that row's first minimum."""
    best, ba, bb = np.inf, 0, 0
    for a in range(rmin.size):
        if rmin[a] < best:
            best, ba, bb = rmin[a], a, rarg[a]
    return ba, bb


@njit(cache=True)
def _refresh_minima(cost, rmin, rarg, a, b):
    """Row minima after merging ``b`` into ``a``: row ``b`` and column ``b`` are now inf, row
    ``a`` and column ``a`` hold new costs; other entries are unchanged."""
    rmin[b], rarg[b] = np.inf, -1
    _row_min(cost, a, rmin, rarg)
    for i in range(b):
        if i == a:
            continue
        if rarg[i] == b or rarg[i] == a:
            _row_min(cost, i, rmin, rarg)
        elif i < a and (cost[i, a] < rmin[i] or (cost[i, a] == rmin[i] and a < rarg[i])):
            rmin[i], rarg[i] = cost[i, a], a


@njit(cache=True)
def _merge_pair(work, table, n, W, owner, cost, a, b, scale, buf):
    """Merge row ``b`` into row ``a`` and refresh row/column ``a`` of the cost matrix."""
    G = work.shape[0]
    work[a] += work[b]
    work[b] = 0
    n[a] += n[b]
    n[b] = 0
    W[a] = _row_weight(work, table, n, a, buf)
    for g in range(G):
        if owner[g] == b:
            owner[g] = a
    cost[b, :] = np.inf
    cost[:, b] = np.inf
    for j in range(G):
        if j == a:
            continue
        if owner[j] != j:
            value = np.inf
        else:
            s = _merged_sum(work, table, a, j, buf)
            value = _round(table[n[a] + n[j]] - s - W[a] - W[j], scale)
        if j > a:
            cost[a, j] = value
        else:
            cost[j, a] = value


@njit(cache=True)
def merge_groups_kernel(counts, table, decimals):
    """Bottom-up merge of the rows of ``counts`` (int64, G >= 2) into two clusters.

    ``table[c]`` must be numpy's ``c * log2(max(c, 1))`` for every ``c <= 2 * counts.sum()``.
    Returns True for the rows not in the cluster of row 0.
    """
    work = counts.copy()
    G, K = work.shape
    buf = np.empty(K)
    scale = 10.0 ** decimals
    n = np.empty(G, dtype=np.int64)
    W = np.empty(G)
    for a in range(G):
        n[a] = work[a].sum()
    for a in range(G):
        W[a] = _row_weight(work, table, n, a, buf)
    cost = _initial_costs(work, table, n, W, scale, buf)
    rmin, rarg = np.empty(G), np.empty(G, dtype=np.int64)
    for i in range(G):
        _row_min(cost, i, rmin, rarg)
    owner = np.arange(G)
    for _ in range(G - 2):
        a, b = _argmin(rmin, rarg)
        _merge_pair(work, table, n, W, owner, cost, a, b, scale, buf)
        _refresh_minima(cost, rmin, rarg, a, b)
    return owner != owner[0]


@njit(cache=True)
def _weighted_entropy(row, table, buf):
    """``weighted_entropy`` of one row of counts: ``xlogx(row.sum()) - xlogx(row).sum()``."""
    n = 0
    for c in range(row.size):
        n += row[c]
        buf[c] = table[row[c]]
    return table[n] - (0.0 + pairwise_sum(buf, 0, row.size))


@njit(cache=True)
def gain_kernel(counts, side, table):
    """The entropy gain of cutting the rows of ``counts`` into ``side`` False and True, as
    :class:`~topomap.core.split.criteria.EntropyCriterion` writes it in numpy: ``(n H(I) -
    n' H(I') - n'' H(I'')) / n`` with every ``x log x`` read from ``table`` (valid up to the
    total count) and every sum in numpy's order.  Not clipped at 0."""
    G, C = counts.shape
    halves = np.zeros((2, C), dtype=np.int64)
    for g in range(G):
        h = 1 if side[g] else 0
        for c in range(C):
            halves[h, c] += counts[g, c]
    buf, parts = np.empty(C), np.empty(2)
    whole = _weighted_entropy(halves[0] + halves[1], table, buf)
    for h in range(2):
        parts[h] = _weighted_entropy(halves[h], table, buf)
    return (whole - (0.0 + pairwise_sum(parts, 0, 2))) / (halves[0].sum() + halves[1].sum())


@njit(cache=True, nogil=True)
def merge_gain_kernel(counts, table, decimals):
    """:func:`merge_groups_kernel`, then :func:`gain_kernel` of its halves, in one call (``table``
    as for the first)."""
    side = merge_groups_kernel(counts, table, decimals)
    return side, gain_kernel(counts, side, table)


@njit(cache=True, nogil=True)
def count_range(counts):
    """The smallest entry and the sum of an int64 matrix (0, 0 when it is empty), in one pass."""
    low, total = 0, 0
    for g in range(counts.shape[0]):
        for c in range(counts.shape[1]):
            v = counts[g, c]
            low = min(low, v)
            total += v
    return low, total


@njit(cache=True)
def _ranks(values, size):
    """The sorted distinct entries of ``values`` (ints in ``[0, size)``) and each entry's rank
    among them (by a presence mask, or by sorting when ``values`` are few next to ``size``)."""
    if 16 * values.size < size:
        distinct = np.unique(values)
        return distinct, np.searchsorted(distinct, values)
    rank = np.zeros(size, dtype=np.int64)
    for v in values:
        rank[v] = 1
    distinct = np.flatnonzero(rank)
    rank[distinct] = np.arange(distinct.size)
    return distinct, rank[values]


@njit(cache=True, nogil=True)
def count_matrix_kernel(codes, counts, size):
    """``(matrix, keys, cols)`` of a sorted instance table (codes ``key << 32 | column``, keys
    and columns below ``size``): its sorted distinct keys and columns and the (keys x columns)
    count matrix."""
    keys, g = _ranks(codes >> 32, size)
    cols, c = _ranks(codes & 0xFFFFFFFF, size)
    matrix = np.zeros((keys.size, cols.size), dtype=np.int64)
    for i in range(codes.size):
        matrix[g[i], c[i]] = counts[i]
    return matrix, keys, cols
