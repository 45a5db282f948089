"""The map learner: the paper's two phases behind one scikit-learn-style object."""

from __future__ import annotations

import time

import numpy as np

from .clustering import FixedClusters, cluster_observations, make_metric
from .map import TopologicalMap, conditional_entropy
from .splitting import (
    CRITERIA,
    TargetStates,
    build_instances,
    episode_masks,
    propose_split,
    split_state,
)
from .trajectory import check_sequences

__all__ = ["MapLearner"]


class MapLearner:
    """Learn a topological map from observations and actions (Yairi, Togami & Hori, 2002).

    Phase 1 clusters the non-GDS observations with K-means into ``ns`` symbols, one state each, and
    adds one fixed state per GDS id.  Phase 2 repeatedly splits the state whose split gains the
    most, until the stopping rule fires.

    Parameters
    ----------
    n_clusters : int
        ``ns``, the number of K-means clusters (used when ``clusters`` is None).
    n_states : int
        Target state count (used when ``stopping`` is None).
    clusters : object, optional
        Cluster-count policy with ``choose(Z, random_state) -> int`` (e.g.
        :class:`topomap.clustering.BICClusters`).  Default: ``FixedClusters(n_clusters)``.
    metric : str or object
        ``"euclidean"`` (default), ``"standardized"``, ``"cosine"`` or an object with
        ``fit_transform(X)``.
    criterion : str or object
        ``"entropy"`` (default) or an object with ``propose(counts) -> (side, score) | None``.
    stopping : object, optional
        Stopping rule with ``check(n_initial)`` and ``should_stop(n_states, best_score)``.
        Default: ``TargetStates(n_states)``.
    covariance_type : {"diag", "full"}
        Form of the Gaussian observation models.
    reg_covar : float
        Added to every variance, relative to the data's mean feature variance.
    n_init : int
        K-means restarts (k-means++ initialisations; the best inertia wins).
    random_state : int
        Seed of K-means (the only random part of the method).
    callbacks : sequence of callables
        Each is called as ``callback(event, info)`` with ``event`` in ``"phase1"``, ``"split"``,
        ``"done"`` and ``info`` a dict (``learner``, ``labels``, ``entropies`` and, for splits, the
        history record).  Used to log progress or record extra metrics.

    Attributes
    ----------
    labels_ : (T,) int -- the state of every step
    labels_phase1_ : (T,) int -- the state of every step after phase 1
    map_ : TopologicalMap
    map_phase1_ : TopologicalMap -- the map before any split
    n_clusters_ : int -- the ``ns`` actually used
    split_history_ : list of dict -- ``iteration``, ``state``, ``new_state``, ``gain`` and sizes
    entropies_ : list of dict -- ``H_o``, ``H_u``, ``H_x`` after phase 1 and after every split
    stop_reason_ : str
    timings_ : dict -- seconds spent in ``phase1`` and ``phase2``
    """

    #: re-evaluate every state after each split instead of only the neighbours of the new state
    #: (the results are identical; the tests use this to check that)
    _recompute_all = False

    def __init__(self, n_clusters: int = 20, n_states: int = 30, *, clusters=None,
                 metric="euclidean", criterion="entropy", stopping=None,
                 covariance_type: str = "diag", reg_covar: float = 1e-3, n_init: int = 3,
                 random_state: int = 0, callbacks=()):
        self.n_clusters = n_clusters
        self.n_states = n_states
        self.clusters = clusters
        self.metric = metric
        self.criterion = criterion
        self.stopping = stopping
        self.covariance_type = covariance_type
        self.reg_covar = reg_covar
        self.n_init = n_init
        self.random_state = random_state
        self.callbacks = callbacks

    # ------------------------------------------------------------------ helpers
    def _components(self):
        clusters = self.clusters if self.clusters is not None else FixedClusters(self.n_clusters)
        stopping = self.stopping if self.stopping is not None else TargetStates(self.n_states)
        criterion = self.criterion
        if isinstance(criterion, str):
            if criterion not in CRITERIA:
                raise ValueError(f"criterion {criterion!r} is unknown; choose one of "
                                 f"{', '.join(sorted(CRITERIA))}")
            criterion = CRITERIA[criterion]()
        if self.covariance_type not in ("diag", "full"):
            raise ValueError(f"covariance_type must be 'diag' or 'full', got {self.covariance_type!r}")
        if not (isinstance(self.reg_covar, (int, float)) and self.reg_covar > 0):
            raise ValueError(f"reg_covar must be a positive number, got {self.reg_covar!r}")
        return clusters, make_metric(self.metric), criterion, stopping

    def _emit(self, event: str, **info) -> None:
        for cb in self.callbacks:
            cb(event, dict(info, learner=self))

    def _make_map(self, X, u, labels, L, symbol, gds, parent, A, names):
        m = TopologicalMap.from_labels(
            X, u, labels, lengths=L, state_symbol=symbol, state_gds=gds, state_parent=parent,
            n_actions=A, covariance_type=self.covariance_type, reg_covar=self.reg_covar,
            action_names=names[0], gds_names=names[1],
            split_history=self.split_history_, entropies=self.entropies_,
        )
        return m

    # ------------------------------------------------------------------ fit
    def fit(self, observations, actions, gds=None, lengths=None, *, n_actions=None,
            action_names=None, gds_names=None):
        """Learn the map.  Returns ``self``.

        ``observations`` (T, D), ``actions`` (T,) ints in ``[0, n_actions)``, ``gds`` (T,) ints with
        -1 for "no GDS", ``lengths`` the episode lengths when several episodes are concatenated.
        """
        X, u, g, L = check_sequences(observations, actions, gds, lengths)
        clusters, metric, criterion, stopping = self._components()
        A = int(u.max()) + 1 if n_actions is None else int(n_actions)
        if action_names is not None:
            A = max(A, len(action_names)) if n_actions is None else A
        if u.max() >= A:
            raise ValueError(f"actions use id {int(u.max())} but n_actions is {A}")
        if gds_names is not None and g.max() >= len(gds_names):
            raise ValueError(f"gds id {int(g.max())} is out of range: only {len(gds_names)} "
                             "gds_names are given")
        T = X.shape[0]
        has_prev, has_next = episode_masks(T, L)
        self.split_history_, self.entropies_ = [], []

        # ---- phase 1: K-means symbols, one state each, plus one fixed state per GDS id
        t0 = time.perf_counter()
        plain = g < 0
        if plain.sum() < 1:
            raise ValueError("every step is labelled as a GDS; no observations are left to cluster")
        symbols = cluster_observations(X[plain], clusters, metric, n_init=self.n_init,
                                       random_state=self.random_state)
        ns = int(symbols.max()) + 1
        gds_ids = np.unique(g[~plain])
        labels = np.empty(T, dtype=np.int64)
        labels[plain] = symbols
        labels[~plain] = ns + np.searchsorted(gds_ids, g[~plain])
        symbol = list(range(ns)) + [-1] * gds_ids.size
        gds_of = [-1] * ns + gds_ids.tolist()
        parent = [-1] * (ns + gds_ids.size)
        S = len(symbol)
        stopping.check(S)
        self.n_clusters_ = ns
        self.labels_phase1_ = labels.copy()
        names = (action_names, gds_names)
        m = self._make_map(X, u, labels, L, symbol, gds_of, parent, A, names)
        self.entropies_.append(dict(m.entropies(), n_states=S, iteration=0))
        m.entropies_ = [dict(e) for e in self.entropies_]
        self.map_phase1_ = m
        h_state = m.state_entropies()
        t1 = time.perf_counter()
        self._emit("phase1", labels=labels, entropies=self.entropies_[-1], map=self.map_phase1_)

        # ---- phase 2: greedy splitting
        splittable = np.array([gid < 0 for gid in gds_of])
        cache: dict[int, object] = {}
        dirty = set(range(S))
        self.stop_reason_ = "stopping rule"
        iteration = 0
        while True:
            inst = build_instances(labels, u, S, A, has_prev, has_next)
            for q in dirty:
                cache[q] = propose_split(inst, q, criterion) if splittable[q] else None
            dirty = set()
            candidates = [p for p in cache.values() if p is not None]
            if not candidates:
                self.stop_reason_ = "no state can be split"
                break
            # the largest score wins; ties go to the smallest state id
            best = max(candidates, key=lambda p: (p.score, -p.state))
            if stopping.should_stop(S, best.score):
                break
            iteration += 1
            q, new = best.state, S
            n_before = int(np.sum(labels == q))
            labels = split_state(labels, u, best, new, S, A, has_prev, has_next)
            # a state's instances change only where a neighbouring step was relabelled q -> new
            touched = np.flatnonzero(labels == new)
            near = np.concatenate([touched, touched[has_prev[touched]] - 1,
                                   touched[has_next[touched]] + 1])
            S += 1
            symbol.append(symbol[q])
            gds_of.append(-1)
            parent.append(q)
            splittable = np.append(splittable, True)
            h_state = np.append(h_state, h_state[q])
            dirty = set(np.unique(labels[near]).tolist()) | {q, new}
            if self._recompute_all:
                dirty = set(range(S))
            record = {
                "iteration": iteration, "state": int(q), "new_state": int(new),
                "gain": best.score, "n_steps": n_before,
                "n_steps_kept": int(np.sum(labels == q)), "n_steps_new": int(np.sum(labels == new)),
                "n_groups": int(best.keys.size),
            }
            self.split_history_.append(record)
            ent = self._counts_entropies(u, labels, has_next, h_state, A)
            self.entropies_.append(dict(ent, n_states=S, iteration=iteration))
            self._emit("split", labels=labels, entropies=self.entropies_[-1], record=record)
        t2 = time.perf_counter()

        self.labels_ = labels
        self.map_ = self._make_map(X, u, labels, L, symbol, gds_of, parent, A, names)
        self.map_.info.update({
            "n_clusters": ns, "stop_reason": self.stop_reason_,
            "criterion": repr(criterion), "stopping": repr(stopping),
            "clusters": repr(clusters), "metric": getattr(metric, "name", repr(metric)),
        })
        self.timings_ = {"phase1": t1 - t0, "phase2": t2 - t1}
        self._emit("done", labels=labels, entropies=self.entropies_[-1], map=self.map_)
        return self

    @staticmethod
    def _counts_entropies(u, labels, has_next, h_state, A) -> dict:
        """The three entropies of a labelling from counts alone.  Observation models are tied to
        symbols, so ``H(o|x)`` only needs each state's share and its model's entropy."""
        S = h_state.size
        t = np.flatnonzero(has_next)
        n = np.bincount(labels, minlength=S)
        ac = np.bincount(labels * A + u, minlength=S * A).reshape(S, A)
        tc = np.bincount((labels[t] * A + u[t]) * S + labels[t + 1], minlength=S * A * S)
        return {"H_o": float(n @ h_state / labels.size), "H_u": conditional_entropy(ac),
                "H_x": conditional_entropy(tc.reshape(S * A, S))}

    def fit_trajectory(self, traj):
        """Fit on a :class:`topomap.Trajectory`, carrying its names and episode lengths."""
        return self.fit(traj.observations, traj.actions, gds=traj.gds, lengths=traj.lengths,
                        n_actions=traj.n_actions, action_names=traj.action_names,
                        gds_names=traj.gds_names)

    def fit_predict(self, observations, actions, gds=None, lengths=None, **kwargs) -> np.ndarray:
        return self.fit(observations, actions, gds, lengths, **kwargs).labels_
