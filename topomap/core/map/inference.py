"""Inference on a learned map in bounded memory: log-densities, forward, filtering, Viterbi.

:class:`~topomap.core.map.model.TopologicalMap`'s ``score``, ``filter`` and ``predict`` call these.
A sequence is processed in chunks of steps: the Gaussian log-densities of a chunk under every
*observation model* (states split from one symbol share it) in the matmul form, then compiled
recursions over the sparse smoothed transitions (:mod:`topomap.core.map.kernels`).  Memory: the
chunk's (rows x models) log-densities (at most :data:`topomap.core.map.observations.CHUNK_BYTES`),
O(S + seen transitions) tables, and for ``predict`` one chunk of back-pointers (rows x S int32)
plus one ``delta`` per chunk (checkpointed Viterbi: the recursion runs twice, the second time
chunk by chunk backwards).  Nothing grows with T but the outputs: the (T,) path of ``predict`` and
the (T, S) beliefs of ``filter``.

Emission pruning (``prune=True``, the default): at every step the states whose emission lies more
than :func:`topomap.core.map.kernels.prune_threshold` nats below the step's best are skipped.  Every
smoothed transition is at least ``smoothing / S``, so Viterbi stays exact and a forward
log-likelihood changes by less than 1e-20 relative.
"""

from __future__ import annotations

import numpy as np

from . import kernels as K
from .observations import log_density_chunks
from ..data.trajectory import check_sequences

__all__ = ["observation_models", "log_densities", "setup", "forward", "filtered", "viterbi",
           "emission_row", "predicted"]


def observation_models(m):
    """``(model_of_state, means, covariances)``: one Gaussian per observation model.  States with
    the same symbol (or GDS) share one, as the learner builds them; a map whose tied states differ
    is treated as one model per state."""
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
    model, means, cov = observation_models(m)
    out = np.empty((X.shape[0], m.n_states))
    for start, logp in log_density_chunks(X, means, cov):
        out[start:start + logp.shape[0]] = logp[:, model]
    return out


def _transition_tables(m, smoothing: float) -> dict:
    """CSR over rows ``i * A + a`` of the seen transitions: probabilities ``(1 - eps) P`` and
    logs of ``(1 - eps) P + eps / S``, plus the row-constant terms of the smoothing."""
    S, A = m.n_states, m.n_actions
    counts = m.transition_counts.reshape(S * A, S)
    rows, cols = np.nonzero(counts)
    c = counts[rows, cols].astype(np.float64)
    total = counts.sum(axis=1).astype(np.float64)
    prob = (1 - smoothing) * (c / total[rows])
    consts = np.log(np.array([0.0 + smoothing / S, (1 - smoothing) * (1.0 / S) + smoothing / S]))
    return {"indptr": np.searchsorted(rows, np.arange(S * A + 1)), "indices": cols,
            "data": prob, "logdata": np.log(prob + smoothing / S), "seen": total > 0,
            "eps_s": smoothing / S, "uni": (1 - smoothing) / S,
            "log_eps_s": consts[0], "log_uni": consts[1]}


def setup(m, observations, actions, gds, lengths, smoothing: float, prune: bool) -> dict:
    """Validate a sequence for the map ``m`` and collect everything the kernels use."""
    X, u, g, L = check_sequences(observations, actions, gds, lengths, min_length=1)
    if X.shape[1] != m.n_features:
        raise ValueError(f"observations have {X.shape[1]} features but the map was learned on "
                         f"{m.n_features}")
    if u.max() >= m.n_actions:
        raise ValueError(f"actions use id {int(u.max())} but the map knows {m.n_actions} actions")
    if not 0 < smoothing < 1:
        raise ValueError(f"smoothing must lie in (0, 1), got {smoothing!r}")
    if gds is None:
        g = np.full(X.shape[0], -2, dtype=np.int64)  # -2: no GDS labels at all
    else:
        known = set(m.state_gds[m.state_gds >= 0].tolist())
        unknown = sorted(set(np.unique(g[g >= 0]).tolist()) - known)
        if unknown:
            raise ValueError(f"gds ids {unknown} are not states of this map")
    ends = np.cumsum(L) - 1
    is_start, is_end = np.zeros(X.shape[0], dtype=bool), np.zeros(X.shape[0], dtype=bool)
    is_start[ends - L + 1], is_end[ends] = True, True
    model, means, cov = observation_models(m)
    S = m.n_states
    s = dict(X=X, u=u, g=g, is_start=is_start, is_end=is_end, model=model, means=means, cov=cov,
             state_gds=m.state_gds,
             log_act=np.log((1 - smoothing) * m.action_probs + smoothing / m.n_actions),
             log_init=np.log((1 - smoothing) * m.state_probs + smoothing / S),
             prune=K.prune_threshold(S, smoothing) if prune else np.inf)
    s.update(_transition_tables(m, smoothing))
    return s


def _recursion(s, kernel, out=None):
    """Run a forward-type kernel over every chunk; returns the summed log-likelihood (forward)."""
    S = s["log_init"].size
    alpha, live = np.zeros(S), np.zeros(S, dtype=np.int64)
    n_live, prev, total = 0, 0, 0.0
    init = np.exp(s["log_init"])
    for start, logp in log_density_chunks(s["X"], s["means"], s["cov"]):
        sl = slice(start, start + logp.shape[0])
        args = (logp, s["u"][sl], s["g"][sl], s["is_start"][sl], s["log_act"], s["model"],
                s["state_gds"], init, s["indptr"], s["indices"], s["data"], s["seen"],
                s["eps_s"], s["uni"], s["prune"], alpha, live, n_live, prev)
        if out is None:
            part, n_live, prev = kernel(*args)
            total += part
        else:
            n_live, prev = kernel(*args, out[sl])
    return total


def forward(s) -> float:
    """Mean log-likelihood per step (natural log) of the sequence of :func:`setup`."""
    return float(_recursion(s, K.forward_chunk) / s["X"].shape[0])


def filtered(s) -> np.ndarray:
    """(T, S) beliefs ``P(x_t | o_1..o_t, u_1..u_{t-1})`` of the sequence of :func:`setup`."""
    out = np.zeros((s["X"].shape[0], s["log_init"].size))
    _recursion(s, K.filter_chunk, out)
    return out


def _viterbi_pass(s, sl, carry, back, end_state, logp=None):
    """Run the Viterbi kernel on the steps ``sl`` from the carried state ``carry`` =
    ``(delta, live, n_live, prev_action)``; returns the state after them."""
    if logp is None:
        logp = next(log_density_chunks(s["X"][sl], s["means"], s["cov"],
                                       chunk_rows=sl.stop - sl.start))[1]
    delta, live, n_live, prev = carry
    n_live, prev = K.viterbi_chunk(
        logp, s["u"][sl], s["g"][sl], s["is_start"][sl], s["is_end"][sl], s["log_act"],
        s["model"], s["state_gds"], s["log_init"], s["indptr"], s["indices"], s["logdata"],
        s["seen"], s["log_eps_s"], s["log_uni"], s["prune"], delta, live, n_live, prev,
        back, end_state)
    return delta, live, n_live, prev


def viterbi(s) -> np.ndarray:
    """Most likely state of every step of the sequence of :func:`setup` (checkpointed)."""
    S, T = s["log_init"].size, s["X"].shape[0]
    carry = (np.zeros(S), np.zeros(S, dtype=np.int64), 0, 0)
    checkpoints, no_back = [], np.empty((0, S), dtype=np.int32)
    for start, logp in log_density_chunks(s["X"], s["means"], s["cov"]):
        sl = slice(start, start + logp.shape[0])
        checkpoints.append((sl, (carry[0].copy(), carry[1].copy(), carry[2], carry[3])))
        carry = _viterbi_pass(s, sl, carry, no_back, np.empty(0, np.int64), logp)
    path, state = np.empty(T, dtype=np.int64), -1
    for sl, saved in reversed(checkpoints):
        back = np.zeros((sl.stop - sl.start, S), dtype=np.int32)
        end_state = np.zeros(sl.stop - sl.start, dtype=np.int64)
        _viterbi_pass(s, sl, saved, back, end_state)
        state = K.backtrack_chunk(back, s["is_start"][sl], s["is_end"][sl], end_state, state,
                                  path[sl])
    return path


def emission_row(s) -> np.ndarray:
    """``log P(o|x)`` of every state for the first step of :func:`setup` (GDS clamp applied)."""
    logp = log_densities_rows(s, 0, 1)[0]
    g, gds = s["g"][0], s["state_gds"]
    allowed = np.ones(gds.size, dtype=bool) if g == -2 else (gds < 0 if g == -1 else gds == g)
    return np.where(allowed, logp, -np.inf)


def log_densities_rows(s, start: int, stop: int) -> np.ndarray:
    """(rows, S) log-densities of the steps ``start:stop`` of :func:`setup`."""
    logp = next(log_density_chunks(s["X"][start:stop], s["means"], s["cov"],
                                   chunk_rows=stop - start))[1]
    return logp[:, s["model"]]


def predicted(s, belief: np.ndarray, action: int) -> np.ndarray:
    """``P(x' | belief, action)``: the belief moved by ``P(action|x) P(x'|x, action)`` (the
    action's choice is evidence too, as in :func:`filtered`)."""
    alpha = belief * np.exp(s["log_act"][:, action])
    alpha /= alpha.sum()
    live = np.flatnonzero(alpha > 0)
    pred = np.empty(alpha.size)
    K._predict_forward(alpha, live, live.size, action, s["log_act"].shape[1], s["indptr"],
                       s["indices"], s["data"], s["seen"], s["eps_s"], s["uni"], pred)
    return pred
