"""Data components: where a run's trajectories come from.

A data component has ``simulates`` (whether it needs the world, noise and explorer),
``train(parts, seed, progress)`` -> the :class:`~topomap.Trajectory` learned from, and
``heldout(parts, seed)`` -> the one the map is scored on (or None).
"""

from __future__ import annotations

import dataclasses
import inspect
import typing
import warnings
from pathlib import Path
from typing import Any, Optional

import numpy as np

from ...core.checks import ParameterError, check_count
from ...core.data.rosbag import read_rosbag
from ...core.data.rosbag.options import Options
from ...core.data.trajectory import Trajectory, load_trajectory
from ...worlds.explorers import RandomExplorer
from ...worlds.mapping import heldout_judge, map_while_exploring, quality_curve

__all__ = ["Simulate", "FromFile", "FromRosbag", "seed_streams", "DEFAULT_STEPS"]

#: steps of a simulated walk in a world that names no length of its own (``default_steps``):
#: the paper's T (Yairi, Togami & Hori 2002, Section 4)
DEFAULT_STEPS = 2000


def seed_streams(seed: int):
    """Independent generators for the simulation, the sensor noise and the held-out walk."""
    ss = np.random.SeedSequence(int(seed))
    return [np.random.default_rng(s) for s in ss.spawn(3)]


class Simulate:
    """Simulate the configured world for ``n_steps`` steps (``env``, ``noise``, ``explorer``).

    Parameters
    ----------
    n_steps : int or None
        Length of the walk learned from; None (the default): the world's own length
        (``default_steps``: the arena's walks cover its layouts), else :data:`DEFAULT_STEPS`.
    heldout_steps : int or None
        Length of a second, held-out walk through the same world that the map is scored on
        (None: ``n_steps``; 0: none).  It uses the seed's third random stream, so it never
        overlaps the training walk.
    update_every : int
        Map while exploring: every ``update_every`` steps the steps so far go to the run's
        learner (:meth:`topomap.MapLearner.partial_fit`) and the map's ARI against the steps
        taken is recorded (``metrics.json``: ``mapping``; ``fig_mapping.png``).  0 (default):
        only with an explorer that uses the map (``explorer=active``, every
        ``explorer.update_every`` steps).  While mapping, the noise is applied step by step, as
        the explorer sees it.
    curve_every : int, optional
        Deprecated name of ``update_every`` (it warns; removed in 0.4).
    """

    simulates = True

    def __init__(self, n_steps: int | None = None, heldout_steps: int | None = None,
                 update_every: int = 0, curve_every: int | None = None):
        self.told_steps = check_count(n_steps, "n_steps", allow_none=True)
        self.told_heldout = check_count(heldout_steps, "heldout_steps", minimum=0,
                                        allow_none=True)
        if curve_every is not None:
            if update_every:
                raise ParameterError("curve_every", "is the old name of update_every: give "
                                                    "update_every alone")
            warnings.warn("data.curve_every was renamed data.update_every (the explorer's name "
                          "for the same steps); the old name goes in 0.4", FutureWarning,
                          stacklevel=2)
            update_every = curve_every
        self.update_every = check_count(update_every, "update_every", minimum=0)

    def steps(self, env) -> int:
        """Steps of the walk learned from in the world ``env``: ``n_steps``, else the world's
        ``default_steps``, else :data:`DEFAULT_STEPS`."""
        if self.told_steps is not None:
            return self.told_steps
        return int(getattr(env, "default_steps", None) or DEFAULT_STEPS)

    def heldout_steps_in(self, env) -> int:
        """Steps of the held-out walk in ``env``: ``heldout_steps``, else :meth:`steps`."""
        return self.steps(env) if self.told_heldout is None else self.told_heldout

    def maps_while_exploring(self, parts) -> int:
        """Steps between two map updates while walking (0: the map is learned after the walk);
        refused for a world that moves by itself (``moves_itself``: the arena)."""
        every = self.update_every or (int(getattr(parts.explorer, "update_every", 0))
                                      if hasattr(parts.explorer, "update") else 0)
        if every and getattr(parts.env, "moves_itself", False):
            raise ValueError(f"mapping while exploring (data.update_every, explorer=active) "
                             f"needs a world an explorer walks step by step, and {parts.env!r} "
                             "moves by itself: leave them out")
        return every

    def train(self, parts, seed: int, progress=None, learner=None) -> Trajectory:
        rng_sim, rng_noise, _ = seed_streams(seed)
        explorer, n_steps = parts.explorer, self.steps(parts.env)
        if progress is not None and not getattr(parts.env, "moves_itself", False):
            explorer = progress.ticking(parts.explorer, n_steps)
        update_every = self.maps_while_exploring(parts)
        if update_every and learner is not None:
            judge = heldout_judge(self.judging_walk(parts, seed))
            traj, walk = map_while_exploring(parts.env, n_steps, explorer, learner,
                                             parts.noise, rng_sim, rng_noise, update_every, judge)
            walk.flush()
            traj.meta["mapping"] = {"update_every": update_every, "explorer": repr(parts.explorer),
                                    "curve": quality_curve(walk, traj.places)}
            return traj
        traj = parts.env.simulate(n_steps, explorer, rng_sim)
        traj.observations = parts.noise.apply(traj.observations, rng_noise)
        return traj

    def judging_walk(self, parts, seed: int) -> Trajectory:
        """The random walk the maps learned while exploring are judged on (``heldout_ari``):
        ``min(n_steps, 10000)`` steps of :class:`~topomap.worlds.RandomExplorer`, from the seed's
        fourth random stream."""
        rng_sim, rng_noise = np.random.SeedSequence(int(seed)).spawn(4)[3].spawn(2)
        traj = parts.env.simulate(min(self.steps(parts.env), 10000), RandomExplorer(),
                                    np.random.default_rng(rng_sim))
        traj.observations = parts.noise.apply(traj.observations, np.random.default_rng(rng_noise))
        return traj

    def heldout(self, parts, seed: int) -> Trajectory | None:
        """The held-out walk: the world's ``heldout_walk`` where it has one (the arena: another
        random walk, or the end of a recorded path after the ``n_steps`` learned from), else
        another walk of the world; from the seed's third random stream."""
        held = self.heldout_steps_in(parts.env)
        if held == 0:
            return None
        rng_sim, rng_noise = seed_streams(seed)[2].spawn(2)
        walk = getattr(parts.env, "heldout_walk", None)
        try:
            traj = (parts.env.simulate(held, parts.explorer, rng_sim) if walk is None
                    else walk(held, parts.explorer, rng_sim, after=self.steps(parts.env)))
        except ParameterError as err:  # the walk's n_steps is this heldout_steps
            raise (err.renamed("heldout_steps") if err.param == "n_steps" else err) from None
        traj.observations = parts.noise.apply(traj.observations, rng_noise)
        return traj


class FromFile:
    """Learn from a recorded trajectory (``.npz``, ``.csv`` or ``.csv.gz``); no simulation.

    Parameters
    ----------
    path : str
        The recording (see the trajectory file formats in ``docs/file-formats.md``), or a
        folder of recordings: every log in it in name order, each an episode (``lengths``),
        read into memory (a run writes every step's state; ``MapLearner.fit_stream`` fits
        logs larger than memory, ``docs/large-logs.md``).
    heldout_path : str or None
        A second recording (or folder) of the same world that the map is scored on.
    """

    simulates = False

    def __init__(self, path: str, heldout_path: str | None = None):
        self.path = path
        self.heldout_path = None if heldout_path in (None, "") else heldout_path

    def train(self, parts, seed: int, progress=None) -> Trajectory:
        return _recording(self.path)

    def heldout(self, parts, seed: int) -> Trajectory | None:
        return None if self.heldout_path is None else _recording(self.heldout_path)


def _recording(path) -> Trajectory:
    """One recording, or every log of a folder as the episodes of one trajectory."""
    if Path(path).is_dir():
        from ...core.stream.plan import read_logs

        return read_logs(path)
    return load_trajectory(path)


def _bag_options() -> list[inspect.Parameter]:
    """The options of ``data=rosbag``, declared once, by :func:`topomap.read_rosbag`: the fields
    of its checked options (:class:`~topomap.core.data.rosbag.options.Options`, with their types)
    with its defaults, but ``action_rule``, a callable that no config can hold."""
    hints = typing.get_type_hints(Options)
    defaults = inspect.signature(read_rosbag).parameters
    return [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY,
                              annotation=_names_if_list(hints[f.name]),
                              default=defaults[f.name].default)
            for f in dataclasses.fields(Options) if f.name != "action_rule"]


def _names_if_list(hint):
    """An option's type in the config: the lists of :func:`read_rosbag`'s options hold names
    (field paths, action names, GDS names), so a list or tuple is a list of str."""
    args = set(typing.get_args(hint))
    if hint in (list, tuple) or (args and args - {type(None)} <= {list, tuple}):
        return Optional[list[str]] if type(None) in args else list[str]
    return hint


class FromRosbag:
    """Learn from ROS bags (``pip install "topomap[ros]"``): one step per message on the action
    topic, the observation the latest message at or before it on the observation topic.

    Every parameter but ``path`` and ``heldout_path`` is an argument of
    :func:`topomap.read_rosbag` (which documents the rules, and declares them: this class's
    signature is derived from it); ``path`` is one bag (a ROS 1 ``.bag`` file, a ROS 2 bag
    folder) or a list of bags, one episode each.  ``heldout_path`` (one bag or a list) is a
    second recording of the same world the map is scored on.
    """

    simulates = False
    __signature__ = inspect.Signature([
        inspect.Parameter("path", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=Any),
        *_bag_options(),
        inspect.Parameter("heldout_path", inspect.Parameter.KEYWORD_ONLY, annotation=Any,
                          default=None)])

    def __init__(self, path: Any, **options):
        bound = self.__signature__.bind(path, **options)  # a TypeError naming what is wrong
        self.path, self.heldout_path = path, options.pop("heldout_path", None)
        self.options = {k: v for k, v in bound.arguments.items() if k in options}

    def train(self, parts, seed: int, progress=None) -> Trajectory:
        return read_rosbag(self.path, **self.options)

    def heldout(self, parts, seed: int) -> Trajectory | None:
        if self.heldout_path in (None, "", []):
            return None
        try:
            return read_rosbag(self.heldout_path, **self.options)
        except ParameterError as err:  # read_rosbag's path is this heldout_path
            raise (err.renamed("heldout_path") if err.param == "path" else err) from None
