"""Phase 1 of a streamed fit: K-means fitted on rows gathered from the logs, every step given
its symbol on the engine, and the phase-1 states and observation models put together here.

K-means runs as the in-memory fit's ``phase1="sample"`` or ``"full"``
(:mod:`topomap.core.phase1.clustering`): ``"full"`` (every non-GDS row; what ``"auto"`` picks
while ``T * ns * D <= 1e7`` or the sample would hold every row) or ``"sample"`` (the same
seeded rows an in-memory fit draws, ``max(20000, 64 ns)`` of them, then every row assigned to
its nearest centre in blocks whose symbols are those of one ``predict`` over all rows).  So the
streamed symbols are the in-memory fit's, given the same phase-1 method.  The distance metric
must act on each row alone (``euclidean``, ``cosine``).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from threadpoolctl import threadpool_limits

from ..checks import ParameterError
from ..phase1.clustering import (FULL_BUDGET, Cosine, Euclidean, _fitted, sample_rows)
from ..phase1.distinct import distinct_rows
from .jobs import Codebook, sample_job
from .moments import combine, keyed_combine

__all__ = ["STREAM_METHODS", "check_metric", "fit_codebook", "phase1_states"]

#: the phase-1 methods a streamed fit runs
STREAM_METHODS = ("auto", "full", "sample")


def check_metric(metric) -> None:
    if not isinstance(metric, (Euclidean, Cosine)):
        raise ParameterError("metric", f"={getattr(metric, 'name', metric)!r}: a streamed fit "
                                       "needs a metric of each row alone (euclidean or cosine)")


def _gather(logs, plan, runner, picks: np.ndarray, metric) -> np.ndarray:
    """The non-GDS rows at the sorted global positions ``picks``, after the metric."""
    bounds = np.concatenate([[0], np.cumsum(plan.n_plain)])
    jobs = []
    for i in range(len(plan.infos)):
        lo, hi = np.searchsorted(picks, bounds[i:i + 2])
        if hi > lo:
            jobs.append((i, plan.infos[i].steps, picks[lo:hi] - bounds[i]))
    rows = runner.map(sample_job, logs, jobs)
    return np.ascontiguousarray(metric.fit_transform(np.concatenate(rows)), dtype=np.float64)


def fit_codebook(learner, logs, plan, runner, policy, metric):
    """``(codebook, details)``: K-means fitted on the gathered rows (see the module
    docstring); ``details`` as :func:`~topomap.core.phase1.clustering.cluster_observations`
    gives them, with ``"method"``."""
    method = learner.phase1
    if method not in STREAM_METHODS:
        raise ParameterError("phase1", f"={method!r}: a streamed fit runs "
                                       f"{', '.join(STREAM_METHODS)}")
    total, seed = int(plan.n_plain.sum()), learner.random_state
    if total < 1:
        raise ValueError("every step is labelled as a GDS; no observations are left to cluster")
    guess = getattr(policy, "ns", None) or getattr(policy, "max_ns", None) or 1
    m = sample_rows(int(guess), learner.sample_size)
    full = method == "full" or m >= total or (
        method == "auto" and total * int(guess) * plan.n_features <= FULL_BUDGET)
    picks = (np.arange(total) if full else
             np.sort(np.random.default_rng(seed).choice(total, size=m, replace=False)))
    Z = _gather(logs, plan, runner, picks, metric)
    choice = policy.choose(Z, seed)
    ns, details = choice if isinstance(choice, tuple) else (choice, {})
    ns = int(ns)
    n_distinct = distinct_rows(Z)[0].size
    if ns > n_distinct:
        where = "" if full else f" of the {Z.shape[0]} rows K-means is fitted on"
        raise ParameterError("ns", f"={ns} is more than the {n_distinct} distinct "
                                   f"observations{where} (GDS steps excluded); lower the "
                                   "cluster count")
    with threadpool_limits(limits=1, user_api="blas"):  # as the in-memory fit runs K-means
        km, cut = _fitted(Z, ns, learner.n_init, seed, True)
    if cut is not None:
        details = dict(details, cut_views=cut)
    fixed = km.labels_.astype(np.int64) if full else None
    offsets = np.concatenate([[0], np.cumsum(plan.n_plain)]) if full else None
    book = Codebook(km, metric, fixed, offsets)
    return book, dict(details, method="full" if full else "sample")


@njit(cache=True)
def _extend_order(raw, rename, n):
    """:func:`~topomap.core.phase1.clustering.first_appearance_order` continued over ``raw``
    (-1: no symbol) from ``rename`` and ``n`` labels seen so far."""
    for t in range(raw.size):
        r = raw[t]
        if r >= 0 and rename[r] < 0:
            rename[r] = n
            n += 1
    return n


def phase1_states(results, plan, k: int, full_cov: bool):
    """``(labels, actions, ns, moments)`` from every log's
    :class:`~topomap.core.stream.jobs.LogResult` (in order): the phase-1 state of every step
    (symbols numbered by first appearance, then one state per GDS id) as int16 (int32 past
    32,767 states), the actions in the smallest type holding them, the symbols' count, and
    ``(per-state Moments, Moments over all rows)``.  Each result's steps are dropped once
    copied."""
    rename, n = np.full(k, -1, dtype=np.int64), 0
    for r in results:
        n = _extend_order(r.raw, rename, n)
    ns, ids = n, plan.gds_ids
    T = int(plan.steps.sum())
    labels = np.empty(T, dtype=np.int16 if ns + ids.size < 2**15 else np.int32)
    actions = np.empty(T, dtype=np.min_scalar_type(-plan.n_actions))
    plain = gds = whole = None
    start = 0
    for r in results:
        seg = labels[start:start + r.raw.size]
        seg[:] = np.where(r.raw >= 0, rename[np.maximum(r.raw, 0)], 0)
        seg[r.gds_steps] = ns + np.searchsorted(ids, r.gds_ids)
        actions[start:start + r.raw.size] = r.actions
        start += r.raw.size
        plain = r.plain if plain is None else combine(plain, r.plain)
        gds = r.gds if gds is None else keyed_combine(gds, r.gds)
        whole = r.whole if whole is None else combine(whole, r.whole)
        r.raw = r.actions = None
    order = np.argsort(np.where(rename >= 0, rename, k))[:ns]  # raw label of each symbol
    per_state = plain.take(order)
    g = gds[1].take(np.searchsorted(gds[0], ids))
    states = type(per_state)(np.concatenate([per_state.n, g.n]),
                             np.concatenate([per_state.mean, g.mean]),
                             np.concatenate([per_state.m2, g.m2]))
    return labels, actions, ns, (states, whole)


def observation_models(moments, T: int, covariance_type: str, reg_covar: float):
    """``(means, covariances)`` of the phase-1 states from their moments, regularised as
    :func:`~topomap.core.map.observations.observation_models` does (``reg_covar`` times the
    data's mean feature variance)."""
    states, whole = moments
    variance = whole.m2[0] / T
    reg = reg_covar * float(np.mean(variance)) if T > 1 else reg_covar
    reg = reg if reg > 0 else reg_covar
    n = np.maximum(states.n, 1)
    if covariance_type == "full":
        D = states.mean.shape[1]
        return states.mean, states.m2 / n[:, None, None] + reg * np.eye(D)
    return states.mean, states.m2 / n[:, None] + reg
