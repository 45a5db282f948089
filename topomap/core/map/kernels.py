"""Compiled kernels of inference on a learned map: forward (score, filter), backward (the
smoothed posteriors of forward-backward), Viterbi (predict) and a path's log-probability, over
sparse, smoothed transitions, one chunk of steps at a time (``*_chunk``).

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
           "predict_forward", "predict_backward", "forward_chunk", "backward_chunk",
           "filter_chunk", "viterbi_chunk", "backtrack_chunk", "log_transition", "path_chunk"]


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
def forward_chunk(logp, steps, tables, trans, alpha, live, n_live, prev_action, out):
    """Scaled forward pass over one chunk: ``logp`` its (rows, models) log-densities, ``steps``
    its :class:`Steps`, ``tables`` the :class:`StateTables`, ``trans`` the :class:`Transitions`.
    ``alpha``/``live``/``n_live``/``prev_action`` carry the state between chunks.  With
    ``out.shape[0] > 0`` row ``t`` of ``out`` gets the normalised forward variable of step ``t``,
    ``P(x_t | o_1..o_t, u_1..u_t)`` (what :func:`backward_chunk` reads).  Returns ``(sum of
    log-likelihood increments, n_live, prev_action)``."""
    u, g, is_start = steps.u, steps.g, steps.is_start
    log_act, model, state_gds, prune = tables.log_act, tables.model, tables.state_gds, tables.prune
    S = alpha.size
    e = np.empty(S)
    pred = np.empty(S)
    new_live = np.empty(S, dtype=np.int64)
    store = out.shape[0] > 0
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
        if store:
            out[t, :] = alpha
        live[:n_new] = new_live[:n_new]
        n_live = n_new
        total += np.log(c) + best
        prev_action = u[t]
    return total, n_live, prev_action


@njit(cache=True)
def predict_backward(v, live, n_live, a, trans, beta):
    """``beta[i] = (T_a @ v)[i]`` for the states ``i`` in ``live`` (``trans``:
    :class:`Transitions`); ``v`` is any non-negative vector."""
    indptr, indices, data, seen = trans.indptr, trans.indices, trans.data, trans.seen
    total = 0.0
    for j in range(v.size):
        total += v[j]
    for k in range(n_live):
        i = live[k]
        r = i * trans.n_actions + a
        if not seen[r]:
            beta[i] = (trans.uni + trans.eps_s) * total
            continue
        b = trans.eps_s * total
        for p in range(indptr[r], indptr[r + 1]):
            b += data[p] * v[indices[p]]
        beta[i] = b


@njit(cache=True)
def backward_chunk(logp, steps, tables, trans, v, out):
    """Backward pass over one chunk, last step first.  ``out`` holds the chunk's rows of
    :func:`forward_chunk`'s ``out`` and becomes the posteriors ``P(x_t | the whole episode)``
    (every row sums to 1).  ``v`` carries, between chunks, ``P(o_{t+1}, u_{t+1}|x) beta_{t+1}``
    of the step after the chunk, scaled to sum to 1 (any scale gives the same rows); at the last
    step of an episode ``beta`` is 1.  Arguments as :func:`forward_chunk`."""
    u, g, is_end = steps.u, steps.g, steps.is_end
    log_act, model, state_gds, prune = tables.log_act, tables.model, tables.state_gds, tables.prune
    S = v.size
    e = np.empty(S)
    beta = np.zeros(S)
    live = np.empty(S, dtype=np.int64)
    for t in range(logp.shape[0] - 1, -1, -1):
        best, n_live = emissions(logp[t], log_act, model, state_gds, u[t], g[t], prune, e, live)
        if is_end[t]:
            for k in range(n_live):
                beta[live[k]] = 1.0
        else:
            predict_backward(v, live, n_live, u[t], trans, beta)
        c = 0.0
        for k in range(n_live):
            j = live[k]
            out[t, j] *= beta[j]
            c += out[t, j]
        for k in range(n_live):
            out[t, live[k]] /= c
        v[:] = 0.0
        c = 0.0
        for k in range(n_live):
            j = live[k]
            v[j] = np.exp(e[j] - best) * beta[j]
            c += v[j]
        for k in range(n_live):
            v[live[k]] /= c


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


@njit(cache=True)
def log_transition(trans, i, a, j):
    """``log T_a[i, j]`` of the smoothed transitions (``trans``: :class:`Transitions`)."""
    r = i * trans.n_actions + a
    if not trans.seen[r]:
        return trans.log_uni
    for p in range(trans.indptr[r], trans.indptr[r + 1]):
        if trans.indices[p] == j:
            return trans.logdata[p]
    return trans.log_eps_s


@njit(cache=True)
def path_chunk(logp, steps, tables, trans, path, prev_state, prev_action):
    """Joint log-probability of the states ``path`` of one chunk with the chunk's observations
    and actions: ``log P(x_1)`` at an episode's first step, else ``log T_{u_{t-1}}[x_{t-1}, x_t]``,
    plus every step's emission (``-inf`` where the GDS clamp forbids the state).  Arguments as
    :func:`forward_chunk`; ``prev_state``/``prev_action`` carry the last step between chunks.
    Returns ``(log-probability, prev_state, prev_action)``."""
    u, g, is_start = steps.u, steps.g, steps.is_start
    total = 0.0
    for t in range(path.size):
        j = path[t]
        gj = tables.state_gds[j]
        ok = g[t] == -2 or (g[t] == -1 and gj < 0) or (g[t] >= 0 and gj == g[t])
        if is_start[t]:
            total += tables.log_init[j]
        else:
            total += log_transition(trans, prev_state, prev_action, j)
        total += logp[t, tables.model[j]] + tables.log_act[j, u[t]] if ok else -np.inf
        prev_state, prev_action = j, u[t]
    return total, prev_state, prev_action
