"""Compiled kernels of the soft-evidence clone EM (:mod:`topomap.core.refine.soft`).

Model
-----
Clones ``0..S-1`` each belong to one symbol id (``clone_symbol``); the symbol *read* at step ``t``
(``read[t]``, the K-means symbol or GDS id phase 1 gave the step) is evidence about the clone, not
its identity: ``P(read = r | clone c) = emit[c, r]`` (``emit[c, r] = C[clone_symbol[c], r]``, C the
confusion matrix).  Transitions are dense, ``trans[u, i, j] = P(x' = j | x = i, u)``.  The first
step of an episode has the prior ``init[c]``.

Sparsity: the clones allowed at a step that reads ``r`` are the candidates
``cidx[cptr[r] : cptr[r + 1]]`` (the clones with ``emit[c, r] > 0``), so a step costs
(candidates at t) x (candidates at t + 1), not ``S^2``.  Per-step vectors are stored back to back
(step ``t`` owns ``pos[t] .. pos[t + 1] - 1``, one entry per candidate of ``read[t]``, see
:func:`soft_offsets`).  Forward messages are scaled at every step; ``log P = sum_t log c_t``.
Episodes: ``has_next[t]`` is False at an episode's last step (no transition leaves it).

Arguments are grouped in named tuples so that no kernel takes more than a few positional
parameters: :data:`SoftData` (the sequence), :data:`SoftModel` (probabilities, or their logs for
:func:`soft_viterbi`) and :data:`SoftStats` (the E-step's accumulators).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from .kernels import normalise_block, viterbi_buffers

__all__ = ["SoftData", "SoftModel", "SoftStats", "soft_offsets", "soft_forward",
           "soft_forward_read", "read_tables",
           "soft_backward", "soft_viterbi", "soft_candidates"]

SoftData = namedtuple("SoftData", ["read", "u", "has_next"])
"""``read`` (T,) int64 symbol read at every step, ``u`` (T,) int64 actions, ``has_next`` (T,) bool."""

SoftModel = namedtuple("SoftModel", ["trans", "emit", "init", "cptr", "cidx"])
"""``trans`` (A, S, S), ``emit`` (S, K), ``init`` (S,) float64 (or their logs), ``cptr`` (K + 1,)
and ``cidx`` int64: the candidate clones of every read symbol (CSR)."""

SoftStats = namedtuple("SoftStats", ["trans", "emit", "init"])
"""Expected counts: ``trans`` (A, S, S) transitions, ``emit`` (S, K) clone x read symbol
occupancy, ``init`` (S,) episode starts."""


def soft_candidates(emit):
    """CSR ``(cptr, cidx)`` of the clones with ``emit[c, r] > 0`` for every read symbol ``r``."""
    emit = np.asarray(emit)
    allowed = emit.T > 0
    cptr = np.concatenate([[0], np.cumsum(allowed.sum(axis=1))]).astype(np.int64)
    cidx = np.nonzero(allowed)[1].astype(np.int64)
    return cptr, cidx


@njit(cache=True)
def soft_offsets(data, model):
    """Offsets ``pos`` (T + 1,) of the per-step candidate vectors."""
    T = data.read.size
    pos = np.empty(T + 1, dtype=np.int64)
    pos[0] = 0
    for t in range(T):
        r = data.read[t]
        pos[t + 1] = pos[t] + model.cptr[r + 1] - model.cptr[r]
    return pos


@njit(cache=True)
def soft_forward(data, model, pos, prune):
    """Scaled forward pass: ``(alpha, log_c)``; ``alpha[pos[t] + k]`` is the filtered probability
    of candidate ``k`` of step ``t``, ``log_c`` (T,) the log scaling factors (their sum is the
    log-likelihood, episode starts included).  Filtered probabilities below ``prune`` become 0."""
    read, u, has_next = data.read, data.u, data.has_next
    trans, emit, cptr, cidx = model.trans, model.emit, model.cptr, model.cidx
    T = read.size
    alpha = np.zeros(pos[T])
    log_c = np.zeros(T)
    for t in range(T):
        a0 = pos[t]
        r = read[t]
        c0 = cptr[r]
        n = pos[t + 1] - a0
        if t == 0 or not has_next[t - 1]:
            for k in range(n):
                c = cidx[c0 + k]
                alpha[a0 + k] = model.init[c] * emit[c, r]
        else:
            p0 = pos[t - 1]
            _forward_sums(alpha, p0, a0, n, trans, u[t - 1], cidx, cptr[read[t - 1]], c0)
            for k in range(n):
                alpha[a0 + k] *= emit[cidx[c0 + k], r]
        log_c[t] = np.log(normalise_block(alpha, a0, n, prune))
    return alpha, log_c


def read_tables(model, clone_symbol, n_ids: int):
    """What :func:`soft_forward_read` needs of ``model``: ``to_symbol`` (A, S, n_ids), the
    transition mass from every clone into the clones of every symbol, and ``reads`` (n_ids,
    n_ids), the largest ``emit[c, r]`` over the clones ``c`` of symbol ``k`` at ``[k, r]``."""
    A, S = model.trans.shape[0], model.trans.shape[1]
    to_symbol = np.zeros((A, S, n_ids))
    for k in np.unique(clone_symbol):
        to_symbol[:, :, k] = model.trans[:, :, clone_symbol == k].sum(axis=2)
    reads = np.zeros((n_ids, model.emit.shape[1]))
    np.maximum.at(reads, clone_symbol, model.emit)
    return to_symbol, reads


@njit(cache=True)
def soft_forward_read(data, model, pos, prune, clone_symbol, tables, share):
    """:func:`soft_forward` where, at every step after an episode's first, the candidates of a
    symbol ``k`` are set to 0 when ``k``'s share of the step's evidence -- the predicted mass of
    its clones (``tables[0]``, :func:`read_tables`) times the largest chance one of them reads
    ``read[t]`` (``tables[1]``) -- is below ``share`` of the sum over the symbols: the
    confusions the forward message makes negligible are dropped, and the next step's sums and
    the backward pass skip their clones."""
    read, u, has_next = data.read, data.u, data.has_next
    trans, emit, cptr, cidx = model.trans, model.emit, model.cptr, model.cidx
    to_symbol, reads = tables
    T = read.size
    alpha, log_c = np.zeros(pos[T]), np.zeros(T)
    mass = np.zeros(reads.shape[0])
    for t in range(T):
        a0, r = pos[t], read[t]
        c0, n = cptr[r], pos[t + 1] - pos[t]
        if t == 0 or not has_next[t - 1]:
            for k in range(n):
                c = cidx[c0 + k]
                alpha[a0 + k] = model.init[c] * emit[c, r]
            log_c[t] = np.log(normalise_block(alpha, a0, n, prune))
            continue
        p0, q0, a = pos[t - 1], cptr[read[t - 1]], u[t - 1]
        mass[:] = 0.0
        for i in range(a0 - p0):
            ai = alpha[p0 + i]
            if ai != 0.0:
                ci = cidx[q0 + i]
                for k in range(mass.size):
                    mass[k] += ai * to_symbol[a, ci, k]
        bar = 0.0
        for k in range(mass.size):
            mass[k] *= reads[k, r]
            bar += mass[k]
        bar *= share
        _forward_sums(alpha, p0, a0, n, trans, a, cidx, q0, c0)
        for k in range(n):
            c = cidx[c0 + k]
            alpha[a0 + k] = alpha[a0 + k] * emit[c, r] if mass[clone_symbol[c]] >= bar else 0.0
        log_c[t] = np.log(normalise_block(alpha, a0, n, prune))
    return alpha, log_c


@njit(cache=True)
def _forward_sums(alpha, p0, a0, n, trans, a, cidx, q0, c0):
    """``alpha[a0 + k] += sum_i alpha[p0 + i] trans[a, cidx[q0 + i], cidx[c0 + k]]`` over the
    nonzero messages of the step before (rows as slices where the clones of the step are a
    run), in the order of ``i``: the sums of :func:`soft_forward` and :func:`soft_forward_read`."""
    lo = cidx[c0]
    if n > 0 and cidx[c0 + n - 1] - lo == n - 1:  # a run of clones: rows as slices
        # two rows of non-zero messages a pass: (out + a1 r1) + a2 r2 is the sum row by row,
        # bit for bit, and reads and writes out once for both (0.58x the forward pass's CPU
        # on the soft E-steps of gridroom 8x6 at 9.7 % misreads, seed 0: 72 candidates a step)
        out = alpha[a0:a0 + n]
        m = a0 - p0
        i = 0
        while i < m:
            a1 = alpha[p0 + i]
            if a1 == 0.0:
                i += 1
                continue
            i2 = i + 1
            while i2 < m and alpha[p0 + i2] == 0.0:
                i2 += 1
            r1 = trans[a, cidx[q0 + i], lo:lo + n]
            if i2 == m:
                for k in range(n):
                    out[k] += a1 * r1[k]
                return
            a2 = alpha[p0 + i2]
            r2 = trans[a, cidx[q0 + i2], lo:lo + n]
            for k in range(n):
                out[k] = (out[k] + a1 * r1[k]) + a2 * r2[k]
            i = i2 + 1
        return
    for i in range(a0 - p0):
        ai = alpha[p0 + i]
        if ai != 0.0:
            ci = cidx[q0 + i]
            for k in range(n):
                alpha[a0 + k] += ai * trans[a, ci, cidx[c0 + k]]


def soft_backward(data, model, pos, alpha, log_c, stats):
    """Scaled backward pass accumulating the E-step's expected counts into ``stats`` (in place):
    transitions ``P(x_t = i, x_{t+1} = j | data)``, clone x read-symbol occupancy and episode
    starts.  ``alpha``/``log_c`` come from :func:`soft_forward` on the same model; candidates with
    ``alpha = 0`` are skipped.

    Where every read symbol's candidates are a run of clones, the pass runs column by column on
    copies of ``trans`` and ``stats.trans`` with their last two axes swapped
    (:func:`_soft_backward_columns`): the messages of all candidates of a step are summed at
    once, over the same terms in the same order, so the counts are the same bits."""
    if not _runs_of_clones(model.cptr, model.cidx):
        return _soft_backward_rows(data, model, pos, alpha, log_c, stats)
    counts_t = _swap_last_axes(stats.trans)
    _soft_backward_columns(data, model._replace(trans=_swap_last_axes(model.trans)), pos, alpha,
                           log_c, stats._replace(trans=counts_t))
    stats.trans[...] = _swap_last_axes(counts_t)
    return stats


@njit(cache=True)
def _soft_backward_rows(data, model, pos, alpha, log_c, stats):
    """:func:`soft_backward` candidate by candidate (any candidate lists)."""
    read, u, has_next = data.read, data.u, data.has_next
    trans, emit, cptr, cidx = model.trans, model.emit, model.cptr, model.cidx
    T = read.size
    width = 0
    for r in range(cptr.size - 1):
        width = max(width, cptr[r + 1] - cptr[r])
    beta = np.zeros(width)
    beta_next = np.zeros(width)
    wnext = np.zeros(width)
    for t in range(T - 1, -1, -1):
        a0 = pos[t]
        r = read[t]
        c0 = cptr[r]
        n = pos[t + 1] - a0
        if not has_next[t]:
            for k in range(n):
                beta[k] = 1.0
        else:
            nn = pos[t + 2] - pos[t + 1]
            r2 = read[t + 1]
            q0 = cptr[r2]
            a = u[t]
            inv_c = np.exp(-log_c[t + 1])
            for kk in range(nn):
                if alpha[pos[t + 1] + kk] == 0.0:
                    wnext[kk] = 0.0
                else:
                    wnext[kk] = emit[cidx[q0 + kk], r2] * beta_next[kk]
            for k in range(n):
                ak = alpha[a0 + k]
                if ak == 0.0:
                    beta[k] = 0.0
                    continue
                ci = cidx[c0 + k]
                w = ak * inv_c
                acc = 0.0
                for kk in range(nn):
                    if wnext[kk] == 0.0:
                        continue
                    cj = cidx[q0 + kk]
                    v = trans[a, ci, cj] * wnext[kk]
                    acc += v
                    stats.trans[a, ci, cj] += w * v
                beta[k] = acc * inv_c
        start = t == 0 or not has_next[t - 1]
        for k in range(n):
            g = alpha[a0 + k] * beta[k]
            if g == 0.0:
                continue
            c = cidx[c0 + k]
            stats.emit[c, r] += g
            if start:
                stats.init[c] += g
        beta, beta_next = beta_next, beta
    return stats


@njit(cache=True)
def _runs_of_clones(cptr, cidx):
    """Whether the candidates of every read symbol are consecutive clones."""
    for r in range(cptr.size - 1):
        n = cptr[r + 1] - cptr[r]
        if n > 0 and cidx[cptr[r + 1] - 1] - cidx[cptr[r]] != n - 1:
            return False
    return True


@njit(cache=True)
def _swap_last_axes(x):
    """A contiguous copy of ``x`` (A, S, S) with ``[a, j, i] = x[a, i, j]``."""
    out = np.empty((x.shape[0], x.shape[2], x.shape[1]))
    for a in range(x.shape[0]):
        for i in range(x.shape[1]):
            for j in range(x.shape[2]):
                out[a, j, i] = x[a, i, j]
    return out


@njit(cache=True)
def _soft_backward_columns(data, model_t, pos, alpha, log_c, stats_t):
    """:func:`soft_backward` where every candidate list is a run of clones, on ``model_t.trans``
    and ``stats_t.trans`` with their last two axes swapped.  A candidate with ``alpha = 0`` has
    weight 0 (its counts gain exactly 0) and its message is set to 0 afterwards."""
    read, u, has_next = data.read, data.u, data.has_next
    trans_t, emit, cptr, cidx = model_t.trans, model_t.emit, model_t.cptr, model_t.cidx
    width = 0
    for r in range(cptr.size - 1):
        width = max(width, cptr[r + 1] - cptr[r])
    beta, beta_next, wnext, w = np.zeros(width), np.zeros(width), np.zeros(width), np.zeros(width)
    for t in range(read.size - 1, -1, -1):
        a0, r = pos[t], read[t]
        c0, n = cptr[r], pos[t + 1] - a0
        if not has_next[t]:
            beta[:n] = 1.0
        else:
            nn, r2, a = pos[t + 2] - pos[t + 1], read[t + 1], u[t]
            q0, lo = cptr[r2], cidx[c0]
            inv_c = np.exp(-log_c[t + 1])
            for kk in range(nn):
                wnext[kk] = (0.0 if alpha[pos[t + 1] + kk] == 0.0
                             else emit[cidx[q0 + kk], r2] * beta_next[kk])
            for k in range(n):
                w[k] = alpha[a0 + k] * inv_c
                beta[k] = 0.0
            for kk in range(nn):
                wj = wnext[kk]
                if wj == 0.0:
                    continue
                cj = cidx[q0 + kk]
                col = trans_t[a, cj, lo:lo + n]
                cnt = stats_t.trans[a, cj, lo:lo + n]
                for k in range(n):
                    v = col[k] * wj
                    beta[k] += v
                    cnt[k] += w[k] * v
            for k in range(n):
                beta[k] = 0.0 if alpha[a0 + k] == 0.0 else beta[k] * inv_c
        _soft_occupancy(alpha, a0, beta, cidx, c0, n, r, t == 0 or not has_next[t - 1], stats_t)
        beta, beta_next = beta_next, beta
    return stats_t


@njit(cache=True)
def _soft_occupancy(alpha, a0, beta, cidx, c0, n, r, start, stats):
    """Add a step's candidate posteriors to ``stats.emit`` (and ``stats.init`` at a start)."""
    for k in range(n):
        g = alpha[a0 + k] * beta[k]
        if g == 0.0:
            continue
        c = cidx[c0 + k]
        stats.emit[c, r] += g
        if start:
            stats.init[c] += g


@njit(cache=True)
def _soft_viterbi_step(delta, out, arg, trans_a, emit_r, cidx, q0, m, c0, n):
    """One step of :func:`soft_viterbi`: ``out[k]`` the best over the ``m`` candidates before
    (scores ``delta``, clones ``cidx[q0:q0 + m]``) of ``delta[i] + trans_a[i's clone, k's
    clone]``, plus ``emit_r[k's clone]``, ``arg[k]`` the first ``i`` reaching it, for the ``n``
    candidates of the step (clones ``cidx[c0:c0 + n]``)."""
    lo = cidx[c0]
    if n > 0 and cidx[c0 + n - 1] - lo == n - 1:
        # a run of clones: the rows as slices, every candidate's best over the candidates
        # before taken row by row (the same comparisons in the same order)
        best_next = out[:n]
        best_next[:] = -np.inf
        arg[:] = 0
        for i in range(m):
            di = delta[i]
            row = trans_a[cidx[q0 + i], lo:lo + n]
            for k in range(n):
                v = di + row[k]
                if v > best_next[k]:
                    best_next[k] = v
                    arg[k] = i
        for k in range(n):
            best_next[k] += emit_r[cidx[c0 + k]]
        return
    for k in range(n):
        cj = cidx[c0 + k]
        best, arg_k = -np.inf, 0
        for i in range(m):
            v = delta[i] + trans_a[cidx[q0 + i], cj]
            if v > best:
                best, arg_k = v, i
        out[k] = best + emit_r[cj]
        arg[k] = arg_k


@njit(cache=True)
def soft_viterbi(data, log_model, pos):
    """Most probable clone sequence under ``log_model`` (a :data:`SoftModel` holding
    ``log(trans)``, ``log(emit)``, ``log(init)``; the candidate lists as usual).  Returns
    ``(path, log_p)``: global clone ids (T,) and the summed log-probability of every episode's
    best path (ties go to the earliest candidate)."""
    read, u, has_next = data.read, data.u, data.has_next
    trans, emit, cptr, cidx = log_model.trans, log_model.emit, log_model.cptr, log_model.cidx
    T = read.size
    psi, delta, delta_next, path = viterbi_buffers(cptr, pos, T)
    log_p = 0.0
    t0 = 0
    for t in range(T):
        r = read[t]
        c0 = cptr[r]
        n = pos[t + 1] - pos[t]
        if t == t0:
            for k in range(n):
                c = cidx[c0 + k]
                delta[k] = log_model.init[c] + emit[c, r]
        else:
            _soft_viterbi_step(delta, delta_next, psi[pos[t]:pos[t] + n], trans[u[t - 1]],
                               emit[:, r], cidx, cptr[read[t - 1]], pos[t] - pos[t - 1], c0, n)
            delta, delta_next = delta_next, delta
        if not has_next[t]:
            best = 0
            for k in range(1, n):
                if delta[k] > delta[best]:
                    best = k
            log_p += delta[best]
            k = best
            for s in range(t, t0 - 1, -1):
                path[s] = cidx[cptr[read[s]] + k]
                if s > t0:
                    k = psi[pos[s] + k]
            t0 = t + 1
    return path, log_p
