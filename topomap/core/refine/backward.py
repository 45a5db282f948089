"""The clone EM's backward pass: the scaled backward messages over the clone layout
(:class:`~topomap.core.refine.kernels.CloneTables`) and, in the same pass, the E-step's expected
transition counts and clone occupancy -- row by row on the row-major blocks, or column by column
on column-major copies of them where the steps' work is large next to the blocks."""

from __future__ import annotations

import numpy as np
from numba import njit

from .kernels import _clone_active, _widest

__all__ = ["COLUMN_PASS_WORK", "clone_backward_counts", "clone_counts_into"]

#: ``sum_t n(sym[t]) n(sym[t + 1])`` over a block array's size from which the backward pass runs
#: on column-major copies of the blocks (the copies cost about one pass over the array)
COLUMN_PASS_WORK = 10.0


@njit(cache=True)
def clone_backward_counts(tables, vals, alpha, log_c, counts, occupancy):
    """Scaled backward pass that accumulates the E-step statistics in place.

    ``counts`` (same layout as ``vals``) receives the expected transition counts
    ``sum_t P(x_t = i, x_{t+1} = j | data)`` and ``occupancy`` (S,) the expected number of steps
    spent in every clone.  ``alpha`` and ``log_c`` come from
    :func:`~topomap.core.refine.kernels.clone_forward` on the same model; clones with
    ``alpha = 0`` are skipped (their backward message is never needed).

    Two loop orders give the same bits (every sum is taken over the same terms in the same
    order): row by row (a step costs (active clones at t) x (active clones at t + 1)), or, where
    the blocks are large next to the steps' work, column by column on column-major copies of
    the blocks, which sums the messages of all clones of a step at once (vectorised).
    """
    return _backward(tables, vals, alpha, log_c, counts, occupancy, np.empty(vals.size),
                     np.empty(vals.size), True)


@njit(cache=True)
def clone_counts_into(tables, vals, alpha, log_c, counts, occupancy, vals_t, counts_t):
    """:func:`clone_backward_counts` into ``counts`` and ``occupancy`` set to zero first (the
    E-step's statistics alone), with ``vals_t`` and ``counts_t`` (the size of ``vals``) as the
    column pass's copies; arrays kept from one E-step to the next spare the page faults of new
    ones.  The same bits as :func:`clone_backward_counts` on zeros."""
    counts[:] = 0.0
    occupancy[:] = 0.0
    return _backward(tables, vals, alpha, log_c, counts, occupancy, vals_t, counts_t, False)


@njit(cache=True)
def _backward(tables, vals, alpha, log_c, counts, occupancy, vals_t, counts_t, accumulate):
    """The pass of :func:`clone_backward_counts`, the column pass's copies in ``vals_t`` and
    ``counts_t``; ``counts_t`` starts from ``counts`` (``accumulate``) or from zeros (``counts``
    then must be zero)."""
    sym, blk, start, boff, pos = tables
    work = 0
    for t in range(sym.size):
        if blk[t] >= 0:
            work += (pos[t + 1] - pos[t]) * (pos[t + 2] - pos[t + 1])
    if work < COLUMN_PASS_WORK * vals.size:
        return _backward_rows(tables, vals, alpha, log_c, counts, occupancy)
    rows = _block_rows(tables, boff.size - 1)
    _transpose_blocks(boff, rows, vals, vals_t, True)
    if accumulate:
        _transpose_blocks(boff, rows, counts, counts_t, True)
    else:
        counts_t[:] = 0.0
    _backward_columns(tables, vals_t, alpha, log_c, counts_t, occupancy)
    _transpose_blocks(boff, rows, counts_t, counts, False)
    return counts, occupancy


@njit(cache=True)
def _backward_rows(tables, vals, alpha, log_c, counts, occupancy):
    """:func:`clone_backward_counts` row by row on the row-major blocks."""
    sym, blk, start, boff, pos = tables
    width = _widest(start)
    beta, beta_next = np.zeros(width), np.zeros(width)
    act, act_next = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    n_next = 0
    for t in range(sym.size - 1, -1, -1):
        a0 = pos[t]
        n_act = _clone_active(alpha, a0, pos[t + 1] - a0, act)
        if blk[t] < 0:
            for k in range(n_act):
                beta[act[k]] = 1.0
        else:
            nn = pos[t + 2] - pos[t + 1]
            inv_c = np.exp(-log_c[t + 1])
            o = boff[blk[t]]
            for k in range(n_act):
                i = act[k]
                row = o + i * nn
                w = alpha[a0 + i] * inv_c
                acc = 0.0
                for kk in range(n_next):
                    j = act_next[kk]
                    v = vals[row + j] * beta_next[j]
                    acc += v
                    counts[row + j] += w * v
                beta[i] = acc * inv_c
        c0 = start[sym[t]]
        for k in range(n_act):
            i = act[k]
            occupancy[c0 + i] += alpha[a0 + i] * beta[i]
        beta, beta_next = beta_next, beta
        act, act_next = act_next, act
        n_next = n_act
    return counts, occupancy


@njit(cache=True)
def _backward_columns(tables, vals_t, alpha, log_c, counts_t, occupancy):
    """:func:`clone_backward_counts` column by column on column-major blocks (``vals_t``,
    ``counts_t``: block ``b``'s entry ``(i, j)`` at ``boff[b] + j * n(src_b) + i``).  Where at
    least half of a step's clones are active, every clone gets a message and a count (an
    inactive one's weight is 0, so its counts gain exactly 0, and its message is never read);
    elsewhere the active clones one by one."""
    sym, blk, start, boff, pos = tables
    width = _widest(start)
    beta, beta_next = np.zeros(width), np.zeros(width)
    act, act_next = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    w = np.empty(width)
    n_next = 0
    for t in range(sym.size - 1, -1, -1):
        a0 = pos[t]
        n = pos[t + 1] - a0
        n_act = _clone_active(alpha, a0, n, act)
        if blk[t] < 0:
            for k in range(n_act):
                beta[act[k]] = 1.0
        else:
            inv_c = np.exp(-log_c[t + 1])
            o = boff[blk[t]]
            if 2 * n_act < n:  # few active clones: one by one
                for k in range(n_act):
                    w[act[k]] = alpha[a0 + act[k]] * inv_c
                _sparse_columns(vals_t, counts_t, o, n, act[:n_act], act_next[:n_next], w,
                                beta_next, beta)
                for k in range(n_act):
                    beta[act[k]] *= inv_c
            else:
                for i in range(n):
                    w[i] = alpha[a0 + i] * inv_c
                    beta[i] = 0.0
                for kk in range(n_next):
                    j = act_next[kk]
                    bj = beta_next[j]
                    col = vals_t[o + j * n:o + (j + 1) * n]
                    cnt = counts_t[o + j * n:o + (j + 1) * n]
                    for i in range(n):
                        v = col[i] * bj
                        beta[i] += v
                        cnt[i] += w[i] * v
                for i in range(n):
                    beta[i] = beta[i] * inv_c
        c0 = start[sym[t]]
        for k in range(n_act):
            i = act[k]
            occupancy[c0 + i] += alpha[a0 + i] * beta[i]
        beta, beta_next = beta_next, beta
        act, act_next = act_next, act
        n_next = n_act
    return counts_t, occupancy


@njit(cache=True)
def _sparse_columns(vals_t, counts_t, o, n, act, act_next, w, beta_next, beta):
    """One step of :func:`_backward_columns` active clone by active clone (the row pass's loops
    on the column-major block at ``o`` with ``n`` rows, over the active clones ``act`` and
    ``act_next``); ``beta`` gets the unscaled sums."""
    for k in range(act.size):
        i = act[k]
        acc = 0.0
        for kk in range(act_next.size):
            j = act_next[kk]
            v = vals_t[o + j * n + i] * beta_next[j]
            acc += v
            counts_t[o + j * n + i] += w[i] * v
        beta[i] = acc


@njit(cache=True)
def _block_rows(tables, n_blocks):
    """Rows of every block (the clones of its source symbol; 0 for a block no step uses)."""
    sym, blk, start, _, _ = tables
    rows = np.zeros(n_blocks, dtype=np.int64)
    for t in range(sym.size):
        if blk[t] >= 0:
            rows[blk[t]] = start[sym[t] + 1] - start[sym[t]]
    return rows


@njit(cache=True)
def _transpose_blocks(boff, rows, src, dst, to_columns):
    """Copy every block of ``src`` into ``dst``, row-major to column-major (``to_columns``) or
    back."""
    for b in range(rows.size):
        o, n = boff[b], rows[b]
        if n == 0:
            continue
        nn = (boff[b + 1] - o) // n
        for i in range(n):
            for j in range(nn):
                if to_columns:
                    dst[o + j * n + i] = src[o + i * nn + j]
                else:
                    dst[o + i * nn + j] = src[o + j * n + i]
