"""One experiment from a config: build the components, get the data, learn, evaluate, write.

:func:`run` is plain Python (a config mapping in, a results dict out); the ``topomap`` command
(:mod:`topomap.app.cli`) composes the config with Hydra and calls it, once per job of a sweep
through :func:`run_job`.
"""

from __future__ import annotations

import logging
import os
import socket
import sys
import time
import traceback
from contextlib import contextmanager
from pathlib import Path

from ..core.checks import ParameterError
from ..core.learner import MapLearner
from ..core.map.model import TopologicalMap
from ..core.progress import reporting
from .config import learner_key
from .config_checks import check_config
from .data import TrajectoryCache, trajectory_key
from .evaluate import check_objective, evaluate, localization_scores, objective_value
from .outputs import (STATUS_FILE, OutputDirInUse, claim_output_dir, versions, write_json,
                      write_localization, write_outputs)
from .kinds import KINDS
from .loggers import RunRecord, start_dir
from .registry import Parts, Registry

log = logging.getLogger("topomap")

__all__ = ["run", "run_job", "make_learner", "load_data", "config_keys", "Progress", "STATUS_FILE",
           "CACHE_DIR", "write_status", "interrupt_on_sigterm"]
#: the folder of a sweep where its jobs share simulated trajectories
CACHE_DIR = ".cache"
#: what the less obvious numbers of metrics.json measure
UNITS = {
    "H_o": "bits; a differential entropy of the Gaussian observation models (continuous "
           "observations), so it can be negative",
    "H_u, H_x": "bits",
    "heldout_loglik": "nats per step; a log-density of continuous observations, so it can be "
                      "positive",
    "loglik": "nats per step (task=localize); a log-density, like heldout_loglik",
}


def run(cfg, output_dir, *, registry: Registry | None = None, cache_dir=None,
        needs_objective: bool = False) -> dict:
    """Run one experiment described by ``cfg`` and write its outputs into ``output_dir``.

    The config is checked (:func:`~topomap.app.config_checks.check_config`), every component is built
    from it (:meth:`Registry.build <topomap.app.registry.Registry.build>`), before any data is
    read; then ``task=learn`` (the default) learns a map (:func:`learn`) and ``task=localize``
    applies the saved ``map`` to the data (:func:`localize`).  Returns the metrics dict.

    A folder that holds another run's outputs is refused (:class:`~topomap.app.outputs.OutputDirInUse`)
    unless ``output.overwrite`` is true, which removes them first
    (:func:`~topomap.app.outputs.claim_output_dir`).  ``needs_objective``: the run's
    ``objective`` is optimised (an Optuna sweep), so data that cannot give it is an error before
    learning.
    """
    cfg = _as_dict(cfg)
    claim_output_dir(output_dir, bool((cfg.get("output") or {}).get("overwrite", False)))
    registry = registry or Registry.load(cfg.get("plugins") or ())
    for err in registry.errors:
        log.warning("%s", err)
    check_config(cfg, registry)
    localizing = cfg.get("task", "learn") == "localize"
    if localizing and not cfg.get("map"):
        raise ValueError("task=localize needs the map to apply: map=path/to/map.json")
    parts = registry.build(cfg)
    if localizing:
        return localize(cfg, parts, output_dir)
    return learn(cfg, parts, output_dir, registry, cache_dir, needs_objective)


def learn(cfg: dict, parts: Parts, output_dir, registry: Registry, cache_dir=None,
          needs_objective: bool = False) -> dict:
    """Learn a map: data -> learner -> evaluation -> outputs.

    The learner's settings are checked before any data is simulated, so a bad setting fails
    first; every file is written atomically.  ``cache_dir``: where simulated trajectories are
    shared between runs (the jobs of a sweep).
    """
    plugin_metrics: dict = {}
    shown = cfg["output"].get("progress", True) and sys.stderr.isatty()
    with Progress(shown) as progress, reporting(progress.on_progress if shown else None):
        learner = make_learner(cfg, parts, [progress.on_event, registry.learner_events(plugin_metrics)])
        with config_keys():
            learner.check_params(n_gds=getattr(parts.world, "n_gds", 0))  # before any simulation
        check_room_for_clusters(cfg, parts)
        (traj, heldout), t_data = load_data(cfg, parts, registry, cache_dir, progress,
                                            learner=learner)
        check_cluster_count(getattr(parts.clusters, "ns", None), traj)
        objective = cfg.get("objective", "heldout_loglik")
        if needs_objective:
            check_objective(objective, traj, heldout)
        with config_keys():
            learner.fit_trajectory(traj)
        _report_missed_target(learner)
        t0 = time.perf_counter()
        results = evaluate(learner, traj, heldout, parts)
        t_data["evaluate"] = time.perf_counter() - t0
        _write_learned(cfg, parts, registry, output_dir, traj, learner, results, t_data,
                       plugin_metrics, objective, cache_dir)
    return results


def _write_learned(cfg, parts, registry, output_dir, traj, learner, results, t_data,
                   plugin_metrics, objective, cache_dir) -> None:
    """Complete the results of a learned map, write the run's files and log the run."""
    results.update({
        "split_history": learner.split_history_, "entropy_trace": learner.entropies_,
        "stop_reason": learner.stop_reason_, "timings": {**t_data, **learner.timings_},
        "size_choice": getattr(learner, "size_choice_", None), "resized": _resized(learner),
        "mapping": _mapping(traj, results),
        "versions": versions(), "config": cfg, "plugin_metrics": plugin_metrics, "units": UNITS,
        "objective": {"name": objective, "value": objective_value(results, objective)},
        "providers": {name: registry.provider(name, cfg[name]["component"])
                      for name, kind in KINDS.items() if kind.learner_arg},  # the learner's
    })
    write_outputs(Path(output_dir), traj, learner, results, cfg, parts.world)
    if parts.logger is not None:
        sweep_dir = None if cache_dir is None else Path(cache_dir).parent  # <sweep>/.cache
        parts.logger.log_run(RunRecord(Path(output_dir), cfg, results, start_dir=start_dir(),
                                       sweep_dir=sweep_dir))


def check_room_for_clusters(cfg: dict, parts: Parts) -> None:
    """Say, before any data or BIC, when a told ``stop.n_states`` narrows the cluster counts a
    policy choosing from the data searches (``clusters=bic``: ``min_ns`` .. ``max_ns``, plus the
    world's GDS): :class:`~topomap.MapLearner` searches only the counts it leaves room for.  (A
    told size below ``min_ns`` plus the GDS is refused by the learner's own checks, before
    this.)"""
    from ..core.split.stopping import TargetStates

    most = getattr(parts.clusters, "max_ns", None)
    least = getattr(parts.clusters, "min_ns", None)
    stop = parts.stop
    if most is None or least is None or not isinstance(stop, TargetStates):
        return
    n_gds = int(getattr(parts.world, "n_gds", 0) or 0)
    if least + n_gds <= stop.n_states < most + n_gds:
        log.info("clusters=%s searches %d to %d clusters: stop.n_states=%d leaves room for no "
                 "more%s", cfg["clusters"]["component"], least, stop.n_states - n_gds,
                 stop.n_states, f" beside the {n_gds} GDS" if n_gds else "")


#: fewer steps than this per K-means symbol, on average, and a run warns (see
#: :func:`check_cluster_count`)
STEPS_PER_SYMBOL = 10


def check_cluster_count(ns: int | None, traj) -> None:
    """Refuse ``clusters.ns`` above half the steps K-means clusters (the steps at no GDS): most
    symbols would hold a single step, whose transitions cannot be estimated; warn below
    :data:`STEPS_PER_SYMBOL` steps per symbol on average, where the symbols' observation models
    and transition counts are poorly estimated.  ``ns`` None: the count is chosen from the data
    (``clusters=bic``), nothing to check."""
    if ns is None:
        return
    n = int((traj.gds < 0).sum()) if traj.gds is not None else len(traj)
    if 2 * ns > n:
        raise ValueError(f"clusters.ns={ns} is more than half of the {n} steps to cluster: most "
                         f"symbols would hold a single step, whose transitions cannot be "
                         f"estimated; give at most clusters.ns={n // 2}, or more steps")
    if ns * STEPS_PER_SYMBOL > n:
        log.warning("clusters.ns=%d leaves %.1f steps per symbol on average (%d steps to "
                    "cluster): below %d, the symbols' observation models and transitions are "
                    "poorly estimated; lower clusters.ns or give more steps", ns, n / ns, n,
                    STEPS_PER_SYMBOL)


def _report_missed_target(learner) -> None:
    """Warn when the split stopped short of the told number of states, saying why."""
    from ..core.split.stopping import TargetStates

    rule = learner.stop
    told = rule.n_states if isinstance(rule, TargetStates) else None
    made = learner.map_split_.n_states
    if told is not None and made < told:
        log.warning("stop.n_states=%d not reached: the split stopped at %d states (%s)", told,
                    made, learner.stop_reason_)


def localize(cfg: dict, parts: Parts, output_dir) -> dict:
    """Apply the saved map ``cfg["map"]`` to the data: the belief over states at every step
    (forward filtering), the Viterbi states and, with ground truth, their scores."""
    m = TopologicalMap.load(cfg["map"])
    with config_keys("data"):
        traj = parts.data.train(parts, int(cfg["seed"]))
    args = (traj.observations, traj.actions)
    kw = {"gds": traj.gds, "lengths": traj.lengths}
    beliefs, viterbi = m.filter(*args, **kw), m.predict(*args, **kw)
    results = {**localization_scores(m, traj, beliefs, viterbi), "config": cfg,
               "versions": versions(), "units": UNITS}
    write_localization(Path(output_dir), traj, beliefs, viterbi, results)
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


@contextmanager
def config_keys(group: str | None = None):
    """Name the parameter of a :class:`~topomap.core.checks.ParameterError` raised inside by its
    config key: ``<group>.<param>`` for a component of ``group``, else the key of a
    :class:`MapLearner` parameter (:func:`~topomap.app.config.learner_key`)."""
    try:
        yield
    except ParameterError as err:
        key = f"{group}.{err.param}" if group else learner_key(err.param)
        raise err.renamed(key) from err.__cause__


def load_data(cfg, parts: Parts, registry: Registry, cache_dir=None, progress=None,
              learner=None):
    """``((trajectory, heldout), timings)`` from the data component; simulated trajectories are
    shared through ``cache_dir`` when one is given (see :class:`TrajectoryCache`).  A walk that
    maps while exploring gets a copy of ``learner`` to ``partial_fit`` (and is not shared: it
    depends on the learner's settings)."""
    seed, data = int(cfg["seed"]), parts.data
    plugins = registry.plugin_names()
    mapping = (learner is not None and data.simulates
               and getattr(data, "maps_while_exploring", lambda _: 0)(parts))
    train = (lambda: data.train(parts, seed, progress, learner=_online_copy(learner))) \
        if mapping else (lambda: data.train(parts, seed, progress))

    def get(kind, build):
        if cache_dir is None or not data.simulates or (mapping and kind == "train"):
            return build()
        key = trajectory_key(cfg, kind, plugins)
        return TrajectoryCache(cache_dir).get(f"{'trajectory' if kind == 'train' else kind}-{key}",
                                              build)

    t0 = time.perf_counter()
    with config_keys("data"):
        traj = get("train", train)
        t1 = time.perf_counter()
        heldout = get("heldout", lambda: data.heldout(parts, seed))
    t2 = time.perf_counter()
    log.info("trajectory: %d steps, %d features, %d actions", len(traj),
             traj.observations.shape[1], traj.n_actions)
    return (traj, heldout), {"data": t1 - t0, "heldout": t2 - t1}


def _online_copy(learner):
    """A copy of the run's learner, with its settings and no callbacks, to map while walking."""
    from sklearn.base import clone

    return clone(learner).set_params(callbacks=())


class Progress:
    """Progress bars on a terminal (tqdm) and the learner's log lines."""

    def __init__(self, enabled: bool):
        self.enabled = bool(enabled)
        self._bars = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for bar in self._bars:
            bar.close()

    def _bar(self, total, desc):
        from tqdm.auto import tqdm

        bar = tqdm(total=total, desc=desc, disable=not self.enabled, leave=False, file=sys.stderr,
                   dynamic_ncols=True)
        self._bars.append(bar)
        return bar

    def ticking(self, explorer, total: int):
        """``explorer``, ticking a "simulating" bar once per chosen action."""
        return _TickingExplorer(explorer, self._bar(total, "simulating"))

    def on_progress(self, stage: str, done: int, total: int | None) -> None:
        """A listener of the core's loops (:mod:`topomap.core.progress`): one bar per running
        loop (BIC, EM, held-out scoring, drawing the figures), closed when the loop ends."""
        bars = self.__dict__.setdefault("_stages", {})
        bar = bars.get(stage)
        if bar is not None and done < bar.n:  # the loop starts again (another EM round)
            bar.close()
            bar = None
        if bar is None:
            bar = bars[stage] = self._bar(total, stage)
        if total is not None and bar.total != total:
            bar.total = total
            bar.refresh()
        bar.update(done - bar.n)
        if total is not None and done >= total:
            bar.close()
            del bars[stage]

    def on_event(self, event, info) -> None:
        """A learner callback: log phase 1, tick a "splitting" bar per split."""
        if event == "phase1":
            n = info["learner"].n_clusters_
            e = info["entropies"]
            log.info("phase 1: %d symbols + %d GDS states, H(o|x)=%.3f bits (differential entropy "
                     "of continuous observations: may be negative), H(u|x)=%.3f, "
                     "H(x'|x,u)=%.3f bits", n, info["map"].n_states - n, e["H_o"], e["H_u"], e["H_x"])
            self.splitting = self._bar(None, "splitting")
        elif event == "split":
            self.splitting.update(1)
            r = info["record"]
            log.debug("split %d: state %d -> %d (gain %.4f)", r["iteration"], r["state"],
                      r["new_state"], r["gain"])
        elif event == "done" and getattr(self, "splitting", None) is not None:
            self.splitting.close()


class _TickingExplorer:
    def __init__(self, explorer, bar):
        self.explorer, self.bar = explorer, bar

    def __getattr__(self, name):  # see / update / update_every of the explorer, when it has them
        return getattr(self.explorer, name)

    def choose(self, executable, rng):
        self.bar.update(1)
        return self.explorer.choose(executable, rng)


def _as_dict(cfg) -> dict:
    from omegaconf import OmegaConf

    if OmegaConf.is_config(cfg):
        return OmegaConf.to_container(cfg, resolve=True, enum_to_str=True)
    return dict(cfg)


# ---------------------------------------------------------------------------------- sweep jobs
def run_job(cfg, output_dir, *, sweep_dir, registry=None, needs_objective=False) -> dict | None:
    """Run one job of a sweep into ``output_dir``; return its results, or None if it failed.

    Trajectories are shared through ``<sweep_dir>/.cache``.  Any exception is logged and written to
    ``output_dir/status.json`` (``{"status": "failed", "error": ..., "traceback": ...}``) rather than
    raised, so the other jobs and the sweep report are not lost.  An interrupt (Ctrl-C, SIGTERM)
    is written as ``{"status": "interrupted"}`` and raised again: it ends the sweep.
    ``status.json`` also holds the job's wall time, process id and host.  A job folder that holds
    another run's outputs is left as it is (the error is logged).
    """
    out = Path(output_dir)
    t0 = time.perf_counter()
    try:
        results = run(cfg, out, registry=registry, cache_dir=Path(sweep_dir) / CACHE_DIR,
                      needs_objective=needs_objective)
    except OutputDirInUse as exc:
        log.error("job not run: %s", exc)
        return None
    except KeyboardInterrupt:
        write_status(out, "interrupted", job_time=time.perf_counter() - t0)
        raise
    except Exception as exc:
        if isinstance(exc, ValueError):
            log.error("job failed: %s", exc)
        else:
            log.exception("job failed: %s", f"{type(exc).__name__}: {exc}")
        write_status(out, "failed", exc, job_time=time.perf_counter() - t0)
        return None
    write_status(out, "completed", job_time=time.perf_counter() - t0)
    return results


def write_status(out, status: str, error: BaseException | None = None, **extra) -> None:
    """Write ``out/status.json``: the ``status`` (``completed``, ``failed``, ``interrupted``),
    the ``error`` (``"<type>: <message>"``) and its traceback, the process id and the host."""
    record = {"status": status, "error": None, **extra}
    if error is not None:
        record["error"] = f"{type(error).__name__}: {error}"
        record["traceback"] = "".join(traceback.format_exception(error))
    _write_status(Path(out), record)


def _write_status(out: Path, status: dict) -> None:
    write_json(out / STATUS_FILE, {**status, "pid": os.getpid(), "host": socket.gethostname()})


def interrupt_on_sigterm() -> None:
    """Make SIGTERM end the process as Ctrl-C does (a :class:`KeyboardInterrupt`), so that a
    killed run or sweep ends as cleanly as an interrupted one."""
    import signal

    def handler(signum, frame):
        raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")

    signal.signal(signal.SIGTERM, handler)
