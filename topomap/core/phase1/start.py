"""From phase 1's symbols to the split's start: every step's phase-1 state, the split's tables
and the observation models of the phase-1 map, estimated side by side.

The split's first tables (:class:`~topomap.core.split.engine.Splitter`) and the observation
models (two passes over the observations) need the same labels and nothing of each other, and
each runs on one core: the models are estimated on a thread of
:mod:`topomap.core.split.threads` while the tables are built (in turn on one thread).  The
data's feature variance, which needs no labels, is computed beside K-means
(:func:`variance_beside`).  Every number is the one the steps in turn give.
"""

from __future__ import annotations

import numpy as np

from ..map.model import TopologicalMap
from ..map.observations import feature_variance
from ..split.engine import Splitter
from ..split.threads import beside

__all__ = ["variance_beside", "phase1_labels", "start_split"]


def variance_beside(X: np.ndarray):
    """Start :func:`~topomap.core.map.observations.feature_variance` of ``X`` on a thread; a
    function without arguments returns it."""
    return beside(feature_variance, X, steps=X.shape[0])


def phase1_labels(symbols: np.ndarray, ns: int, gds: np.ndarray):
    """``(labels, gds_ids)``: the phase-1 state of every step -- its symbol (``symbols`` holds
    one in ``[0, ns)`` per step whose ``gds`` is -1), or ``ns`` plus the rank of its GDS id
    among the sorted ``gds_ids`` -- as int64 (the symbols' own array when no step is a GDS)."""
    plain = gds < 0
    gds_ids = np.unique(gds[~plain])
    if not gds_ids.size:
        return np.asarray(symbols, dtype=np.int64), gds_ids
    labels = np.empty(gds.size, dtype=np.int64)
    labels[plain] = symbols
    labels[~plain] = ns + np.searchsorted(gds_ids, gds[~plain])
    return labels, gds_ids


def start_split(data, labels: np.ndarray, ns: int, gds_ids: np.ndarray, variance, *, criterion,
                recompute_all: bool, covariance_type: str, reg_covar: float):
    """``(splitter, models)``: the :class:`~topomap.core.split.engine.Splitter` of the phase-1
    ``labels`` (``ns`` symbols, then one state per GDS id, never split) and the observation
    models of its states (:meth:`~topomap.core.map.model.TopologicalMap.state_models`),
    estimated beside it; ``variance``: a function returning the data's feature variance."""
    symbol = list(range(ns)) + [-1] * gds_ids.size
    gds = [-1] * ns + gds_ids.tolist()
    models = beside(TopologicalMap.state_models, data.X, labels, symbol, gds, covariance_type,
                    reg_covar, variance(), steps=labels.size)
    splitter = Splitter(labels, data.u, data.n_actions, *data.masks, symbol=symbol, gds=gds,
                        obs_entropy=np.zeros(0), criterion=criterion,
                        recompute_all=recompute_all)
    return splitter, models()
