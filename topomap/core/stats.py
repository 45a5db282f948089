"""Counts and entropies shared by the phases and the map, and matching two labellings' states:
the per-label means and the majority share the learner and the scores both use.

Everything the method measures of the discrete model is a function of integer counts: how often
each state occurs, takes each action, and reaches each next state; entropies are in bits.  Where a
result is stored in ``map.json`` the sums are taken in numpy's pairwise order
(:mod:`topomap.core.sums`), so the bytes never depend on which implementation ran.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .sums import sparse_pairwise_sum

__all__ = ["majority_match", "majority_share", "label_means", "xlogx", "weighted_entropy",
           "conditional_entropy", "sparse_conditional_entropy", "normalise", "episode_masks",
           "count_tables"]

_SHIFT = np.int64(32)
_MASK = np.int64((1 << 32) - 1)


def xlogx(c) -> np.ndarray:
    """``c * log2(c)`` elementwise, with ``0 log 0 = 0``."""
    c = np.asarray(c, dtype=np.float64)
    if np.all(c == np.round(c)):  # counts: log2(max(c, 1)) is exact at 0 and 1
        return c * np.log2(np.maximum(c, 1.0))
    return np.where(c > 0, c * np.log2(np.where(c > 0, c, 1.0)), 0.0)


def weighted_entropy(counts) -> np.ndarray:
    """``n * H`` in bits for each row of a count matrix (``n`` = row sum, ``H`` = row entropy)."""
    counts = np.atleast_2d(counts)
    return xlogx(counts.sum(axis=1)) - xlogx(counts).sum(axis=1)


def conditional_entropy(counts) -> float:
    """``H(Y|X)`` in bits from a count table whose last axis is ``Y`` and other axes are ``X``."""
    c = np.asarray(counts, dtype=np.float64).reshape(-1, np.shape(counts)[-1])
    n = c.sum()
    if n == 0:
        return 0.0
    rows = c.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(c > 0, c * np.log2(c / rows[:, None]), 0.0)
    return float(-terms.sum() / n) + 0.0  # + 0.0 turns -0.0 into 0.0


def sparse_conditional_entropy(codes, counts, n_rows_cols) -> float:
    """:func:`conditional_entropy` of a dense ``(R, C)`` table given by its sorted non-zero
    entries (``codes = row << 32 | col``), bit for bit, in O(non-zeros).

    ``n_rows_cols = (R, C)`` fixes the virtual layout that numpy's pairwise sum runs over.
    """
    if counts.size == 0:
        return 0.0
    R, C = n_rows_cols
    c = counts.astype(np.float64)
    rows = codes >> _SHIFT
    first = np.flatnonzero(np.concatenate([[True], rows[1:] != rows[:-1]]))
    row_sum = np.add.reduceat(c, first)
    per_entry = np.repeat(row_sum, np.diff(np.append(first, c.size)))
    terms = c * np.log2(c / per_entry)
    total = sparse_pairwise_sum(rows * C + (codes & _MASK), terms, R * C)
    n = np.float64(counts.sum())
    return float(-total / n) + 0.0


def normalise(counts) -> np.ndarray:
    """Row-normalise along the last axis; rows with no counts become uniform."""
    counts = np.asarray(counts, dtype=np.float64)
    total = counts.sum(axis=-1, keepdims=True)
    uniform = np.full_like(counts, 1.0 / counts.shape[-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, counts / total, uniform)


def episode_masks(T: int, lengths) -> tuple[np.ndarray, np.ndarray]:
    """``(has_prev, has_next)``: whether step ``t`` has a predecessor / successor in its episode."""
    lengths = np.asarray(lengths)
    ends = np.cumsum(lengths) - 1
    starts = ends - lengths + 1
    has_prev = np.ones(T, dtype=bool)
    has_next = np.ones(T, dtype=bool)
    has_prev[starts] = False
    has_next[ends] = False
    return has_prev, has_next


@njit(cache=True)
def _count_tables(x, u, S, A, has_next):
    """One pass over the steps: the three tables of :func:`count_tables`, no (T,) temporaries."""
    state = np.zeros(S, dtype=np.int64)
    action = np.zeros((S, A), dtype=np.int64)
    trans = np.zeros((S, A, S), dtype=np.int64)
    for t in range(x.size):
        state[x[t]] += 1
        action[x[t], u[t]] += 1
        if has_next[t]:
            trans[x[t], u[t], x[t + 1]] += 1
    return state, action, trans


def count_tables(labels, actions, n_states: int, n_actions: int, has_next):
    """``(state_counts (S,), action_counts (S, A), transition_counts (S, A, S))`` of a labelling.

    Transitions ``(x_t, u_t) -> x_{t+1}`` are counted only where ``has_next[t]`` (inside episodes).
    Counted in one compiled pass (a ten-million-step labelling needs no (T,) temporaries).
    """
    x, u, S, A = np.asarray(labels), np.asarray(actions), int(n_states), int(n_actions)
    has_next = np.asarray(has_next, dtype=bool)
    if x.shape != u.shape or x.shape != has_next.shape or x.ndim != 1:
        raise ValueError(f"labels, actions and has_next must be (T,) arrays of one length, got "
                         f"{x.shape}, {u.shape} and {has_next.shape}")
    if x.size and (x.min() < 0 or x.max() >= S or u.min() < 0 or u.max() >= A):
        raise ValueError(f"labels must lie in [0, {S}) and actions in [0, {A})")
    if x.size and has_next[-1]:
        raise ValueError("has_next must be False at the last step")
    return _count_tables(x, u, S, A, has_next)


def majority_match(a, b, n_a: int, n_b: int) -> np.ndarray:
    """(n_a,) for every state of the labelling ``a``, the state of ``b`` most of its steps hold
    (ties: the larger state of ``b``; -1 for a state none of whose steps has a state in ``b``).
    ``a`` and ``b`` label the same steps; -1 in either is left out."""
    a, b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
    both = (a >= 0) & (b >= 0)
    codes, counts = np.unique(a[both] * n_b + b[both], return_counts=True)
    out = np.full(n_a, -1, dtype=np.int64)
    for code, _ in sorted(zip(codes, counts), key=lambda p: p[1]):  # the largest count wins
        out[code // n_b] = code % n_b
    return out


def majority_share(truth, labels) -> float:
    """The share of steps whose label's most common ``truth`` value is their own (``truth``,
    ``labels``: (T,) ids of the same steps): 1 where every label holds one value of ``truth``;
    the purity of ``labels`` against ``truth`` (:func:`topomap.metrics.purity`)."""
    from sklearn.metrics.cluster import contingency_matrix

    truth = np.asarray(truth)
    table = contingency_matrix(truth, labels)  # rows: truth values, columns: labels
    return float(table.max(axis=0).sum() / truth.size)


def label_means(labels, values, n_labels: int) -> np.ndarray:
    """(n_labels, D): the mean of the rows of ``values`` ((T, D)) that carry each label
    (``labels``: (T,) ids in ``[0, n_labels)``), summed in step order; NaN for a label no row
    carries."""
    labels = np.asarray(labels, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)
    counts = np.bincount(labels, minlength=n_labels).astype(np.float64)
    sums = np.column_stack([np.bincount(labels, weights=values[:, k], minlength=n_labels)
                            for k in range(values.shape[1])])
    with np.errstate(invalid="ignore", divide="ignore"):
        return sums / counts[:, None]
