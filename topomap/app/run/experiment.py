"""One experiment from a config: build the components, get the data, learn, evaluate, write.

:func:`run` is plain Python (a config mapping in, a results dict out); the ``topomap`` command
(:mod:`topomap.app.cli`) composes the config with Hydra and calls it, once per job of a sweep
through :func:`~topomap.app.run.job.run_job`.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ...core.learner import MapLearner
from ...core.map.model import TopologicalMap
from ...core.progress import reporting
from ..components.loggers import RunRecord, start_dir
from ..compose.config_checks import check_config
from ..compose.kinds import KINDS
from ..compose.registry import Parts, Registry
from ..compose.schemas import config_keys
from ..results import UNITS
from .checks import (check_before_data, check_cluster_count, check_room_for_clusters,
                     check_state_count, report_missed_target)
from .data import load_data
from .evaluate import check_objective, evaluate, localization_scores, objective_value
from .outputs import claim_output_dir, versions, write_localization, write_outputs
from .progress import Progress

log = logging.getLogger("topomap")

__all__ = ["run", "check_and_build", "CheckedRun", "Experiment", "learn", "localize",
           "make_learner"]


@dataclass(frozen=True)
class Experiment:
    """One run, once its components are built: its resolved config, its components, the
    registry they came from, its folder, and where the jobs of a sweep share simulated
    trajectories (None for a single run)."""

    cfg: dict
    parts: Parts
    registry: Registry
    output_dir: Path
    cache_dir: Path | None = None


@dataclass(frozen=True)
class CheckedRun:
    """A run's config once every check has passed (:func:`check_and_build`): the config as a
    plain dict, the registry, and the components built from it."""

    cfg: dict
    registry: Registry
    parts: Parts


def check_and_build(cfg, registry: Registry | None = None) -> CheckedRun:
    """Every check a run makes before it touches its folder: the config
    (:func:`~topomap.app.compose.config_checks.check_config`), every component built from it
    (:meth:`Registry.build <topomap.app.compose.registry.Registry.build>`: each checks its
    parameters), the learner's settings and what the data will need
    (:func:`~topomap.app.run.checks.check_before_data`).  The ``topomap`` command calls it
    before Hydra makes the run's folder, so a bad setting leaves nothing behind, and hands the
    result to :func:`run`."""
    cfg = _as_dict(cfg)
    registry = registry or Registry.load(cfg.get("plugins") or ())
    check_config(cfg, registry)
    localizing = cfg.get("task", "learn") == "localize"
    if localizing and not cfg.get("map"):
        raise ValueError("task=localize needs the map to apply: map=path/to/map.json")
    parts = registry.build(cfg)
    if not localizing:
        learner = make_learner(cfg, parts)
        with config_keys():
            learner.check_params(n_gds=getattr(parts.env, "n_gds", 0))
        check_before_data(cfg, parts)
    if hasattr(parts.logger, "check"):  # a store that cannot be reached: before any data
        parts.logger.check()
    return CheckedRun(cfg, registry, parts)


def run(cfg, output_dir, *, registry: Registry | None = None, checked: CheckedRun | None = None,
        cache_dir=None, needs_objective: bool = False, on_replaced=None,
        folder_key: str = "hydra.run.dir") -> dict:
    """Run one experiment described by ``cfg`` and write its outputs into ``output_dir``.

    Everything is checked first (:func:`check_and_build`), before any data is read, unless
    ``checked`` holds that check of the same config (the ``topomap`` command made it before
    Hydra made the run's folder); then ``task=learn`` (the default) learns a map (:func:`learn`)
    and ``task=localize`` applies the saved ``map`` to the data (:func:`localize`).  Returns the
    metrics dict.

    A folder that holds another run's outputs is refused
    (:class:`~topomap.app.run.outputs.OutputDirInUse`) unless ``output.overwrite`` is true,
    which removes them first (:func:`~topomap.app.run.outputs.claim_output_dir`) and then calls
    ``on_replaced(output_dir)`` (the command starts the run's log afresh).
    ``needs_objective``: the run's ``objective`` is optimised (an Optuna sweep), so data that
    cannot give it is an error before learning.  ``folder_key``: the config key that chose the
    folder, for the error.
    """
    cfg = _as_dict(cfg)
    overwrite = bool((cfg.get("output") or {}).get("overwrite", False))
    claim_output_dir(output_dir, overwrite, check_only=True, key=folder_key)
    if checked is None or checked.cfg != cfg:
        checked = check_and_build(cfg, registry)
    for err in checked.registry.errors:
        log.warning("%s", err)
    replaced = claim_output_dir(output_dir, overwrite)
    if replaced and on_replaced is not None:
        on_replaced(output_dir)
    experiment = Experiment(checked.cfg, checked.parts, checked.registry, Path(output_dir),
                            None if cache_dir is None else Path(cache_dir))
    if checked.cfg.get("task", "learn") == "localize":
        return localize(experiment)
    return learn(experiment, needs_objective)


def learn(experiment: Experiment, needs_objective: bool = False) -> dict:
    """Learn a map: data -> learner -> evaluation -> outputs (the settings were checked by
    :func:`check_and_build`, before any data is simulated); every file is written atomically."""
    cfg, parts, registry = experiment.cfg, experiment.parts, experiment.registry
    plugin_metrics: dict = {}
    shown = cfg["output"].get("progress", True) and sys.stderr.isatty()
    with Progress(shown) as progress, \
            reporting(progress.on_progress if shown else progress.log_stages):
        learner = make_learner(cfg, parts, [progress.on_event, registry.learner_events(plugin_metrics)])
        check_room_for_clusters(cfg, parts)
        (traj, heldout), timings = load_data(cfg, parts, registry, experiment.cache_dir,
                                             progress, learner=learner)
        check_cluster_count(getattr(parts.clusters, "ns", None), traj)
        check_state_count(parts.stop, len(traj))
        objective = cfg.get("objective", "heldout_loglik")
        if needs_objective:
            check_objective(objective, traj, heldout)
        with config_keys():
            learner.fit_trajectory(traj)
        report_missed_target(learner)
        t0 = time.perf_counter()
        results = evaluate(learner, traj, heldout, parts)
        timings["evaluate"] = time.perf_counter() - t0
        _write_learned(experiment, traj, learner, results, timings=timings,
                       plugin_metrics=plugin_metrics, objective=objective)
    return results


def _write_learned(experiment: Experiment, traj, learner, results, *, timings, plugin_metrics,
                   objective) -> None:
    """Complete the results of a learned map, write the run's files and log the run."""
    cfg, parts = experiment.cfg, experiment.parts
    results.update({
        "split_history": learner.split_history_, "entropy_trace": learner.entropies_,
        "stop_reason": learner.stop_reason_, "timings": {**timings, **learner.timings_},
        "motion": _motion(learner),
        "size_choice": getattr(learner, "size_choice_", None), "resized": _resized(learner),
        "mapping": _mapping(traj, results),
        "versions": versions(), "config": cfg, "plugin_metrics": plugin_metrics, "units": UNITS,
        "objective": {"name": objective, "value": objective_value(results, objective)},
        "providers": {name: experiment.registry.provider(name, cfg[name]["component"])
                      for name, kind in KINDS.items() if kind.learner_arg},  # the learner's
    })
    write_outputs(experiment.output_dir, traj, learner, results, cfg, parts.env)
    if parts.logger is not None:
        cache_dir = experiment.cache_dir
        sweep_dir = None if cache_dir is None else cache_dir.parent  # <sweep>/.cache
        parts.logger.log_run(RunRecord(experiment.output_dir, cfg, results,
                                       start_dir=start_dir(), sweep_dir=sweep_dir))


def _motion(learner) -> dict | None:
    """What the map of a continuous log is (``"places"`` or ``"views"``, the view clusters) and,
    where it is the view clusters, why (``motion_info_["reason"]``); None for other logs."""
    info = getattr(learner, "motion_info_", None)
    if not info:
        return None
    return {"chosen": info.get("chosen"), "reason": info.get("reason")}


def localize(experiment: Experiment) -> dict:
    """Apply the saved map ``cfg["map"]`` to the data: the belief over states at every step
    (forward filtering), the Viterbi states and, with ground truth, their scores."""
    cfg, parts = experiment.cfg, experiment.parts
    m = TopologicalMap.load(cfg["map"])
    log.info("map %s: %d states, %d actions", cfg["map"], m.n_states, m.n_actions)
    with config_keys("data"):
        traj = parts.data.train(parts, int(cfg["seed"]))
    log.info("trajectory: %d steps, %d features, %d actions", len(traj),
             traj.observations.shape[1], traj.n_actions)
    args = (traj.observations, traj.actions)
    kw = {"gds": traj.gds, "lengths": traj.lengths}
    beliefs, viterbi = m.filter(*args, **kw), m.predict(*args, **kw)
    results = {**localization_scores(m, traj, beliefs, viterbi), "config": cfg,
               "versions": versions(), "units": UNITS}
    write_localization(experiment.output_dir, traj, beliefs, viterbi, results)
    log.info("localised %d steps: log-likelihood %.3f per step, mean belief in the most likely "
             "state %.3f", len(traj), results["loglik"], results["mean_max_belief"])
    return results


def _mapping(traj, results) -> dict | None:
    """The map's quality against the steps taken while exploring (None: not mapped while
    exploring), with the batch map's ARI on the whole walk beside it."""
    mapping = (traj.meta or {}).get("mapping")
    if mapping is None:
        return None
    batch = ((results.get("ground_truth") or {}).get("final") or {}).get("ari")
    if mapping["curve"]:
        log.info("mapping while exploring: ARI %s after %d steps (online), %s after the walk "
                 "(batch)", f"{mapping['curve'][-1]['ari']:.3f}", mapping["curve"][-1]["steps"],
                 "n/a" if batch is None else f"{batch:.3f}")
    return dict(mapping, batch_ari=batch)


def _resized(learner) -> dict | None:
    """How the kept refined map was brought to the told size (None: it was not)."""
    info = getattr(learner, "refine_info_", {})
    resized = info.get("resized")
    if resized is None or info.get("kept", "refined") != "refined" or resized["from"] == resized["to"]:
        return None
    return resized


def make_learner(cfg, parts: Parts, callbacks=()) -> MapLearner:
    """A :class:`MapLearner` with the run's components and ``learner.*`` settings."""
    components = {kind.learner_arg: getattr(parts, name) for name, kind in KINDS.items()
                  if kind.learner_arg}
    return MapLearner(**components, random_state=int(cfg["seed"]), callbacks=callbacks,
                      **cfg["learner"])


def _as_dict(cfg) -> dict:
    from omegaconf import OmegaConf

    if OmegaConf.is_config(cfg):
        return OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    return dict(cfg)
