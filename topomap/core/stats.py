"""Counts, entropies and one-pass statistics shared by both phases and the map.

Everything the method measures of the discrete model is a function of integer counts: how often
each state occurs, takes each action, and reaches each next state; entropies are in bits.  The
statistics over all T steps (observation models, distinct rows, Gaussian log-densities) make one
or two passes over the (T, D) observations and allocate O(D), O(M D) or O(chunk x M) memory, never
T x D.  Where a result is stored in ``map.json`` the compiled loops add the same numbers in the
same order as the plain numpy expressions (``np.add.at`` adds rows in step order; ``X.var(axis=0)``
of a C-contiguous array accumulates rows in step order), so the bytes never depend on which
implementation ran.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .exact import sparse_pairwise_sum

__all__ = ["xlogx", "weighted_entropy", "conditional_entropy", "sparse_conditional_entropy",
           "normalise", "episode_masks", "count_tables", "model_sums", "model_squares",
           "feature_variance", "observation_models", "distinct_rows", "log_density_chunks",
           "LOG2PI", "CHUNK_BYTES"]

LOG2PI = np.log(2 * np.pi)
#: size of the (rows x models) blocks of log-densities computed at once
CHUNK_BYTES = 32 * 2**20
_NEG_ZERO_BITS = np.uint64(1 << 63)
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


def count_tables(labels, actions, n_states: int, n_actions: int, has_next):
    """``(state_counts (S,), action_counts (S, A), transition_counts (S, A, S))`` of a labelling.

    Transitions ``(x_t, u_t) -> x_{t+1}`` are counted only where ``has_next[t]`` (inside episodes).
    """
    x, u, S, A = labels, actions, int(n_states), int(n_actions)
    state = np.bincount(x, minlength=S)
    action = np.bincount(x * A + u, minlength=S * A).reshape(S, A)
    t = np.flatnonzero(has_next)
    trans = np.bincount((x[t] * A + u[t]) * S + x[t + 1], minlength=S * A * S).reshape(S, A, S)
    return state, action, trans


# ---------------------------------------------------------------------- observation models
@njit(cache=True)
def model_sums(X, model, n_models):
    """``np.add.at(sums, model, X)`` with ``sums`` zero (M, D): per-model column sums in step order."""
    out = np.zeros((n_models, X.shape[1]))
    for t in range(X.shape[0]):
        m = model[t]
        for d in range(X.shape[1]):
            out[m, d] += X[t, d]
    return out


@njit(cache=True)
def model_squares(X, model, means):
    """``np.add.at(sq, model, (X - means[model]) ** 2)``: per-model squared residuals."""
    out = np.zeros(means.shape)
    for t in range(X.shape[0]):
        m = model[t]
        for d in range(X.shape[1]):
            r = X[t, d] - means[m, d]
            out[m, d] += r * r
    return out


@njit(cache=True)
def _column_var_rowwise(X):
    T, D = X.shape
    s = np.zeros(D)
    for t in range(T):
        for d in range(D):
            s[d] += X[t, d]
    mean = s / T
    q = np.zeros(D)
    for t in range(T):
        for d in range(D):
            r = X[t, d] - mean[d]
            q[d] += r * r
    return q / T


def feature_variance(X: np.ndarray) -> np.ndarray:
    """``X.var(axis=0)`` bit for bit, without the (T, D) temporary when X is C-contiguous."""
    if X.flags.c_contiguous and X.shape[1] >= 2:
        return _column_var_rowwise(X)
    return X.var(axis=0)


def _full_covariances(X, model, means, n_models, reg):
    """Per-model ``r.T @ r / n + reg * I`` exactly as the frozen code (one model's rows at a time)."""
    D = X.shape[1]
    order = np.argsort(model, kind="stable")
    bounds = np.searchsorted(model[order], np.arange(n_models + 1))
    cov = np.zeros((n_models, D, D))
    for m in range(n_models):
        r = X[order[bounds[m]:bounds[m + 1]]] - means[m]
        cov[m] = r.T @ r / max(len(r), 1) + reg * np.eye(D)
    return cov


def observation_models(X, model, n_models, covariance_type="diag", reg_covar=1e-3):
    """Gaussian of every model id: ``(means (M, D), covariances (M, D[, D]), counts (M,))``,
    the same floats as ``topomap.map.TopologicalMap.from_labels``."""
    T = X.shape[0]
    n_m = np.bincount(model, minlength=n_models).astype(np.float64)
    means = model_sums(X, model, n_models) / np.maximum(n_m, 1)[:, None]
    reg = reg_covar * float(np.mean(feature_variance(X))) if T > 1 else reg_covar
    reg = reg if reg > 0 else reg_covar
    if covariance_type == "diag":
        cov = model_squares(X, model, means) / np.maximum(n_m, 1)[:, None] + reg
    elif covariance_type == "full":
        cov = _full_covariances(X, model, means, n_models, reg)
    else:
        raise ValueError(f"covariance_type must be 'diag' or 'full', got {covariance_type!r}")
    return means, cov, n_m


# ---------------------------------------------------------------------- distinct rows
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


# ---------------------------------------------------------------------- log-densities
def _diag_terms(means, variances):
    """Matmul form of diagonal Gaussians: ``log N = X^2 @ a + X @ b + c``."""
    prec = 1.0 / variances
    c = -0.5 * ((means**2 * prec).sum(1) + np.log(variances).sum(1) + means.shape[1] * LOG2PI)
    return -0.5 * prec.T, (means * prec).T, c


def _full_terms(means, covariances):
    """Cholesky factors of the precisions and log-normalisers (as scikit-learn's mixtures)."""
    D = means.shape[1]
    chol = np.linalg.cholesky(covariances)
    prec_chol = np.linalg.inv(chol).transpose(0, 2, 1)
    log_det = -np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(1)
    return prec_chol, log_det - 0.5 * D * LOG2PI


def log_density_chunks(X, means, covariances, chunk_rows=None):
    """Yield ``(start, logp)`` with ``logp`` the (rows, M) Gaussian log-densities of the rows
    ``X[start:start + rows]`` under every model; blocks stay below :data:`CHUNK_BYTES`.

    Diagonal models use the matmul form ``X^2 @ (-1/(2 var)) + X @ (mu/var) + const``; full ones
    scikit-learn's ``(X - mu) @ prec_chol`` per model.  Relative to the direct form the result
    differs by rounding only (~1e-12 relative for data of unit scale).
    """
    T, M = X.shape[0], means.shape[0]
    rows = chunk_rows or max(1, CHUNK_BYTES // (8 * max(M, X.shape[1])))  # read at call time
    diag = covariances.ndim == 2
    terms = _diag_terms(means, covariances) if diag else _full_terms(means, covariances)
    for start in range(0, T, rows):
        Xc = X[start:start + rows]
        if diag:
            a, b, c = terms
            logp = (Xc * Xc) @ a + Xc @ b + c
        else:
            prec_chol, c = terms
            logp = np.empty((Xc.shape[0], M))
            for m in range(M):
                y = (Xc - means[m]) @ prec_chol[m]
                logp[:, m] = c[m] - 0.5 * np.einsum("ij,ij->i", y, y)
        yield start, logp
