"""The streamed fit: the paper's two phases on logs that need not fit in memory together.

What is read, and where (:mod:`.engines`): a survey of every log (steps, episodes, actions,
GDS; the observations of an ``.npz`` log are not read), the rows K-means is fitted on, and a
pass over every log giving each step its symbol and the observation moments (:mod:`.jobs`).
What is kept, here: every step's phase-1 state and action as small integers (3 bytes a step
with fewer than 32,768 states and 128 actions), the episode masks and the split's own tables
(:class:`~topomap.core.split.engine.Splitter`): 20 bytes a step at the peak (measured at 10^8
steps: 2.0 GB with the interpreter), against 8 D for the observations (120 at D = 15), which
are never held together.  The split is the in-memory
fit's, on the same states and actions, so given the same phase-1 symbols it makes the same
states, step for step.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..checks import ParameterError
from ..components import make_components, naming, within_told_size
from ..data.logs import CHUNK_STEPS, Logs
from ..map.model import TopologicalMap
from ..size import AutoStates
from ..split.engine import Splitter
from ..stats import episode_masks
from .engines import make_engine
from .jobs import assign_job
from .phase1 import check_metric, fit_codebook, observation_models, phase1_states
from .plan import make_plan, survey_job

__all__ = ["fit_stream"]


def _components(learner):
    """The learner's components, refused where a streamed fit cannot run them."""
    clusters, metric, criterion, stopping = make_components(learner)
    if learner.refine is not None:
        raise ParameterError("refine", f"={learner.refine!r}: a streamed fit runs the paper's "
                                       "two phases; a refinement needs every observation in "
                                       "memory (refine=None)")
    if isinstance(stopping, AutoStates):
        raise ParameterError("n_states", "='auto' scores held-out observations in memory; a "
                                         "streamed fit needs a number of states or a rule")
    check_metric(metric)
    return clusters, metric, criterion, stopping


def fit_stream(learner, source, *, n_actions=None, action_names=None, gds_names=None,
               engine=None, workers=None, rosbag=None, chunk_steps=CHUNK_STEPS):
    """:meth:`topomap.MapLearner.fit_stream` (its docstring says what each argument is)."""
    clusters, metric, criterion, stopping = _components(learner)
    logs = source if isinstance(source, Logs) else Logs(source, rosbag=rosbag,
                                                        chunk_steps=chunk_steps)
    runner = make_engine(engine, workers)
    learner._forget_fit()
    learner._online = None
    clock = [time.perf_counter()]
    plan = make_plan(logs, runner.map(survey_job, logs, [(i,) for i in range(len(logs))]),
                     n_actions, action_names, gds_names)
    clock.append(time.perf_counter())
    searched = within_told_size(clusters, stopping, plan.gds_ids.size)
    with naming(learner, "clusters", method="phase1"):
        book, choice = fit_codebook(learner, logs, plan, runner, searched, metric)
    clock.append(time.perf_counter())
    full_cov = learner.covariance_type == "full"
    adt = np.min_scalar_type(-plan.n_actions)
    results = runner.map(assign_job, logs, [(i, info.steps, book, full_cov, adt)
                                            for i, info in enumerate(plan.infos)])
    labels, u, ns, moments = phase1_states(results, plan, book.kmeans.n_clusters, full_cov)
    del results
    clock.append(time.perf_counter())
    learner.n_features_in_ = plan.n_features
    learner.phase1_method_ = choice.pop("method")
    learner.cluster_choice_, learner.n_clusters_ = choice, ns
    with naming(learner, "stop"):
        stopping.check(ns + plan.gds_ids.size)
    splitter = _start(learner, plan, labels, u, ns, moments, criterion)
    clock.append(time.perf_counter())
    _split(learner, splitter, stopping, plan, clusters, criterion, metric)
    clock.append(time.perf_counter())
    learner.timings_ = {"phase1": clock[4] - clock[0], "phase2": clock[5] - clock[4]}
    learner.stream_info_ = {"logs": len(logs), "steps": int(labels.size), "engine": runner.name,
                            "survey": clock[1] - clock[0], "sample": clock[2] - clock[1],
                            "assign": clock[3] - clock[2]}
    learner._emit("done", labels=learner.labels_, entropies=learner.entropies_[-1],
                  map=learner.map_)
    return learner


def _map(learner, plan, splitter, models, info=None) -> TopologicalMap:
    """The map of the splitter's labelling (its counts, the observation models given)."""
    return TopologicalMap(
        splitter.symbol, splitter.gds, splitter.parent, *models, *splitter.count_tables(),
        info={"covariance_type": learner.covariance_type, **(info or {})},
        action_names=plan.action_names, gds_names=plan.gds_names,
        split_history=learner.split_history_, entropy_history=learner.entropies_)


def _start(learner, plan, labels, u, ns, moments, criterion) -> Splitter:
    """The phase-1 map and the splitter (as the in-memory ``_phase1`` makes them)."""
    ids = plan.gds_ids
    symbol, gds = list(range(ns)) + [-1] * ids.size, [-1] * ns + ids.tolist()
    models = observation_models(moments, labels.size, learner.covariance_type,
                                learner.reg_covar)
    learner.labels_phase1_ = labels
    learner.split_history_, learner.entropies_ = [], []
    splitter = Splitter(labels, u, plan.n_actions, *episode_masks(labels.size, plan.lengths),
                        symbol=symbol, gds=gds, obs_entropy=np.zeros(0), criterion=criterion,
                        recompute_all=learner._recompute_all)
    m = _map(learner, plan, splitter, models)
    learner.entropies_.append(dict(m.entropies(), n_states=m.n_states, iteration=0))
    m = learner.map_phase1_ = replace(m, entropy_history=learner.entropies_)
    splitter.obs_entropy = m.state_entropies()
    learner._emit("phase1", labels=labels, entropies=learner.entropies_[-1], map=m)
    return splitter


def _split(learner, splitter, stopping, plan, clusters, criterion, metric) -> None:
    """Phase 2 and the split map (as the in-memory fit's)."""
    learner.stop_reason_ = "no state can be split"
    while (best := splitter.best()) is not None:
        if stopping.should_stop(splitter.n_states, best.score):
            learner.stop_reason_ = "stopping rule"
            break
        learner._record_split(splitter, best)
    splitter.finish()
    learner.labels_ = learner.labels_split_ = splitter.labels
    info = {"n_clusters": learner.n_clusters_, "stop_reason": learner.stop_reason_,
            "criterion": repr(criterion), "stopping": repr(stopping),
            "clusters": repr(clusters), "metric": getattr(metric, "name", repr(metric))}
    root, first = splitter.roots(), learner.map_phase1_
    learner.map_ = learner.map_split_ = _map(
        learner, plan, splitter, (first.means[root], first.covariances[root]), info)
