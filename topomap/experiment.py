"""One experiment from a config: get a trajectory, learn the map, evaluate it, write the outputs.

:func:`run` is plain Python (a config mapping in, a results dict out); the Hydra app
(:mod:`topomap.app`) is a thin layer that composes the config and calls it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sys
import time
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from . import metrics as M
from .learner import MapLearner
from .registry import Registry
from .trajectory import Trajectory, _atomic_write, load_trajectory, save_trajectory

log = logging.getLogger("topomap")

__all__ = ["run", "make_trajectory", "make_heldout", "trajectory_key", "build_learner",
           "write_outputs", "OUTPUT_FILES"]

#: files every run writes, with what they hold (figures only with ``output.figures``)
OUTPUT_FILES = {
    "trajectory.npz": "the observations and actions learned from (plus GDS, ground truth)",
    "map.json": "the learned map (states, observation models, counts, split history)",
    "map.graphml": "the map as a graph: arcs where P(x'|x,u) > output.min_prob",
    "states.csv": "step, state after phase 1, final state (and ground-truth place)",
    "metrics.json": "entropies, ARI/NMI/purity/compound states, splits, timings, versions, config",
}
FIGURE_FILES = {
    "fig_states.png": "observation points coloured by state (the paper's Fig. 4, right)",
    "fig_split.png": "a compound state before and after its split, with transition tables (Figs. 5-6)",
    "fig_map.png": "the learned map at the states' mean positions, arcs where P > min_prob (Fig. 7)",
    "fig_entropy.png": "H(u|x), H(x'|x,u) and their sum after each split",
}


def _container(cfg) -> dict:
    try:
        from omegaconf import OmegaConf

        if OmegaConf.is_config(cfg):
            return OmegaConf.to_container(cfg, resolve=True)
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        pass
    return dict(cfg)


def _seeds(seed: int):
    """Independent generators for the simulation, the sensor noise and held-out data."""
    ss = np.random.SeedSequence(int(seed))
    return [np.random.default_rng(s) for s in ss.spawn(3)]


class _ProgressExplorer:
    """Wraps an explorer to tick a progress bar once per simulated step."""

    def __init__(self, explorer, bar):
        self.explorer, self.bar = explorer, bar

    def choose(self, executable, rng):
        self.bar.update(1)
        return self.explorer.choose(executable, rng)


def _bar(total, desc, enabled):
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False, file=sys.stderr,
                dynamic_ncols=True)


def _make_world(cfg, registry: Registry):
    env = dict(cfg["env"])
    extra = []
    for actions in registry.pm.hook.topomap_world_actions(world=env["component"], params=dict(env)):
        extra.extend(actions or [])
    kwargs = {"extra_actions": extra} if extra else {}
    return registry.make("env", env, **kwargs)


def trajectory_key(cfg, kind: str = "train") -> str:
    """A hash of every setting that determines the simulated trajectory.

    ``kind`` is ``"train"`` (the trajectory learned from) or ``"heldout"`` (the one scored).  Two
    configs with the same key simulate the same trajectory, whatever their learner settings.
    """
    data = dict(cfg["data"])
    if kind == "train":
        data.pop("heldout_steps", None)
    elif kind == "heldout":
        data["heldout_steps"] = _heldout_steps(data)
    else:
        raise ValueError(f"kind must be 'train' or 'heldout', not {kind!r}")
    payload = {"kind": kind, "data": data, "seed": cfg["seed"],
               "plugins": [str(p) for p in cfg.get("plugins") or ()],
               **{k: dict(cfg[k]) for k in ("env", "noise", "explorer")}}
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@contextmanager
def _file_lock(path: Path):
    """Hold an exclusive lock on ``path`` (where the OS supports it) so that parallel jobs of one
    sweep build a cached file once; the cached file itself is always written atomically."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not on POSIX: each job may build it, still atomic
        yield
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _cached(cache_dir, name: str, build):
    """``build()`` a trajectory, or load it from ``cache_dir/name.npz`` if a job built it already."""
    if cache_dir is None:
        return build()
    path = Path(cache_dir) / f"{name}.npz"
    with _file_lock(path.with_suffix(".lock")):
        if path.is_file():
            log.info("trajectory %s: reused from %s", name, path)
            return load_trajectory(path)
        traj = build()
        save_trajectory(traj, path)
        return traj


def make_trajectory(cfg, registry: Registry, *, progress: bool = False, cache_dir=None):
    """Simulate (``data.name == "simulate"``) or load (``"file"``) the trajectory.

    Returns ``(trajectory, world)``; ``world`` is None for recorded data.  With ``cache_dir`` (the
    jobs of a sweep share one), a simulated trajectory is stored there under
    :func:`trajectory_key` and every later config with the same key loads it instead of simulating.
    """
    data = dict(cfg["data"])
    if data["component"] == "file":
        return load_trajectory(data["path"]), None
    if data["component"] != "simulate":
        raise ValueError(f"data={data['component']!r} is unknown; choose simulate or file")
    world = _make_world(cfg, registry)
    explorer = registry.make("explorer", cfg["explorer"])
    noise = registry.make("noise", cfg["noise"])

    def build():
        rng_sim, rng_noise, _ = _seeds(cfg["seed"])
        n_steps = data["n_steps"]
        with _bar(n_steps, "simulating", progress) as bar:
            traj = world.simulate(n_steps, _ProgressExplorer(explorer, bar), rng_sim)
        traj.observations = noise.apply(traj.observations, rng_noise)
        return traj

    return _cached(cache_dir, f"trajectory-{trajectory_key(cfg, 'train')}", build), world


def _heldout_steps(data: dict) -> int:
    n = data.get("heldout_steps")
    n = data.get("n_steps") if n is None else n
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        raise ValueError(f"data.heldout_steps must be a non-negative integer or null, got {n!r}")
    return n


def make_heldout(cfg, registry: Registry, *, cache_dir=None) -> Trajectory | None:
    """The held-out trajectory the learned map is scored on, or None.

    ``data=simulate``: a second walk through the same world (``data.heldout_steps`` steps, default
    ``data.n_steps``; 0 for none) with the seed's third random stream, so it never overlaps the
    training walk.  ``data=file``: the recording at ``data.heldout_path``, if one is given.
    """
    data = dict(cfg["data"])
    if data["component"] == "file":
        path = data.get("heldout_path")
        return None if path in (None, "") else load_trajectory(path)
    n_steps = _heldout_steps(data)
    if n_steps == 0:
        return None
    world = _make_world(cfg, registry)
    explorer = registry.make("explorer", cfg["explorer"])
    noise = registry.make("noise", cfg["noise"])

    def build():
        rng_sim, rng_noise = _seeds(cfg["seed"])[2].spawn(2)
        traj = world.simulate(n_steps, explorer, rng_sim)
        traj.observations = noise.apply(traj.observations, rng_noise)
        return traj

    return _cached(cache_dir, f"heldout-{trajectory_key(cfg, 'heldout')}", build)


def build_learner(cfg, registry: Registry, callbacks=()) -> MapLearner:
    """A :class:`MapLearner` with the configured components."""
    lcfg = dict(cfg["learner"])
    return MapLearner(
        clusters=registry.make("clusters", cfg["clusters"]),
        metric=registry.make("metric", cfg["metric"]),
        criterion=registry.make("split", cfg["split"]),
        stopping=registry.make("stop", cfg["stop"]),
        covariance_type=lcfg["covariance_type"], reg_covar=lcfg["reg_covar"],
        n_init=lcfg["n_init"], random_state=int(cfg["seed"]), callbacks=callbacks,
    )


def _versions() -> dict:
    out = {"python": sys.version.split()[0]}
    for pkg in ("topomap", "numpy", "scikit-learn", "networkx", "hydra-core", "omegaconf",
                "pluggy", "matplotlib"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def _evaluate(learner: MapLearner, traj: Trajectory) -> dict:
    out = {
        "n_states": {"phase1": learner.map_phase1_.n_states, "final": learner.map_.n_states},
        "entropies": {"phase1": learner.entropies_[0], "final": learner.entropies_[-1]},
    }
    if traj.places is not None:
        out["ground_truth"] = {
            "phase1": M.evaluate(learner.labels_phase1_, traj.places),
            "final": M.evaluate(learner.labels_, traj.places),
        }
    return out


def run(cfg, output_dir, *, registry: Registry | None = None, cache_dir=None) -> dict:
    """Run one experiment described by ``cfg`` and write its outputs into ``output_dir``.

    Everything that can be wrong with the input (config values, data files) is checked before the
    first output file is written; every file is written atomically.  Returns the metrics dict.
    ``cache_dir``: where simulated trajectories are shared between runs (the jobs of a sweep).
    """
    out = Path(output_dir)
    container = _container(cfg)
    progress = bool(container["output"].get("progress", True)) and sys.stderr.isatty()
    registry = registry or Registry.load(container.get("plugins") or ())
    for err in registry.errors:
        log.warning("%s", err)

    plugin_metrics: dict = {}
    bar = _bar(None, "splitting", progress)

    def on_event(event, info):
        if event == "phase1":
            log.info("phase 1: %d symbols + %d GDS states, H(o|x)=%.3f H(u|x)=%.3f H(x'|x,u)=%.3f",
                     info["learner"].n_clusters_, info["map"].n_states - info["learner"].n_clusters_,
                     info["entropies"]["H_o"], info["entropies"]["H_u"], info["entropies"]["H_x"])
        elif event == "split":
            bar.update(1)
            r = info["record"]
            log.debug("split %d: state %d -> %d (gain %.4f)", r["iteration"], r["state"],
                      r["new_state"], r["gain"])
        registry.pm.hook.topomap_learner_event(event=event, info=dict(info, metrics=plugin_metrics))

    # build every component first, so a bad setting fails before a long simulation
    learner = build_learner(container, registry, callbacks=[on_event])
    t0 = time.perf_counter()
    traj, world = make_trajectory(container, registry, progress=progress, cache_dir=cache_dir)
    t_data = time.perf_counter() - t0
    t0 = time.perf_counter()
    heldout = make_heldout(container, registry, cache_dir=cache_dir)
    t_heldout = time.perf_counter() - t0
    log.info("trajectory: %d steps, %d features, %d actions", len(traj),
             traj.observations.shape[1], traj.n_actions)
    log.info("clustering and splitting ...")
    with bar:
        learner.fit_trajectory(traj)
    results = _evaluate(learner, traj)
    t0 = time.perf_counter()
    results.update(_score_heldout(learner, heldout))
    t_heldout += time.perf_counter() - t0
    results.update({
        "split_history": learner.split_history_,
        "entropy_trace": learner.entropies_,
        "stop_reason": learner.stop_reason_,
        "timings": {"data": t_data, **learner.timings_, "heldout": t_heldout},
        "versions": _versions(),
        "config": container,
        "providers": {k: registry.provider(k, container[k]["component"])
                      for k in ("clusters", "metric", "split", "stop")},
        "plugin_metrics": plugin_metrics,
    })
    write_outputs(out, traj, learner, results, container, world)
    return results


def _score_heldout(learner: MapLearner, heldout: Trajectory | None) -> dict:
    """Mean log-likelihood per step of the held-out trajectory under the learned map (None if
    there is none)."""
    if heldout is None:
        return {"heldout_loglik": None, "heldout_steps": 0}
    score = learner.map_.score(heldout.observations, heldout.actions, gds=heldout.gds,
                               lengths=heldout.lengths)
    return {"heldout_loglik": score, "heldout_steps": len(heldout)}


def write_outputs(out: Path, traj, learner, results, cfg, world=None) -> None:
    """Write every output file of a run into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    save_trajectory(traj, out / "trajectory.npz")
    m = learner.map_
    m.save(out / "map.json")
    m.to_graphml(out / "map.graphml", min_prob=cfg["output"]["min_prob"])
    cols = [np.arange(len(traj)), learner.labels_phase1_, learner.labels_]
    header = "step,state_phase1,state"
    if traj.places is not None:
        cols.append(traj.places)
        header += ",place"
    table = np.column_stack(cols)
    _atomic_write(out / "states.csv",
                  lambda tmp: np.savetxt(tmp, table, fmt="%d", delimiter=",", header=header,
                                         comments=""))
    if cfg["output"]["figures"]:
        from . import plots

        plots.write_figures(out, traj, learner, world, min_prob=cfg["output"]["min_prob"],
                            compound_state=cfg["output"].get("compound_state"))
    results["timings"]["outputs"] = time.perf_counter() - t0
    text = json.dumps(results, indent=1, sort_keys=True, default=_json_default)
    _atomic_write(out / "metrics.json", lambda tmp: Path(tmp).write_text(text + "\n"))


def _json_default(obj):
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")
