"""A run's data: the trajectory learned from and the held-out one, from the run's data component,
shared between the jobs of a sweep through a folder of simulated trajectories.

:func:`load_data` asks the data component (:mod:`topomap.app.components.data`) for both;
a simulated trajectory is stored under a hash of every setting that determines it
(:func:`trajectory_key`) in :class:`TrajectoryCache`, so the jobs of a sweep that differ only in
their learner settings simulate it once.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from pathlib import Path

from ...core.data.trajectory import Trajectory, load_trajectory, save_trajectory
from ..compose.kinds import parts_of
from ..compose.registry import Parts, Registry
from ..compose.schemas import config_keys

log = logging.getLogger("topomap")

__all__ = ["load_data", "trajectory_key", "TrajectoryCache"]


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
        if mapping and "mapping" in (traj.meta or {}):  # the explorer as the run chose it
            traj.meta["mapping"]["component"] = f"explorer={cfg['explorer']['component']}"
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


def trajectory_key(cfg, kind: str = "train", plugins=()) -> str:
    """A hash of every setting that determines a simulated trajectory.

    ``kind`` is ``"train"`` (the trajectory learned from) or ``"heldout"`` (the one scored);
    ``plugins`` the loaded plugins (a plugin may add actions to the world).  Two configs with the
    same key simulate the same trajectory, whatever their learner settings.
    """
    data = dict(cfg["data"])
    if kind == "train":
        data.pop("heldout_steps", None)
    elif kind == "heldout":
        hold = data.get("heldout_steps")
        data["heldout_steps"] = data.get("n_steps") if hold is None else hold
    else:
        raise ValueError(f"kind must be 'train' or 'heldout', not {kind!r}")
    payload = {"kind": kind, "data": data, "seed": cfg["seed"],
               "plugins": sorted({str(p) for p in cfg.get("plugins") or ()} | set(plugins)),
               **{k: dict(cfg[k]) for k in ("env", "noise", "explorer")},
               **{k: dict(cfg[k]) for k in parts_of("env") if cfg.get(k) is not None}}
    text = json.dumps(payload, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class TrajectoryCache:
    """A folder of simulated trajectories shared by the jobs of a sweep.

    :meth:`get` loads ``<folder>/<name>.npz`` or builds and stores it (a build that returns None,
    "no trajectory", is not stored), holding a lock file
    (``filelock.SoftFileLock``, which works on a cluster's shared file system) so that parallel
    jobs build each trajectory once; the file itself is written atomically.
    """

    def __init__(self, folder, timeout: float = 3600.0):
        self.folder = Path(folder)
        self.timeout = float(timeout)

    def get(self, name: str, build) -> Trajectory | None:
        from filelock import SoftFileLock, Timeout

        path = self.folder / f"{name}.npz"
        self.folder.mkdir(parents=True, exist_ok=True)
        try:
            with SoftFileLock(str(path.with_suffix(".lock")), timeout=self.timeout):
                if path.is_file():
                    log.info("trajectory %s: reused from %s", name, path)
                    return load_trajectory(path)
                traj = build()
                if traj is not None:
                    save_trajectory(traj, path)
                return traj
        except Timeout:
            raise ValueError(f"waited {self.timeout:.0f} s for {path} (lock "
                             f"{path.with_suffix('.lock')}); if no job is building it, delete "
                             "the lock file") from None
