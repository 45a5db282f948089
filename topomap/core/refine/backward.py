"""The E-step's backward pass on two threads, with the bits of the one-thread pass.

:func:`~topomap.core.refine.kernels.clone_backward_counts` does two jobs at every step, from the
last step back: the backward message ``beta_t`` (each clone's sum over the active clones of the
next step, in ascending order, times ``1 / c_{t+1}``) and the expected counts and occupancies
the message gives.  Only the messages depend on each other; a count entry gains exactly one term
at a step, ``(alpha_t[i] / c_{t+1}) * (vals[i, j] * beta_{t+1}[j])``, and an occupancy one,
``alpha_t[i] * beta_t[i]``.  So :func:`backward_counts_threaded` lets one thread compute the
messages in pieces of :data:`THREAD_CHUNK` steps (:func:`_messages`) while the other adds the
terms of the pieces already done (:func:`_tally`), piece after piece from the last step back:
every sum is taken over the same terms in the same order as in the one-thread pass, so the
counts and occupancies are the same bits.  Both kernels release the GIL; the threads are the
pool of :func:`topomap.core.split.threads.in_threads`.

:func:`backward_counts` is what the E-step calls: the two threads where ``NUMBA_NUM_THREADS``
allows two and the pass has work enough (:data:`THREAD_WORK`), the fused pass elsewhere.
"""

from __future__ import annotations

import threading

import numpy as np
from numba import njit

from ..split import threads
from .kernels import _block_rows, _clone_active, _transpose_blocks, _widest, clone_backward_counts

__all__ = ["backward_counts", "backward_counts_threaded", "pair_work", "THREAD_CHUNK",
           "THREAD_WORK", "THREAD_STEP_PAIRS"]

#: steps per piece handed from the message thread to the counting thread
THREAD_CHUNK = 512
#: clone pairs over all steps (:func:`pair_work`) from which the pass runs on two threads (the
#: fused pass takes about a millisecond there; handing the pieces over costs a tenth of that)
THREAD_WORK = 1_000_000
#: clone pairs per step (on average) from which the pass runs on two threads: with fewer, the
#: two threads took longer than the fused pass on an idle machine (pruned clones leave less
#: work than the pairs counted: the 8 x 6 room's passes of 216 and 706 pairs a step took 1.5x
#: as long, the 12 x 12 room's of 1,566 0.82x)
THREAD_STEP_PAIRS = 1000


@njit(cache=True)
def pair_work(tables):
    """``sum_t n(sym[t]) n(sym[t + 1])`` over the steps with a transition: the clone pairs the
    backward pass visits at most."""
    blk, pos = tables.blk, tables.pos
    work = 0
    for t in range(blk.size):
        if blk[t] >= 0:
            work += (pos[t + 1] - pos[t]) * (pos[t + 2] - pos[t + 1])
    return work


@njit(cache=True, nogil=True)
def _messages(tables, vals_t, alpha, log_c, betas, t_hi, t_lo):
    """The scaled backward messages of steps ``t_hi - 1`` down to ``t_lo`` into ``betas`` (laid
    out as ``alpha``; the messages of step ``t_hi`` are there already), summed as
    :func:`~topomap.core.refine.kernels.clone_backward_counts` sums them: over the active clones
    of the next step in ascending order, on column-major blocks ``vals_t``.  An inactive clone's
    entry is 0."""
    sym, blk, start, boff, pos = tables
    width = _widest(start)
    act, act_next = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    n_next = 0
    if t_hi < sym.size:
        n_next = _clone_active(alpha, pos[t_hi], pos[t_hi + 1] - pos[t_hi], act_next)
    for t in range(t_hi - 1, t_lo - 1, -1):
        a0 = pos[t]
        n = pos[t + 1] - a0
        n_act = _clone_active(alpha, a0, n, act)
        beta = betas[a0:a0 + n]
        beta[:] = 0.0
        if blk[t] < 0:
            for k in range(n_act):
                beta[act[k]] = 1.0
        else:
            nxt = betas[pos[t + 1]:pos[t + 2]]
            inv_c = np.exp(-log_c[t + 1])
            o = boff[blk[t]]
            if 2 * n_act < n:  # few active clones: one by one
                for k in range(n_act):
                    i = act[k]
                    acc = 0.0
                    for kk in range(n_next):
                        j = act_next[kk]
                        acc += vals_t[o + j * n + i] * nxt[j]
                    beta[i] = acc * inv_c
            else:
                for kk in range(n_next):
                    j = act_next[kk]
                    bj = nxt[j]
                    col = vals_t[o + j * n:o + (j + 1) * n]
                    for i in range(n):
                        beta[i] += col[i] * bj
                for i in range(n):
                    beta[i] = beta[i] * inv_c if alpha[a0 + i] > 0.0 else 0.0
        act, act_next = act_next, act
        n_next = n_act


@njit(cache=True, nogil=True)
def _tally(tables, vals, alpha, log_c, betas, counts, occupancy, t_hi, t_lo):
    """Add the terms of steps ``t_hi - 1`` down to ``t_lo`` to the row-major ``counts`` and to
    ``occupancy``, from the messages ``betas`` (:func:`_messages`; an inactive clone's is 0, so
    its terms are exactly 0 and every active pair of a step gets its one term)."""
    sym, blk, start, boff, pos = tables
    width = _widest(start)
    act = np.empty(width, dtype=np.int64)
    for t in range(t_hi - 1, t_lo - 1, -1):
        a0 = pos[t]
        n_act = _clone_active(alpha, a0, pos[t + 1] - a0, act)
        if blk[t] >= 0:
            nn = pos[t + 2] - pos[t + 1]
            nxt = betas[pos[t + 1]:pos[t + 2]]
            inv_c = np.exp(-log_c[t + 1])
            o = boff[blk[t]]
            for k in range(n_act):
                i = act[k]
                w = alpha[a0 + i] * inv_c
                row = counts[o + i * nn:o + (i + 1) * nn]
                vrow = vals[o + i * nn:o + (i + 1) * nn]
                for j in range(nn):
                    row[j] += w * (vrow[j] * nxt[j])
        c0 = start[sym[t]]
        for k in range(n_act):
            i = act[k]
            occupancy[c0 + i] += alpha[a0 + i] * betas[a0 + i]


def backward_counts(tables, vals, alpha, log_c, counts, occupancy):
    """:func:`~topomap.core.refine.kernels.clone_backward_counts` (the same arguments, the same
    bits): on two threads (:func:`backward_counts_threaded`) where
    :func:`~topomap.core.split.threads.n_threads` is at least 2 and the pass visits at least
    :data:`THREAD_WORK` clone pairs (:func:`pair_work`), :data:`THREAD_STEP_PAIRS` a step on
    average; else the fused one-thread pass."""
    if (threads.n_threads() < 2
            or pair_work(tables) < max(THREAD_WORK, THREAD_STEP_PAIRS * tables.sym.size)):
        return clone_backward_counts(tables, vals, alpha, log_c, counts, occupancy)
    return backward_counts_threaded(tables, vals, alpha, log_c, counts, occupancy)


def backward_counts_threaded(tables, vals, alpha, log_c, counts, occupancy,
                             chunk: int = THREAD_CHUNK):
    """:func:`~topomap.core.refine.kernels.clone_backward_counts` as two jobs handed to
    :func:`~topomap.core.split.threads.in_threads`: the messages, ``chunk`` steps at a time from
    the last step back, and the counts of every piece once its messages are done (on one
    thread the two jobs run one after the other, the messages first)."""
    T = tables.sym.size
    betas = np.empty(int(tables.pos[T]))
    edges = list(range(T, 0, -chunk)) + [0]
    pieces = list(zip(edges, edges[1:]))
    ready = [threading.Event() for _ in pieces]

    failed = []

    def messages():
        try:
            vals_t = np.empty(vals.size)
            _transpose_blocks(tables.boff, _block_rows(tables, tables.boff.size - 1), vals,
                              vals_t, True)
            for (hi, lo), done in zip(pieces, ready):
                _messages(tables, vals_t, alpha, log_c, betas, hi, lo)
                done.set()
        except BaseException as error:  # raised below, once the counting job has stopped too
            failed.append(error)
        finally:  # a failure must not leave the counting job waiting
            for done in ready:
                done.set()

    def tally():
        for (hi, lo), done in zip(pieces, ready):
            done.wait()
            if failed:
                return
            _tally(tables, vals, alpha, log_c, betas, counts, occupancy, hi, lo)

    threads.in_threads(lambda job: job(), [messages, tally])
    if failed:
        raise failed[0]
    return counts, occupancy
