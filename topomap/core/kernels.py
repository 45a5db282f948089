"""Compiled kernels: inference on a learned map, and EM on clone-structured models.

Inference on a map (``*_chunk``): forward (score, filter) and Viterbi (predict) over sparse,
smoothed transitions.

The smoothed transition matrix of action ``a`` is

    T_a[i, j] = (1 - eps) P_a[i, j] + eps / S      (a row seen in training)
    T_a[i, j] = (1 - eps) / S + eps / S            (a row never seen: P_a uniform)

so it is a sparse matrix (the seen transitions, CSR over rows ``i * A + a``) plus row-constant
terms.  One step of the forward recursion then costs O(S + non-zeros of the rows in use) instead
of the O(S^2) ``exp`` and product of the dense code, and the Viterbi maximum over the zero entries
of a column is the largest ``delta`` plus ``log(eps / S)`` (taken from the smallest such index,
exactly as ``np.argmax`` breaks ties).

Emission pruning: at every step the states whose emission log-density (observation plus action
term) lies more than ``prune`` nats below the step's best are skipped.  Every smoothed transition
is at least ``eps / S``, so with ``prune > 2 log(S / eps)`` a pruned state can neither be on the
Viterbi path nor be the best predecessor of a kept state (the Viterbi result is then exact), and
in the forward pass it carries at most ``exp(-prune) * S / eps`` of a step's likelihood.
:func:`prune_threshold` adds a 50-nat margin to that bound (``exp(-50) ~ 2e-22``).

Episodes: ``is_start[t]`` marks the first step of an episode; the recursion restarts there from
the initial distribution.  All kernels work on one chunk of steps at a time and carry their state
(``alpha`` / ``delta`` and the list of live states) between chunks, so memory does not grow with T.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["prune_threshold", "emissions", "forward_chunk", "filter_chunk", "viterbi_chunk",
           "backtrack_chunk", "clone_step_offsets", "clone_forward", "clone_backward_counts",
           "clone_viterbi", "clone_path_counts", "clone_normalize_blocks"]


def prune_threshold(n_states: int, smoothing: float, margin: float = 50.0) -> float:
    """Pruning distance in nats that keeps Viterbi exact and forward errors below ``exp(-margin)``."""
    return 2.0 * np.log(n_states / smoothing) + margin


@njit(cache=True)
def emissions(logp_row, log_act, model, state_gds, u_t, g_t, prune, out, live):
    """Per-state emission log-weights of one step into ``out``; the indices of the states within
    ``prune`` of the best into ``live``.  ``g_t`` -2: no GDS clamp, -1: a non-GDS step, >= 0: that
    GDS.  Returns ``(best, n_live)``."""
    S = out.size
    best = -np.inf
    for j in range(S):
        gj = state_gds[j]
        ok = g_t == -2 or (g_t == -1 and gj < 0) or (g_t >= 0 and gj == g_t)
        out[j] = logp_row[model[j]] + log_act[j, u_t] if ok else -np.inf
        if out[j] > best:
            best = out[j]
    n_live = 0
    for j in range(S):
        if out[j] > -np.inf and out[j] >= best - prune:
            live[n_live] = j
            n_live += 1
        else:
            out[j] = -np.inf
    return best, n_live


@njit(cache=True)
def _predict_forward(alpha, live, n_live, a, A, indptr, indices, data, seen, eps_s, uni, pred):
    """``pred = alpha @ T_a`` for a normalised ``alpha`` that is zero outside ``live``."""
    unseen_mass = 0.0
    pred[:] = 0.0
    for k in range(n_live):
        i = live[k]
        r = i * A + a
        if not seen[r]:
            unseen_mass += alpha[i]
            continue
        for p in range(indptr[r], indptr[r + 1]):
            pred[indices[p]] += alpha[i] * data[p]
    base = eps_s + uni * unseen_mass
    for j in range(pred.size):
        pred[j] += base


@njit(cache=True)
def forward_chunk(logp, u, g, is_start, log_act, model, state_gds, init, indptr, indices, data,
                  seen, eps_s, uni, prune, alpha, live, n_live, prev_action):
    """Scaled forward pass over one chunk.  ``alpha``/``live``/``n_live``/``prev_action`` carry the
    state between chunks.  Returns ``(sum of log-likelihood increments, n_live, prev_action)``."""
    S, A = alpha.size, log_act.shape[1]
    e = np.empty(S)
    pred = np.empty(S)
    new_live = np.empty(S, dtype=np.int64)
    total = 0.0
    for t in range(logp.shape[0]):
        best, n_new = emissions(logp[t], log_act, model, state_gds, u[t], g[t], prune, e, new_live)
        if is_start[t]:
            pred[:] = init
        else:
            _predict_forward(alpha, live, n_live, prev_action, A, indptr, indices, data, seen,
                             eps_s, uni, pred)
        c = 0.0
        alpha[:] = 0.0
        for k in range(n_new):
            j = new_live[k]
            alpha[j] = pred[j] * np.exp(e[j] - best)
            c += alpha[j]
        for k in range(n_new):
            alpha[new_live[k]] /= c
        live[:n_new] = new_live[:n_new]
        n_live = n_new
        total += np.log(c) + best
        prev_action = u[t]
    return total, n_live, prev_action


@njit(cache=True)
def _argmax_live(delta, live, n_live):
    """Largest ``delta`` over the live states, smallest index on ties (as ``np.argmax``)."""
    best, arg = -np.inf, live[0]
    for k in range(n_live):
        if delta[live[k]] > best:
            best, arg = delta[live[k]], live[k]
    return best, arg


@njit(cache=True)
def _argmax_unseen(delta, live, n_live, seen, a, A):
    """Largest ``delta`` over the live states whose row ``(i, a)`` was never seen (uniform
    transitions), smallest index on ties; index -1 when there is none."""
    best, arg = -np.inf, -1
    for k in range(n_live):
        i = live[k]
        if not seen[i * A + a] and (arg < 0 or delta[i] > best):
            best, arg = delta[i], i
    return best, arg


@njit(cache=True)
def _predict_viterbi(delta, live, n_live, a, A, indptr, indices, logdata, seen, log_eps_s,
                     log_uni, best, arg):
    """``best[j] = max_i delta[i] + log T_a[i, j]`` and its smallest argmax ``arg[j]``."""
    best[:] = -np.inf
    arg[:] = -1
    for k in range(n_live):  # live is sorted: increasing i, so '>' keeps the smallest index
        i = live[k]
        r = i * A + a
        if seen[r]:
            for p in range(indptr[r], indptr[r + 1]):
                v = delta[i] + logdata[p]
                j = indices[p]
                if v > best[j] or arg[j] < 0:
                    best[j], arg[j] = v, i
    m0, i0 = _argmax_live(delta, live, n_live)
    m1, i1 = _argmax_unseen(delta, live, n_live, seen, a, A)
    for j in range(best.size):
        v0 = m0 + log_eps_s  # a zero entry of a seen row (or dominated by that row's own entry)
        if v0 > best[j] or (v0 == best[j] and i0 < arg[j]) or arg[j] < 0:
            best[j], arg[j] = v0, i0
        if i1 >= 0:
            v1 = m1 + log_uni
            if v1 > best[j] or (v1 == best[j] and i1 < arg[j]):
                best[j], arg[j] = v1, i1


@njit(cache=True)
def viterbi_chunk(logp, u, g, is_start, is_end, log_act, model, state_gds, log_init, indptr,
                  indices, logdata, seen, log_eps_s, log_uni, prune, delta, live, n_live,
                  prev_action, back, end_state):
    """Viterbi recursion over one chunk (log space).  ``delta``/``live``/``n_live``/``prev_action``
    carry the state between chunks.  With ``back.shape[0] > 0`` the best predecessor of every
    state at every step is written to ``back`` and, at the last step of an episode, the best
    final state to ``end_state``.  Returns ``(n_live, prev_action)``."""
    S, A = delta.size, log_act.shape[1]
    e = np.empty(S)
    best = np.empty(S)
    arg = np.empty(S, dtype=np.int64)
    new_live = np.empty(S, dtype=np.int64)
    store = back.shape[0] > 0
    for t in range(logp.shape[0]):
        _, n_new = emissions(logp[t], log_act, model, state_gds, u[t], g[t], prune, e, new_live)
        if is_start[t]:
            best[:] = log_init
        else:
            _predict_viterbi(delta, live, n_live, prev_action, A, indptr, indices, logdata, seen,
                             log_eps_s, log_uni, best, arg)
            if store:
                back[t, :] = arg
        for k in range(n_new):
            j = new_live[k]
            delta[j] = best[j] + e[j]
        live[:n_new] = new_live[:n_new]
        n_live = n_new
        if store and is_end[t]:
            end_state[t] = _argmax_live(delta, live, n_live)[1]
        prev_action = u[t]
    return n_live, prev_action


@njit(cache=True)
def backtrack_chunk(back, is_start, is_end, end_state, carry, path):
    """Fill ``path`` (one chunk) backwards from ``carry``, the state of the chunk's last step when
    that step is not an episode end.  Returns the state of the step before the chunk."""
    s = carry
    for t in range(path.size - 1, -1, -1):
        if is_end[t]:
            s = end_state[t]
        path[t] = s
        if not is_start[t]:
            s = back[t, s]
    return s


@njit(cache=True)
def filter_chunk(logp, u, g, is_start, log_act, model, state_gds, init, indptr, indices, data,
                 seen, eps_s, uni, prune, alpha, live, n_live, prev_action, out):
    """Forward filtering over one chunk: ``out[t]`` is the belief ``P(x_t | o_1..o_t,
    u_1..u_{t-1})`` (the step's action, chosen after it, is not evidence yet).  ``alpha`` carries
    the belief times ``P(u_t|x)`` between steps and chunks; arguments as :func:`forward_chunk`.
    Returns ``(n_live, prev_action)``."""
    S = alpha.size
    A = log_act.shape[1]
    no_act = np.zeros((S, 1))
    e = np.empty(S)
    pred = np.empty(S)
    new_live = np.empty(S, dtype=np.int64)
    for t in range(logp.shape[0]):
        best, n_new = emissions(logp[t], no_act, model, state_gds, 0, g[t], prune, e, new_live)
        if is_start[t]:
            pred[:] = init
        else:
            _predict_forward(alpha, live, n_live, prev_action, A, indptr, indices, data, seen,
                             eps_s, uni, pred)
        out[t, :] = 0.0
        c = 0.0
        for k in range(n_new):
            j = new_live[k]
            out[t, j] = pred[j] * np.exp(e[j] - best)
            c += out[t, j]
        c_act = 0.0
        alpha[:] = 0.0
        for k in range(n_new):
            j = new_live[k]
            out[t, j] /= c
            alpha[j] = out[t, j] * np.exp(log_act[j, u[t]])
            c_act += alpha[j]
        for k in range(n_new):
            alpha[new_live[k]] /= c_act
        live[:n_new] = new_live[:n_new]
        n_live = n_new
        prev_action = u[t]
    return n_live, prev_action


# ======================================================================================
# Clone-structured, action-conditioned HMMs (the refinement phase, topomap.core.clones)
# ======================================================================================
# Model
# -----
# Every hidden state (a *clone*) emits exactly one discrete symbol.  Clones are numbered so that the
# clones of symbol ``k`` are ``start[k] .. start[k + 1] - 1``.  At step ``t`` the symbol ``sym[t]``
# is observed, so only its clones can be occupied, and the transition ``t -> t + 1`` under action
# ``u[t]`` only involves the clones of ``sym[t]`` (rows) and of ``sym[t + 1]`` (columns).
#
# Sparse transition storage
# -------------------------
# Transitions are stored as dense *blocks*, one per ``(action, symbol, next symbol)`` triple that
# occurs in the data: block ``b`` is an ``n(src) x n(dst)`` row-major matrix at
# ``vals[boff[b] : boff[b + 1]]``, where ``n(k) = start[k + 1] - start[k]``.  ``blk[t]`` is the block
# of the transition ``t -> t + 1``, or ``-1`` when step ``t`` ends its episode (no transition crosses
# an episode boundary).  Memory is ``sum_b n(src_b) n(dst_b)``, a small fraction of the dense
# ``S x A x S`` tensor when clones are many and each symbol is followed by few symbols.
#
# What a block entry means (``P(x'|x,u)`` or the joint ``P(u,x'|x)``) is up to the caller: the
# kernels only need ``vals[b][i, j]`` to be the factor of moving from clone ``i`` of ``src_b`` to
# clone ``j`` of ``dst_b`` at a step with that block.
#
# Conventions
# -----------
# * The first step of every episode has a uniform distribution over the clones of its symbol; all
#   likelihoods are conditional on the first symbol of each episode.
# * Forward messages are normalised at every step (scaling factors ``c_t``), so
#   ``log P = sum_t log c_t`` never underflows however long the sequence is.
# * Per-step vectors are stored back to back in one flat array: the vector of step ``t`` starts at
#   ``pos[t]`` (see :func:`clone_step_offsets`).
#
# All arrays are contiguous ``int64`` / ``float64``; no Python objects are used inside the kernels.


@njit(cache=True)
def clone_step_offsets(sym, start):
    """Offsets ``pos`` (T + 1,) of the per-step clone vectors: step ``t`` owns
    ``pos[t] .. pos[t + 1] - 1``, one entry per clone of ``sym[t]``."""
    T = sym.size
    pos = np.empty(T + 1, dtype=np.int64)
    pos[0] = 0
    for t in range(T):
        k = sym[t]
        pos[t + 1] = pos[t] + start[k + 1] - start[k]
    return pos


@njit(cache=True)
def clone_forward(sym, blk, start, boff, vals, pos, prune):
    """Scaled forward pass.

    Returns ``(alpha, log_c)``: ``alpha`` (pos[-1],) holds the filtered distribution
    ``P(x_t | s_1..s_t, u_1..u_{t-1})`` of every step over the clones of ``sym[t]``; ``log_c`` (T,)
    the log scaling factors, whose sum is the log-likelihood (0 at episode starts).  Filtered
    probabilities below ``prune`` are set to exactly 0 (0: exact inference), which lets both passes
    skip the clones a confident model has ruled out.  A step the model gives probability zero
    yields ``log_c = -inf`` and a zero message.
    """
    T = sym.size
    alpha = np.zeros(pos[T])
    log_c = np.zeros(T)
    for t in range(T):
        a0 = pos[t]
        n = pos[t + 1] - a0
        if t == 0 or blk[t - 1] < 0:
            for j in range(n):
                alpha[a0 + j] = 1.0 / n
            continue
        p0 = pos[t - 1]
        o = boff[blk[t - 1]]
        for i in range(a0 - p0):
            ai = alpha[p0 + i]
            if ai == 0.0:
                continue
            row = o + i * n
            for j in range(n):
                alpha[a0 + j] += ai * vals[row + j]
        c = 0.0
        for j in range(n):
            c += alpha[a0 + j]
        if c > 0.0:
            for j in range(n):
                a = alpha[a0 + j] / c
                alpha[a0 + j] = a if a >= prune else 0.0
        log_c[t] = np.log(c)
    return alpha, log_c


@njit(cache=True)
def _clone_active(alpha, a0, n, out):
    """Write the local indices ``j < n`` with ``alpha[a0 + j] > 0`` into ``out``; return how many."""
    k = 0
    for j in range(n):
        if alpha[a0 + j] > 0.0:
            out[k] = j
            k += 1
    return k


@njit(cache=True)
def clone_backward_counts(sym, blk, start, boff, vals, pos, alpha, log_c, counts, occupancy):
    """Scaled backward pass that accumulates the E-step statistics in place.

    ``counts`` (same layout as ``vals``) receives the expected transition counts
    ``sum_t P(x_t = i, x_{t+1} = j | data)`` and ``occupancy`` (S,) the expected number of steps
    spent in every clone.  ``alpha`` and ``log_c`` come from :func:`clone_forward` on the same model;
    clones with ``alpha = 0`` are skipped (their backward message is never needed), so a step
    costs (active clones at t) x (active clones at t + 1).
    """
    width = 0
    for k in range(start.size - 1):
        width = max(width, start[k + 1] - start[k])
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
def _clone_backtrace(psi, pos, start, sym, t0, t1, last, path):
    """Write the best path of steps ``t0 .. t1`` (inclusive) ending in local clone ``last``."""
    k = last
    for t in range(t1, t0 - 1, -1):
        path[t] = start[sym[t]] + k
        if t > t0:
            k = psi[pos[t] + k]


@njit(cache=True)
def clone_viterbi(sym, blk, start, boff, log_vals, pos):
    """Most probable clone sequence (max-product in log space; ties go to the lowest clone).

    ``log_vals`` is ``log(vals)`` (``-inf`` for zeros).  Returns ``(path, log_p)``: ``path`` (T,)
    global clone ids and ``log_p`` the summed log-probability of the best path of every episode,
    including the uniform start ``-log n(sym[t0])``.
    """
    T = sym.size
    psi = np.zeros(pos[T], dtype=np.int64)
    width = 0
    for k in range(start.size - 1):
        width = max(width, start[k + 1] - start[k])
    delta = np.empty(width)
    delta_next = np.empty(width)
    path = np.empty(T, dtype=np.int64)
    log_p = 0.0
    t0 = 0
    for t in range(T):
        n = pos[t + 1] - pos[t]
        if t == t0:
            for j in range(n):
                delta[j] = -np.log(n)
        else:
            m = pos[t] - pos[t - 1]
            o = boff[blk[t - 1]]
            for j in range(n):
                delta_next[j] = -np.inf
                psi[pos[t] + j] = 0
            for i in range(m):
                di = delta[i]
                if di == -np.inf:
                    continue
                row = o + i * n
                for j in range(n):
                    v = di + log_vals[row + j]
                    if v > delta_next[j]:
                        delta_next[j] = v
                        psi[pos[t] + j] = i
            delta, delta_next = delta_next, delta
        if blk[t] < 0:
            best = 0
            for j in range(1, n):
                if delta[j] > delta[best]:
                    best = j
            log_p += delta[best]
            _clone_backtrace(psi, pos, start, sym, t0, t, best, path)
            t0 = t + 1
    return path, log_p


@njit(cache=True)
def clone_path_counts(path, sym, blk, start, boff, counts):
    """Add the transitions of a hard clone path to ``counts`` (layout of ``vals``), in place."""
    for t in range(sym.size):
        b = blk[t]
        if b < 0:
            continue
        s, s2 = sym[t], sym[t + 1]
        nn = start[s2 + 1] - start[s2]
        counts[boff[b] + (path[t] - start[s]) * nn + (path[t + 1] - start[s2])] += 1.0
    return counts


@njit(cache=True)
def clone_normalize_blocks(counts, bsrc, bdst, bkey, n_keys, start, boff, pseudocount, smooth):
    """M-step: turn counts into block probabilities.

    Rows are grouped by a *row key*: row ``i`` of block ``b`` belongs to group
    ``(bkey[b], start[bsrc[b]] + i)`` -- for ``P(x'|x,u)`` the key is the action, for the joint
    ``P(u,x'|x)`` it is 0 for all blocks.  Every stored entry becomes
    ``(count + pseudocount) / Z`` with ``Z = (group's count total) + smooth``; ``smooth`` stands for
    the pseudocount mass of all entries that are not stored (``pseudocount`` times the number of
    columns of a dense row).  Rows with ``Z = 0`` become 0.  Returns ``(vals, Z)``, ``Z`` of shape
    ``(n_keys, S)``.
    """
    S = start[start.size - 1]
    Z = np.zeros((n_keys, S))
    B = bsrc.size
    for b in range(B):
        c0 = start[bsrc[b]]
        n = start[bsrc[b] + 1] - c0
        nn = start[bdst[b] + 1] - start[bdst[b]]
        for i in range(n):
            acc = 0.0
            for j in range(nn):
                acc += counts[boff[b] + i * nn + j]
            Z[bkey[b], c0 + i] += acc
    for key in range(n_keys):
        for x in range(S):
            Z[key, x] += smooth
    vals = np.zeros(counts.size)
    for b in range(B):
        c0 = start[bsrc[b]]
        n = start[bsrc[b] + 1] - c0
        nn = start[bdst[b] + 1] - start[bdst[b]]
        for i in range(n):
            z = Z[bkey[b], c0 + i]
            if z <= 0.0:
                continue
            row = boff[b] + i * nn
            for j in range(nn):
                vals[row + j] = (counts[row + j] + pseudocount) / z
    return vals, Z
