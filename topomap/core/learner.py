"""The map learner: the paper's two phases behind one scikit-learn estimator."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Self

import numpy as np
from numpy.typing import ArrayLike
from sklearn.base import BaseEstimator

from .checks import check_count
from .components import (fit_refinement, fold_renamed, make_components, make_refinement, naming,
                         refinement_hints, refinement_label, set_params, within_told_size)
from .refining import (alphabet, bic_scores, choose_refined_size, refined_from, resized,
                       split_symbol, symbol_map)
from .online import OnlineState, Window
from .online_codebook import WindowClusters
from .online_pass import PassStart, start_map, warm_start, warm_starts, wider_pass
from .phase1.clustering import cluster_observations
from .phase1.heading import phase1_states
from .phase1.start import phase1_labels, start_split, variance_beside
from .size import AutoStates, probe_sizes
from .map.model import TopologicalMap
from .map_methods import MapMethods
from .motion.inputs import check_odometry
from .stream.learner import StreamFit
from .motion.learn import early_headings, fit_places
from .motion.settings import MotionSettings, motion_settings
from .refine.sequence import SymbolSequence
from .split.engine import Splitter
from .split.stopping import TargetStates
from .data.trajectory import FitData, check_fit_data, check_sequences

__all__ = ["MapLearner"]


class MapLearner(StreamFit, MapMethods, BaseEstimator):
    """Learn a topological map from observations and actions (Yairi, Togami & Hori, 2002).

    Phase 1 clusters the non-GDS observations with K-means into ``ns`` symbols, one state each, and
    adds one state per GDS id (never split).  Phase 2 repeatedly splits the state whose split
    gains the most, until the stopping rule fires.  A scikit-learn estimator: ``get_params``,
    ``set_params`` and ``sklearn.base.clone`` work, and ``fit`` never changes the parameters.
    ``criterion`` and ``stopping``, the names of ``split`` and ``stop`` before 0.3, are still
    taken (and by ``set_params``) with a ``FutureWarning`` until 0.4.

    Parameters
    ----------
    n_clusters : int
        ``ns``, the number of K-means clusters (used when ``clusters`` is None).
    n_states : int or "auto"
        Target state count (used when ``stop`` is None); ``"auto"`` chooses it by the
        held-out log-likelihood (:class:`topomap.core.size.AutoStates`).
    clusters : object, optional
        Cluster-count policy with ``choose(Z, random_state)`` returning ``ns`` or ``(ns, details)``
        (e.g. :class:`topomap.core.phase1.clustering.BICClusters`).  Default: ``FixedClusters(n_clusters)``.
    metric : str or object
        ``"euclidean"`` (default), ``"standardized"``, ``"cosine"`` or an object with
        ``fit_transform(X)``.
    split : str or object
        The split criterion (the config's ``split``): ``"entropy"`` (default) or an object with
        ``propose(counts) -> (side, score) | None``.
    stop : object, optional
        The stopping rule (the config's ``stop``), with ``check(n_initial)`` and
        ``should_stop(n_states, best_score)``.  Default: ``TargetStates(n_states)``.
    covariance_type : {"diag", "full"}
        Form of the Gaussian observation models.
    reg_covar : float
        Added to every variance, relative to the data's mean feature variance.
    n_init : int
        K-means restarts (k-means++ initialisations; the best inertia wins).
    phase1 : {"auto", "full", "distinct", "sample", "minibatch"}
        How K-means runs (:data:`topomap.core.phase1.clustering.METHODS`): ``"full"`` is the paper's
        exact fit on every step, which ``"auto"`` picks for runs up to ``T * ns * D = 1e7`` (the
        paper's included); above that it clusters the distinct rows with their counts when
        observations repeat, else fits on a sample and assigns every step.
    sample_size : int, optional
        Rows K-means is fitted on with ``phase1="sample"`` (default ``max(20000, 64 ns)``).
    refine : None, "em", "cscg" or object
        A refinement phase after the split (:mod:`topomap.core.refine.methods`): ``"em"`` re-estimates
        every state jointly with EM over a clone budget sized by the split, merges states that
        are one place and splits compound ones (maps that stay right under heavy aliasing);
        ``"cscg"`` is EM alone from phase 1 with CSCG's recipe, ignoring the split; or an
        estimator whose ``fit(sequence, split_state_symbol, random_state)`` returns itself with
        ``labels_``, ``state_symbol_`` and ``info_`` (a fit refines a clone of it).  None
        (default): the paper's method alone.  Built-ins group their settings by stage
        (:mod:`topomap.core.refine.settings`: ``EMRefinement(hard={"max_iter": 40})``).
    refined_size : "told" or "free"
        With a refinement and a told number of states (``n_states`` an int, or a
        :class:`~topomap.core.split.stopping.TargetStates` rule): ``"told"`` (default) brings the
        refined map to that number (:mod:`topomap.core.refine.resize`: the least costly merges of
        same-symbol states, or further splits); ``"free"`` keeps the number the refinement chose.
    motion : MotionSettings, "auto", "discrete", "continuous" or "robot"
        How a log recorded at 10-50 Hz is mapped: places instead of a refinement, or why not
        (:class:`~topomap.core.motion.MotionSettings` or a mapping; docs/continuous.md).
    heading : {"auto", "on", "off"}
        Phase 1's states as (symbol, heading) pairs, the heading integrated from actions that
        turn the view (:mod:`topomap.core.phase1.heading`): ``"auto"`` where the data support
        it, ``"on"`` wherever an action turns, ``"off"`` never (nor :meth:`fit_stream`).  MiniGrid
        FourRooms 50,000 steps, ``refine="em"``, seeds 0-2: ARI 0.95 against 0.69 (Empty-16x16 0.93).
    window : int
        :meth:`partial_fit` only: the latest steps a wider pass re-learns the map's structure
        from (:mod:`topomap.core.online`; steps: 50,000 holds a FourRooms walk of 1,036 places,
        whose map learned from its last 20,000 steps alone lost 0.12 ARI).
    refit_every : int
        :meth:`partial_fit` only: new steps after which a wider pass runs (earlier, while fewer
        steps than that were seen at the last pass).
    random_state : int
        Seed of K-means (the only random part of the method).
    callbacks : sequence of callables
        Each is called as ``callback(event, info)`` with ``event`` in ``"phase1"``, ``"split"``,
        ``"refine"`` (after a refinement), ``"done"`` and ``info`` a dict (``learner``,
        ``labels``, ``entropies`` and, for splits, the history record), by every fit, the wider
        passes of :meth:`partial_fit` included (on the window's steps).  Used to log progress or
        record extra metrics.  ``labels`` of a split is the learner's working array (int16 while
        the states fit it), changed in place by later splits: copy it to keep it.

    Attributes
    ----------
    labels_ : (T,) int -- the state of every step (of every step seen after :meth:`partial_fit`)
    labels_phase1_, labels_split_ : (T,) int -- the state of every step after phase 1 and after
        phase 2, before any refinement (not kept by :meth:`partial_fit`)
    map_ : TopologicalMap -- the final map (refined, with ``refine``)
    map_phase1_ : TopologicalMap -- the map before any split
    map_split_ : TopologicalMap -- the map after splitting (``map_`` without ``refine``; a
        wider pass from the last map: the map its refinement started from)
    refine_info_ : dict -- the refinement's stages (with ``refine``)
    symbol_ambiguity_ : float -- the share of steps phase 1 may misread (``refine="em"``)
    heading_ : dict -- phase 1's heading: ``used``, ``reason`` if not, ``turns``, measurements
    motion_info_ : dict -- what the places of a continuous log measured, the check's errors and
        which map was ``chosen`` (``"places"``, ``"views"``, ``"robot"``; a continuous log's)
    robot_map_ : RobotMap -- the robot route's cells (``"robot"`` chosen) ``predict`` places on
    size_choice_ : dict -- with ``stop=auto``: the criterion, the chosen count and every score
    n_clusters_ : int -- the ``ns`` actually used
    cluster_choice_ : dict -- what the cluster-count policy measured (e.g. ``{"bic": {...}}``)
    phase1_method_ : str -- the K-means method that ran (``phase1`` with ``"auto"`` resolved)
    n_features_in_ : int -- observation dimension seen by ``fit``
    split_history_ : list of dict -- ``iteration``, ``state``, ``new_state``, ``gain`` and sizes
    entropies_ : list of dict -- ``H_o``, ``H_u``, ``H_x`` after phase 1 and after every split
    stop_reason_ : str
    timings_ : dict -- seconds spent in ``phase1``, ``phase2`` (and ``refine`` or ``places``)
    online_ : dict -- after :meth:`partial_fit`: steps seen, calls, wider passes, the steps the
        last call touched, the first step the last pass learned from, the bytes kept
    """

    #: re-evaluate every state after each split instead of only the neighbours of the new state
    #: (the results are identical; the tests use this to check that)
    _recompute_all = False

    def __init__(self, n_clusters: int = 20, n_states: int = 30, *, clusters=None,
                 metric="euclidean", split="entropy", stop=None,
                 covariance_type: str = "diag", reg_covar: float = 1e-3, n_init: int = 3,
                 phase1: str = "auto", sample_size: int | None = None, refine=None,
                 refined_size: str = "told", motion: MotionSettings | str = MotionSettings(),
                 heading: str = "auto", window: int = 50000, refit_every: int = 2000,
                 random_state: int = 0, callbacks=(), **renamed):
        self.n_clusters = n_clusters
        self.n_states = n_states
        self.clusters = clusters
        self.metric = metric
        self.split = split
        self.stop = stop
        self.covariance_type = covariance_type
        self.reg_covar = reg_covar
        self.n_init = n_init
        self.phase1 = phase1
        self.sample_size = sample_size
        self.refine = refine
        self.refined_size = refined_size
        self.motion = motion
        self.heading = heading
        self.window = window
        self.refit_every = refit_every
        self.random_state = random_state
        self.callbacks = callbacks
        if renamed:  # criterion=, stopping= (before 0.3)
            self.split, self.stop = fold_renamed(renamed, split, stop, stacklevel=2)

    set_params = set_params

    # ------------------------------------------------------------------ the paper's method
    def fit(self, observations: ArrayLike, actions: ArrayLike, gds: ArrayLike | None = None,
            lengths: ArrayLike | None = None, *, odometry: ArrayLike | None = None,
            n_actions: int | None = None, action_names: Sequence[str] | None = None,
            gds_names: Sequence[str] | None = None) -> Self:
        """Learn the map.  Returns ``self``.

        ``observations`` (T, D): float64, or float32 used as it is (half the memory; K-means
        computes in float32), other types as float64; ``actions`` (T,) ints in ``[0,
        n_actions)``, ``gds`` (T,) ints with -1 for "no GDS", ``lengths`` the episode lengths
        when several episodes are concatenated, ``odometry`` (T, 3) the robot's dead reckoning
        (:mod:`topomap.core.motion.inputs`).  A fit forgets any earlier :meth:`partial_fit`."""
        data = check_fit_data(observations, actions, gds, lengths, n_actions, action_names,
                              gds_names)
        odometry = check_odometry(odometry, data.u.size, data.lengths)
        self._online = None
        return self._fit(data, odometry=odometry)

    def _fit(self, data: FitData, symbols: np.ndarray | None = None, motion: bool = True,
             warm: PassStart | None = None, odometry: np.ndarray | None = None) -> Self:
        """Phase 1, the split, the map and the refinement on checked ``data``, forgetting what an
        earlier fit (or pass) learned.  ``symbols``: the K-means symbol of every non-GDS step,
        given instead of running K-means (a wider pass of :meth:`partial_fit` gives the
        codebook's); ``motion=False``: no places of a continuous log (wider passes); ``warm``:
        how a wider pass splits and refines (:class:`~topomap.core.online_pass.PassStart`)."""
        clusters, metric, criterion, stopping = make_components(self)
        refinement = make_refinement(self.refine)
        places = motion_settings(self.motion) if motion else None
        self._forget_fit()
        self._solving = early_headings(places, data, odometry)  # beside phase 1 and the split
        self.n_features_in_ = data.X.shape[1]
        t0 = time.perf_counter()
        told = stopping.n_states if isinstance(stopping, TargetStates) else None
        heading = "off" if warm and warm.old is not None else self.heading  # afresh: as fit
        splitter = self._phase1(data, clusters, metric, criterion, stopping, symbols,
                                capped=warm is not None, heading=heading, told=told)
        auto = stopping if isinstance(stopping, AutoStates) else None
        if auto is not None:
            stopping = TargetStates(self._choose_size(data, splitter, auto))
        t1 = time.perf_counter()
        self.stop_reason_ = "no state can be split"  # a pass from the last map splits none
        while (warm is None or warm.splits(auto)) and (best := splitter.best()) is not None:
            if stopping.should_stop(splitter.n_states, best.score):
                self.stop_reason_ = "stopping rule"
                break
            self._record_split(splitter, best)
        splitter.finish(widen=True)
        t2 = time.perf_counter()
        self.labels_ = self.labels_split_ = splitter.labels
        info = {
            "n_clusters": self.n_clusters_, "stop_reason": self.stop_reason_,
            "criterion": repr(criterion), "stopping": repr(stopping),
            "clusters": repr(clusters), "metric": getattr(metric, "name", repr(metric)),
        }
        if self._headed is not None:
            info["heading"] = self._headed.record(data.action_names)
        if hasattr(self, "size_choice_"):
            info["size_choice"] = {k: self.size_choice_[k] for k in ("criterion", "chosen")}
        root, first = splitter.roots(), self.map_phase1_  # symbols kept: phase 1's P(o|x)
        self.map_ = self.map_split_ = self._make_map(
            data, splitter, info, models=(first.means[root], first.covariances[root]))
        self.timings_ = {"phase1": t1 - t0, "phase2": t2 - t1}
        continuous = places is not None and fit_places(self, data, places, metric, odometry)
        if warm is not None and not warm.refines(data.u.size, splitter.n_states):
            refinement = None  # too few steps per state: the pass keeps the split
        if refinement is not None and not continuous:
            if auto is not None and auto.criterion == "heldout" and self.refined_size == "told":
                told = choose_refined_size(self, data, splitter, refinement, auto)
            self._refine(data, splitter, refinement, told, warm)
            self.timings_["refine"] = time.perf_counter() - t2
        self._emit("done", labels=self.labels_, entropies=self.entropies_[-1], map=self.map_)
        return self

    def partial_fit(self, observations, actions, gds=None, *, new_episode: bool = False,
                    odometry=None, n_actions=None, action_names=None, gds_names=None):
        """Learn from the next steps of the walk (scikit-learn's incremental convention).

        Each call continues the walk of the calls before it (``new_episode=True`` starts a new
        episode with its first step); afterwards ``labels_`` covers every step seen and ``map_``
        is the current map, with or without ``refine`` and with ``n_states="auto"``.  The cost of
        a call does not grow with the steps seen before it: its chunk is decoded with the map and
        counted, and every ``refit_every`` steps a wider pass re-learns the map from the latest
        ``window`` steps (:mod:`topomap.core.online` says what is kept).  ``n_actions``,
        ``action_names`` and ``gds_names`` may be given with any call (more actions than the
        map has bring a wider pass).  A cluster count above the distinct observations a pass's
        window holds is capped at them and grown as new views appear, with one warning
        (:mod:`topomap.core.online_codebook`; ``online_["clusters"]``).  A call that fails
        changes nothing.  :meth:`fit` starts over.  ``odometry`` is checked as :meth:`fit`'s
        (wider passes do not use it).  Returns ``self``.
        """
        X, u, g, _ = check_sequences(observations, actions, gds, None, min_length=1)
        check_odometry(odometry, X.shape[0])
        window, every = check_count(self.window, "window"), check_count(self.refit_every,
                                                                        "refit_every")
        state = getattr(self, "_online", None) or OnlineState(Window(window))
        starts = np.zeros(X.shape[0], dtype=bool)
        starts[0] = new_episode or state.n_steps == 0
        saved, learned = state.snapshot(), self._learned()
        try:
            state.take(X, u, g, starts, n_actions, action_names, gds_names)
            if state.needs_pass(getattr(self, "map_", None), every, warm_starts(self.refine)):
                wider_pass(self, state, X)
            else:
                self.map_ = state.decode_chunk(self.map_, X.shape[0])
        except BaseException:
            state.restore(saved)
            self._forget_fit()
            for name, value in learned.items():
                setattr(self, name, value)
            raise
        state.n_calls += 1
        self._online = state
        self.labels_ = state.record.labels
        self.online_ = state.summary()
        return self

    def _learned(self) -> dict:
        """The learned attributes (names ending in ``_``), to restore after a failed call."""
        return {k: v for k, v in vars(self).items() if k.endswith("_") and not k.startswith("_")}

    def _refine(self, data: FitData, splitter: Splitter, refinement, told: int | None,
                warm=None) -> None:
        """Re-estimate every state jointly (:mod:`topomap.core.refine.methods`); the split map
        stays as ``map_split_``.  With ``guard``, the refined map is kept only when its BIC is no
        worse (both BICs and the map kept go into ``refine_info_``).  Refined states have no
        parent; ``map_.info["refined_from"]`` names, for each, the split state most of its steps
        held."""
        ns, ids, emitted = alphabet(self)
        seq = SymbolSequence.build(self.labels_phase1_, data.u, data.lengths, data.n_actions, ids)
        runner, init = warm_start(refinement, warm, seq.sym)
        if init is not None:  # EM starts from the last map's states, not from a split
            self.labels_split_, self.map_split_ = start_map(self, data, init)
        with naming(self, "refine"):
            fit = fit_refinement(runner, seq, split_symbol(splitter), self.random_state,
                                 init, self.labels_split_, **refinement_hints(self, data, runner))
        if runner is not refinement:  # the last map's refinement found no misread symbols
            fit.info.update(soft="skipped", soft_from="the last map")
        if told is not None and self.refined_size == "told" and fit.n_states != told:
            fit = resized(fit, data, told, splitter.criterion, ids)
        refined = symbol_map(data, slice(None), data.lengths, fit.labels,
                             emitted(fit.state_symbol), ns,
                             covariance_type=self.covariance_type, reg_covar=self.reg_covar,
                             action_names=data.action_names, gds_names=data.gds_names,
                             split_history=self.split_history_, info=dict(self.map_split_.info))
        self.refine_info_ = dict(fit.info)
        record = {"refine": refinement_label(refinement), "refine_info": self.refine_info_}
        if getattr(refinement, "guard", False):
            scores = bic_scores(data, {"split": (self.map_split_, self.labels_split_),
                                       "refined": (refined, fit.labels)})
            keep = scores["refined"] <= scores["split"]
            self.refine_info_.update(bic=scores, kept="refined" if keep else "split")
            if not keep:
                self.labels_ = self.labels_split_
                self.map_ = self.map_split_ = replace(
                    self.map_split_, info=dict(self.map_split_.info, **record))
                return
        self.labels_ = fit.labels
        self.entropies_.append(dict(refined.entropies(), n_states=refined.n_states,
                                    iteration=len(self.split_history_) + 1, stage="refined"))
        origin = refined_from(fit.labels, self.labels_split_, fit.n_states,
                              self.map_split_.n_states)
        self.map_ = replace(refined, entropy_history=self.entropies_,
                            info=dict(refined.info, **record, refined_from=origin))
        self._emit("refine", labels=self.labels_, entropies=self.entropies_[-1], map=self.map_)

    def _phase1(self, data: FitData, clusters, metric, criterion, stopping,
                symbols=None, capped: bool = False, heading: str = "off",
                told: int | None = None) -> Splitter:
        """K-means symbols (or the ``symbols`` given), one state each -- or one per (symbol,
        heading) pair, as ``heading`` and the data say (:func:`phase1_states`; ``told``: the
        states asked for) -- plus one state per GDS id, never split (paper Section 3.2).
        ``capped``: a wider pass of :meth:`partial_fit`, whose count is capped at the distinct
        observations of its window (:class:`~topomap.core.online_codebook.WindowClusters`)."""
        plain = data.gds < 0
        if plain.sum() < 1:
            raise ValueError("every step is labelled as a GDS; no observations are left to cluster")
        variance = variance_beside(data.X)  # the observation models' scale: needs no labels
        if symbols is not None:
            choice = {"method": "online codebook"}
            symbols = np.array(symbols, dtype=np.int64)  # the caller's array is left alone
        else:
            searched = within_told_size(clusters, stopping, np.unique(data.gds[~plain]).size)
            searched = WindowClusters(searched) if capped else searched
            with naming(self, "clusters", method="phase1"):
                symbols, choice = cluster_observations(
                    data.X if plain.all() else data.X[plain], searched, metric,
                    n_init=self.n_init, random_state=self.random_state, method=self.phase1,
                    sample_size=self.sample_size, checked=True)
        self.phase1_method_ = choice.pop("method")
        self.cluster_choice_ = choice
        ns = self.n_clusters_ = int(symbols.max()) + 1
        # the splitter works on its own copy: the symbols are kept as they are
        labels, gds_ids = phase1_labels(symbols, ns, data.gds)
        del symbols
        labels, ns, symbol, self._headed, self.heading_ = phase1_states(heading, labels, ns,
                                                                        data, told)
        self.n_clusters_ = ns
        with naming(self, "stop"):
            stopping.check(len(symbol) + gds_ids.size)
        self.labels_phase1_ = labels
        self.split_history_, self.entropies_ = [], []
        splitter, models = start_split(data, labels, ns, gds_ids, variance, criterion=criterion,
                                       recompute_all=self._recompute_all,
                                       covariance_type=self.covariance_type,
                                       reg_covar=self.reg_covar,
                                       symbol=None if self._headed is None else symbol)
        m = self._make_map(data, splitter, models=models, labels=labels)
        self.entropies_.append(dict(m.entropies(), n_states=m.n_states, iteration=0))
        m = self.map_phase1_ = replace(m, entropy_history=self.entropies_)
        splitter.obs_entropy = m.state_entropies()
        self._emit("phase1", labels=labels, entropies=self.entropies_[-1], map=m)
        return splitter

    def _record_split(self, splitter: Splitter, best) -> None:
        """Apply the best split and record it (history, entropies, callbacks)."""
        iteration = len(self.split_history_) + 1
        record = {"iteration": iteration, **splitter.apply(best)}
        self.split_history_.append(record)
        self.entropies_.append(dict(splitter.entropies(), n_states=splitter.n_states,
                                    iteration=iteration))
        self._emit("split", labels=splitter.labels, entropies=self.entropies_[-1], record=record)

    def check_params(self, n_gds: int = 0) -> None:
        """Check what can be checked before any data is seen; raise a
        :class:`~topomap.core.checks.ParameterError` naming the parameter (``n_states``,
        ``stop.n_states`` for a stopping rule passed as ``stop``, ``refine.<param>`` for the
        refinement's).  The stopping rule is also checked against the states phase 1 will
        create: at least ``min_clusters`` of the cluster-count policy (when it tells) plus
        ``n_gds``, the GDS the data is expected to hold.  ``fit`` checks again with the real
        counts."""
        clusters, _, _, stopping = make_components(self)
        least = getattr(clusters, "min_clusters", None)
        if least is not None:
            with naming(self, "stop"):
                stopping.check(int(least) + int(n_gds))
        refinement = make_refinement(self.refine)
        motion_settings(self.motion)
        if callable(getattr(refinement, "check_params", None)):
            with naming(self, "refine"):
                refinement.check_params()

    # ------------------------------------------------------------------ helpers
    def _choose_size(self, data: FitData, splitter: Splitter, rule: AutoStates) -> int:
        """The number of states ``stop=auto`` picks (:func:`topomap.core.size.probe_sizes`);
        ``size_choice_`` keeps the scores."""
        self.size_choice_ = probe_sizes(self.labels_phase1_, data, splitter, rule)
        return self.size_choice_["chosen"]

    def _emit(self, event: str, **info) -> None:
        for cb in self.callbacks:
            cb(event, dict(info, learner=self))

    def _make_map(self, data: FitData, splitter: Splitter, info=None, models=None, labels=None):
        return TopologicalMap.from_labels(  # int64 ``labels`` spare a copy of the splitter's
            data.X, data.u, splitter.labels if labels is None else labels, lengths=data.lengths,
            state_symbol=splitter.symbol, state_gds=splitter.gds, state_parent=splitter.parent,
            n_actions=data.n_actions, covariance_type=self.covariance_type, models=models,
            reg_covar=self.reg_covar, action_names=data.action_names, gds_names=data.gds_names,
            split_history=self.split_history_, entropy_history=self.entropies_, info=info,
            counts=splitter.count_tables())

    def _forget_fit(self) -> None:
        """Drop every attribute an earlier fit learned (names ending in ``_``), so a refit never
        shows the last fit's refinement, size choice or split map as its own."""
        for name in self._learned():
            delattr(self, name)
        self._headed = None  # phase 1's (symbol, heading) pairs, where used
