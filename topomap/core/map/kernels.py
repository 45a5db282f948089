"""Compiled kernels of inference on a learned map: forward (score, filter) and Viterbi (predict)
over sparse, smoothed transitions, one chunk of steps at a time (``*_chunk``).

The tables the kernels share come as named tuples: :class:`Steps` (one chunk's actions, GDS
labels and episode marks), :class:`StateTables` (the per-state terms) and :class:`Transitions`
(the smoothed transitions), all made by :func:`topomap.core.map.inference.setup`.

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

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["Steps", "StateTables", "Transitions", "prune_threshold", "emissions",
           "predict_forward", "forward_chunk", "filter_chunk", "viterbi_chunk", "backtrack_chunk"]


class Steps(NamedTuple):
    """Per-step inputs of a chunk (or of a whole sequence)."""

    u: np.ndarray  # (T,) int64 action of every step
    g: np.ndarray  # (T,) int64 GDS of every step: -2 no GDS labels at all, -1 none, >= 0 that GDS
    is_start: np.ndarray  # (T,) bool: the first step of an episode
    is_end: np.ndarray  # (T,) bool: the last step of an episode


class StateTables(NamedTuple):
    """Per-state terms of the recursions (smoothed as :func:`~topomap.core.map.inference.setup`
    says)."""

    log_act: np.ndarray  # (S, A) log P(u|x)
    model: np.ndarray  # (S,) int64 observation model of each state (a column of the densities)
    state_gds: np.ndarray  # (S,) int64 GDS id of each state, -1 for ordinary states
    init: np.ndarray  # (S,) initial distribution of an episode
    log_init: np.ndarray  # (S,) its log
    prune: float  # pruning distance in nats (inf: no pruning)


class Transitions(NamedTuple):
    """The smoothed transitions (see above): the seen ones as CSR over rows ``i * A + a``."""

    indptr: np.ndarray  # (S * A + 1,) int64
    indices: np.ndarray  # next state of every seen transition
    data: np.ndarray  # its (1 - eps) P
    logdata: np.ndarray  # log((1 - eps) P + eps / S)
    seen: np.ndarray  # (S * A,) bool: whether row i * A + a was seen in training
    n_actions: int  # A
    eps_s: float  # eps / S
    uni: float  # (1 - eps) / S
    log_eps_s: float  # log(eps / S)
    log_uni: float  # log((1 - eps) / S + eps / S)


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
def predict_forward(alpha, live, n_live, a, trans, pred):
    """``pred = alpha @ T_a`` for a normalised ``alpha`` that is zero outside ``live``
    (``trans``: :class:`Transitions`)."""
    indptr, indices, data, seen = trans.indptr, trans.indices, trans.data, trans.seen
    unseen_mass = 0.0
    pred[:] = 0.0
    for k in range(n_live):
        i = live[k]
        r = i * trans.n_actions + a
        if not seen[r]:
            unseen_mass += alpha[i]
            continue
        for p in range(indptr[r], indptr[r + 1]):
            pred[indices[p]] += alpha[i] * data[p]
    base = trans.eps_s + trans.uni * unseen_mass
    for j in range(pred.size):
        pred[j] += base


@njit(cache=True)
def forward_chunk(logp, steps, tables, trans, alpha, live, n_live, prev_action):
    """Scaled forward pass over one chunk: ``logp`` its (rows, models) log-densities, ``steps``
    its :class:`Steps`, ``tables`` the :class:`StateTables`, ``trans`` the :class:`Transitions`.
    ``alpha``/``live``/``n_live``/``prev_action`` carry the state between chunks.  Returns
    ``(sum of log-likelihood increments, n_live, prev_action)``."""
    u, g, is_start = steps.u, steps.g, steps.is_start
    log_act, model, state_gds, prune = tables.log_act, tables.model, tables.state_gds, tables.prune
    S = alpha.size
    e = np.empty(S)
    pred = np.empty(S)
    new_live = np.empty(S, dtype=np.int64)
    total = 0.0
    for t in range(logp.shape[0]):
        best, n_new = emissions(logp[t], log_act, model, state_gds, u[t], g[t], prune, e, new_live)
        if is_start[t]:
            pred[:] = tables.init
        else:
            predict_forward(alpha, live, n_live, prev_action, trans, pred)
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
def _predict_viterbi(delta, live, n_live, a, trans, best, arg):
    """``best[j] = max_i delta[i] + log T_a[i, j]`` and its smallest argmax ``arg[j]``
    (``trans``: :class:`Transitions`)."""
    indptr, indices, logdata, seen = trans.indptr, trans.indices, trans.logdata, trans.seen
    A, log_eps_s, log_uni = trans.n_actions, trans.log_eps_s, trans.log_uni
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
def viterbi_chunk(logp, steps, tables, trans, delta, live, n_live, prev_action, back, end_state):
    """Viterbi recursion over one chunk (log space); arguments as :func:`forward_chunk`.
    ``delta``/``live``/``n_live``/``prev_action`` carry the state between chunks.  With
    ``back.shape[0] > 0`` the best predecessor of every state at every step is written to
    ``back`` and, at the last step of an episode, the best final state to ``end_state``.
    Returns ``(n_live, prev_action)``."""
    u, g, is_start, is_end = steps.u, steps.g, steps.is_start, steps.is_end
    log_act, model, state_gds, prune = tables.log_act, tables.model, tables.state_gds, tables.prune
    S = delta.size
    e = np.empty(S)
    best = np.empty(S)
    arg = np.empty(S, dtype=np.int64)
    new_live = np.empty(S, dtype=np.int64)
    store = back.shape[0] > 0
    for t in range(logp.shape[0]):
        _, n_new = emissions(logp[t], log_act, model, state_gds, u[t], g[t], prune, e, new_live)
        if is_start[t]:
            best[:] = tables.log_init
        else:
            _predict_viterbi(delta, live, n_live, prev_action, trans, best, arg)
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
def filter_chunk(logp, steps, tables, trans, alpha, live, n_live, prev_action, out):
    """Forward filtering over one chunk: ``out[t]`` is the belief ``P(x_t | o_1..o_t,
    u_1..u_{t-1})`` (the step's action, chosen after it, is not evidence yet).  ``alpha`` carries
    the belief times ``P(u_t|x)`` between steps and chunks; arguments as :func:`forward_chunk`.
    Returns ``(n_live, prev_action)``."""
    u, g, is_start = steps.u, steps.g, steps.is_start
    log_act, model, state_gds, prune = tables.log_act, tables.model, tables.state_gds, tables.prune
    S = alpha.size
    no_act = np.zeros((S, 1))
    e = np.empty(S)
    pred = np.empty(S)
    new_live = np.empty(S, dtype=np.int64)
    for t in range(logp.shape[0]):
        best, n_new = emissions(logp[t], no_act, model, state_gds, 0, g[t], prune, e, new_live)
        if is_start[t]:
            pred[:] = tables.init
        else:
            predict_forward(alpha, live, n_live, prev_action, trans, pred)
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
