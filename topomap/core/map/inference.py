"""Inference on a learned map in bounded memory: log-densities, forward, filtering,
forward-backward, Viterbi and a path's log-probability.

:class:`~topomap.core.map.model.TopologicalMap`'s ``score``, ``filter``, ``predict``,
``predict_proba``, ``score_samples`` and ``decode`` call these.
A sequence is processed in chunks of steps: the Gaussian log-densities of a chunk under every
*observation model* (states split from one symbol share it: :func:`tied_gaussians`) in the matmul
form, then compiled recursions over the sparse smoothed transitions
(:mod:`topomap.core.map.kernels`).  :func:`setup` checks a sequence against a map and gathers what
the kernels read into a :class:`Query`.  Memory: the
chunk's (rows x models) log-densities (at most :data:`topomap.core.map.observations.CHUNK_BYTES`),
O(S + seen transitions) tables, and for ``predict`` one chunk of back-pointers (rows x S int32)
plus one ``delta`` per chunk (checkpointed Viterbi: the recursion runs twice, the second time
chunk by chunk backwards).  Forward-backward keeps the scaled forward variables in its output and
turns them into posteriors chunk by chunk backwards (the log-densities are computed again), each
step scaled to sum to 1, so nothing underflows however long the sequence.  Nothing grows with T
but the outputs: the (T,) path of ``predict`` and the (T, S) beliefs of ``filter`` and
posteriors of ``predict_proba``.

Emission pruning (``prune=True``, the default): at every step the states whose emission lies more
than :func:`topomap.core.map.kernels.prune_threshold` nats below the step's best are skipped.  Every
smoothed transition is at least ``smoothing / S``, so Viterbi stays exact and a forward
log-likelihood changes by less than 1e-20 relative.

A sequence without actions (``actions=None``) is decoded on the map with its actions summed out
(:func:`without_actions`): a hidden Markov model over the same states whose transitions are
``sum_u P(u|x) P(x'|x,u)``, the likelihood ``P(o)`` of the observations alone.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import kernels as K
from .observations import log_density_chunks
from ..data.trajectory import check_sequences

__all__ = ["Query", "tied_gaussians", "log_densities", "setup", "marginal_transitions",
           "without_actions", "forward", "filtered",
           "posteriors", "viterbi", "path_log_prob", "emission_row", "predicted"]


class Query(NamedTuple):
    """A sequence checked against a map, with the map's tables the kernels read (:func:`setup`)."""

    X: np.ndarray  # (T, D) observations
    means: np.ndarray  # (M, D) mean of every observation model
    cov: np.ndarray  # (M, D[, D]) its covariance
    steps: K.Steps  # actions, GDS labels, episode marks of every step
    tables: K.StateTables
    trans: K.Transitions

    @property
    def n_states(self) -> int:
        return self.tables.log_init.size

    def chunk(self, sl: slice) -> K.Steps:
        """The :class:`~topomap.core.map.kernels.Steps` of the steps ``sl``."""
        return K.Steps(*(a[sl] for a in self.steps))


def tied_gaussians(m):
    """``(model_of_state, means, covariances)``: the map's distinct Gaussians, one per
    observation model, and the model of every state.  States with the same symbol (or GDS) share
    one, as the learner builds them; a map whose tied states differ gets one model per state."""
    symbol, gds = m.state_symbol, m.state_gds
    key = np.where(symbol >= 0, symbol, max(int(symbol.max()) + 1, 0) + gds)
    _, first, model = np.unique(key, return_index=True, return_inverse=True)
    means, cov = m.means[first], m.covariances[first]
    if not (np.array_equal(means[model], m.means)
            and np.array_equal(cov[model], m.covariances)):
        return np.arange(m.n_states), m.means, m.covariances
    return model.ravel(), means, cov


def log_densities(m, X: np.ndarray) -> np.ndarray:
    """(T, S) Gaussian log-densities of the rows of ``X`` under every state's model."""
    model, means, cov = tied_gaussians(m)
    out = np.empty((X.shape[0], m.n_states))
    for start, logp in log_density_chunks(X, means, cov):
        out[start:start + logp.shape[0]] = logp[:, model]
    return out


def _transitions(m, smoothing: float) -> K.Transitions:
    """CSR over rows ``i * A + a`` of the seen transitions: probabilities ``(1 - eps) P`` and
    logs of ``(1 - eps) P + eps / S``, plus the row-constant terms of the smoothing."""
    S, A = m.n_states, m.n_actions
    counts = m.transition_counts.reshape(S * A, S)
    rows, cols = np.nonzero(counts)
    c = counts[rows, cols].astype(np.float64)
    total = counts.sum(axis=1).astype(np.float64)
    return _smoothed(rows, cols, c / total[rows], total > 0, A, smoothing)


def _smoothed(rows, cols, p, seen, n_actions: int, smoothing: float) -> K.Transitions:
    """The :class:`~topomap.core.map.kernels.Transitions` of the probabilities ``p`` at
    ``(rows, cols)`` (rows sorted; ``seen``: the rows that hold any), smoothed by ``smoothing``."""
    S = seen.size // n_actions
    prob = (1 - smoothing) * p
    consts = np.log(np.array([0.0 + smoothing / S, (1 - smoothing) * (1.0 / S) + smoothing / S]))
    return K.Transitions(
        indptr=np.searchsorted(rows, np.arange(seen.size + 1)), indices=cols, data=prob,
        logdata=np.log(prob + smoothing / S), seen=seen, n_actions=n_actions,
        eps_s=smoothing / S, uni=(1 - smoothing) / S, log_eps_s=consts[0], log_uni=consts[1])


def marginal_transitions(m) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The map's transitions with the action summed out, ``M[x, x'] = sum_u P(u|x) P(x'|x,u)``,
    sparse: ``(rows, cols, probabilities, seen)``, rows sorted, ``seen`` (S,) the states
    whose row is not uniform.  ``P(x'|x,u)`` is uniform for an ``(x, u)`` without a counted
    transition (as :attr:`~topomap.core.map.model.TopologicalMap.transition_probs`), so a state
    that took such an action gets that share spread over every state."""
    S = m.n_states
    act = m.action_probs
    total = m.transition_counts.sum(axis=2)
    xs, us, ys = np.nonzero(m.transition_counts)
    weight = act[xs, us] * m.transition_counts[xs, us, ys] / total[xs, us]
    spread = (act * (total == 0)).sum(axis=1) / S  # the uniform rows' share, per next state
    seen = (act * (total > 0)).sum(axis=1) > 0
    partial = np.flatnonzero(seen & (spread > 0))
    keys = np.concatenate([xs * S + ys, (partial[:, None] * S + np.arange(S)).ravel()])
    values = np.concatenate([weight, np.repeat(spread[partial], S)])
    cells, where = np.unique(keys, return_inverse=True)
    return cells // S, cells % S, np.bincount(where, weights=values), seen


def without_actions(m, observations, gds, lengths, smoothing: float, prune: bool) -> Query:
    """:func:`setup` for a sequence without actions: the map with its actions summed out, a
    hidden Markov model whose transitions are :func:`marginal_transitions` (smoothed as every
    table) and whose steps' action term is ``log sum_u P(u|x) = 0``.  Its likelihood is
    ``P(o) = sum over the action sequences u of P(o, u)``."""
    n = np.shape(observations)[0] if np.ndim(observations) else 0
    q = setup(m, observations, np.zeros(n, dtype=np.int64), gds, lengths, smoothing, prune)
    rows, cols, p, seen = marginal_transitions(m)
    return q._replace(tables=q.tables._replace(log_act=np.zeros((m.n_states, 1))),
                      trans=_smoothed(rows, cols, p, seen, 1, smoothing))


def _check_query(m, X, u, g, gds, smoothing) -> None:
    """A ValueError when the checked sequence ``X, u, g`` does not fit the map ``m``."""
    if X.shape[1] != m.n_features:
        raise ValueError(f"observations have {X.shape[1]} features but the map was learned on "
                         f"{m.n_features}")
    if u.max() >= m.n_actions:
        raise ValueError(f"actions use id {int(u.max())} but the map knows {m.n_actions} actions")
    if not 0 < smoothing < 1:
        raise ValueError(f"smoothing must lie in (0, 1), got {smoothing!r}")
    if gds is not None:
        known = set(m.state_gds[m.state_gds >= 0].tolist())
        unknown = sorted(set(np.unique(g[g >= 0]).tolist()) - known)
        if unknown:
            raise ValueError(f"gds ids {unknown} are not states of this map")


def setup(m, observations, actions, gds, lengths, smoothing: float, prune: bool) -> Query:
    """Validate a sequence for the map ``m`` and collect everything the kernels use;
    ``actions=None``: a sequence without actions (:func:`without_actions`)."""
    if actions is None:
        return without_actions(m, observations, gds, lengths, smoothing, prune)
    X, u, g, L = check_sequences(observations, actions, gds, lengths, min_length=1)
    _check_query(m, X, u, g, gds, smoothing)
    if gds is None:
        g = np.full(X.shape[0], -2, dtype=np.int64)  # -2: no GDS labels at all
    ends = np.cumsum(L) - 1
    is_start, is_end = np.zeros(X.shape[0], dtype=bool), np.zeros(X.shape[0], dtype=bool)
    is_start[ends - L + 1], is_end[ends] = True, True
    model, means, cov = tied_gaussians(m)
    S = m.n_states
    log_init = np.log((1 - smoothing) * m.state_probs + smoothing / S)
    tables = K.StateTables(
        log_act=np.log((1 - smoothing) * m.action_probs + smoothing / m.n_actions),
        model=model, state_gds=m.state_gds, init=np.exp(log_init), log_init=log_init,
        prune=K.prune_threshold(S, smoothing) if prune else np.inf)
    return Query(X, means, cov, K.Steps(u, g, is_start, is_end), tables,
                 _transitions(m, smoothing))


def _recursion(q: Query, kernel, out) -> tuple[float, list]:
    """Run a forward-type kernel over every chunk (``out``: its per-step output, or an empty
    array); returns the summed log-likelihood (forward) and the chunks' slices."""
    S = q.n_states
    alpha, live = np.zeros(S), np.zeros(S, dtype=np.int64)
    n_live, prev, total, slices = 0, 0, 0.0, []
    for start, logp in log_density_chunks(q.X, q.means, q.cov):
        sl = slice(start, start + logp.shape[0])
        *part, n_live, prev = kernel(logp, q.chunk(sl), q.tables, q.trans, alpha, live, n_live,
                                     prev, out[sl])
        total += part[0] if part else 0.0
        slices.append(sl)
    return total, slices


def _chunk_densities(q: Query, sl: slice) -> np.ndarray:
    """(rows, models) log-densities of the steps ``sl`` (one chunk of :func:`_recursion`)."""
    return next(log_density_chunks(q.X[sl], q.means, q.cov, chunk_rows=sl.stop - sl.start))[1]


def forward(q: Query) -> float:
    """Mean log-likelihood per step (natural log) of the sequence of :func:`setup`."""
    total, _ = _recursion(q, K.forward_chunk, np.empty((0, q.n_states)))
    return float(total / q.X.shape[0])


def filtered(q: Query) -> np.ndarray:
    """(T, S) beliefs ``P(x_t | o_1..o_t, u_1..u_{t-1})`` of the sequence of :func:`setup`."""
    out = np.zeros((q.X.shape[0], q.n_states))
    _recursion(q, K.filter_chunk, out)
    return out


def posteriors(q: Query) -> tuple[float, np.ndarray]:
    """``(log-likelihood, posteriors)`` of the sequence of :func:`setup` by forward-backward:
    the summed log-likelihood (natural log, every episode) and the (T, S) ``P(x_t | o, u)`` of
    every step given its whole episode, rows summing to 1."""
    out = np.zeros((q.X.shape[0], q.n_states))
    total, slices = _recursion(q, K.forward_chunk, out)
    v = np.zeros(q.n_states)
    for sl in reversed(slices):
        K.backward_chunk(_chunk_densities(q, sl), q.chunk(sl), q.tables, q.trans, v, out[sl])
    return float(total), out


def path_log_prob(q: Query, path: np.ndarray) -> float:
    """Joint log-probability ``log P(o, u, x)`` (natural log, summed over the episodes) of the
    sequence of :func:`setup` with the states ``path``."""
    total, state, action = 0.0, 0, 0
    for start, logp in log_density_chunks(q.X, q.means, q.cov):
        sl = slice(start, start + logp.shape[0])
        part, state, action = K.path_chunk(logp, q.chunk(sl), q.tables, q.trans, path[sl],
                                           state, action)
        total += part
    return float(total)


def _viterbi_pass(q: Query, sl, carry, back, end_state, logp=None):
    """Run the Viterbi kernel on the steps ``sl`` from the carried state ``carry`` =
    ``(delta, live, n_live, prev_action)``; returns the state after them."""
    if logp is None:
        logp = _chunk_densities(q, sl)
    delta, live, n_live, prev = carry
    n_live, prev = K.viterbi_chunk(logp, q.chunk(sl), q.tables, q.trans, delta, live, n_live,
                                   prev, back, end_state)
    return delta, live, n_live, prev


def viterbi(q: Query) -> np.ndarray:
    """Most likely state of every step of the sequence of :func:`setup` (checkpointed)."""
    S, T = q.n_states, q.X.shape[0]
    carry = (np.zeros(S), np.zeros(S, dtype=np.int64), 0, 0)
    checkpoints, no_back = [], np.empty((0, S), dtype=np.int32)
    for start, logp in log_density_chunks(q.X, q.means, q.cov):
        sl = slice(start, start + logp.shape[0])
        checkpoints.append((sl, (carry[0].copy(), carry[1].copy(), carry[2], carry[3])))
        carry = _viterbi_pass(q, sl, carry, no_back, np.empty(0, np.int64), logp)
    path, state = np.empty(T, dtype=np.int64), -1
    for sl, saved in reversed(checkpoints):
        back = np.zeros((sl.stop - sl.start, S), dtype=np.int32)
        end_state = np.zeros(sl.stop - sl.start, dtype=np.int64)
        _viterbi_pass(q, sl, saved, back, end_state)
        steps = q.chunk(sl)
        state = K.backtrack_chunk(back, steps.is_start, steps.is_end, end_state, state, path[sl])
    return path


def emission_row(q: Query) -> np.ndarray:
    """``log P(o|x)`` of every state for the first step of :func:`setup` (GDS clamp applied)."""
    logp = log_densities_rows(q, 0, 1)[0]
    g, gds = q.steps.g[0], q.tables.state_gds
    allowed = np.ones(gds.size, dtype=bool) if g == -2 else (gds < 0 if g == -1 else gds == g)
    return np.where(allowed, logp, -np.inf)


def log_densities_rows(q: Query, start: int, stop: int) -> np.ndarray:
    """(rows, S) log-densities of the steps ``start:stop`` of :func:`setup`."""
    logp = next(log_density_chunks(q.X[start:stop], q.means, q.cov, chunk_rows=stop - start))[1]
    return logp[:, q.tables.model]


def predicted(q: Query, belief: np.ndarray, action: int) -> np.ndarray:
    """``P(x' | belief, action)``: the belief moved by ``P(action|x) P(x'|x, action)`` (the
    action's choice is evidence too, as in :func:`filtered`)."""
    alpha = belief * np.exp(q.tables.log_act[:, action])
    alpha /= alpha.sum()
    live = np.flatnonzero(alpha > 0)
    pred = np.empty(alpha.size)
    K.predict_forward(alpha, live, live.size, action, q.trans, pred)
    return pred
