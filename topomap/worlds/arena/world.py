"""The arena world: continuous motion in a floor plan, sensed and turned into actions.

:class:`ArenaWorld` ties the pieces together: a layout (:mod:`.layouts`, :mod:`.floorplan`) made
into a ratinabox ``Environment``; motion that is ratinabox's random ``Agent``
(:func:`.motion.random_motion`) or a recorded path (:mod:`.paths`), sampled every ``dt``
seconds; a sensor (:mod:`.sensors`) that reads all positions at once; an action rule
(:mod:`.actions`) that reads the moves.  ``simulate(n_steps, explorer, rng)`` returns a
:class:`~topomap.Trajectory` with noise-free observations, the actions and the true
``positions``; no ``places``: the arena has no discrete places, its scores are in metres
(:mod:`topomap.evaluation.metres`, with :meth:`ArenaWorld.region_of` for the wrong-region
share).  ``heldout_walk`` gives the walk such scores are taken on: another random walk, or the
end of a recorded path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.checks import ParameterError, check_count
from ...core.data.trajectory import Trajectory
from ..checks import check_no_extra_actions
from ..explorers import RandomExplorer
from .actions import make_action_rule
from .checks import non_negative, positive, require_ratinabox
from .floorplan import FLOORPLAN_SUFFIXES, load_floorplan
from .layouts import LAYOUTS, Layout, builtin_layout
from .kinematics import MOTION_PARAMETERS, Motion, random_motion
from .odometry import ODOMETRY_STREAM, WheelOdometry
from .paths import RecordedPath
from .plot import plot_layout
from .sensors import make_sensor

__all__ = ["ArenaWorld", "Arena", "make_layout", "WALK_STEPS"]

#: steps of the arena's default walk (``data.n_steps`` left out): 30 minutes at 10 Hz, by which
#: ratinabox's random motion had entered every region of ``open``, ``two_rooms`` and
#: ``four_rooms`` on each of three seeds (by step 787, 1,733 and 10,789 at the latest; 2,000
#: steps left whole rooms of ``four_rooms`` unvisited on all three), and of ``corridor`` on two
#: (16,703; one seed missed a room in 40 minutes): ``benchmarks/notes/arena-walks.md``
WALK_STEPS = 18000


@dataclass(frozen=True, eq=False)
class Arena:
    """A layout and the ratinabox ``Environment`` built from it (objects added with their types,
    renumbered ``0, 1, ...`` in increasing order)."""

    layout: Layout
    environment: object

    @classmethod
    def build(cls, layout: Layout) -> "Arena":
        from ratinabox.Environment import Environment

        env = Environment(params=layout.environment_params())
        _, types = np.unique(layout.object_types, return_inverse=True)
        for point, kind in zip(layout.objects, types):
            env.add_object(point.tolist(), type=int(kind))
        return cls(layout, env)


def _floorplan(path, param: str) -> Layout:
    """The floor plan in the file ``path``; its problems are errors naming ``param``."""
    try:
        return load_floorplan(path)
    except ValueError as exc:
        detail = str(exc).removeprefix(f"floor plan {Path(path)}: ")
        raise ParameterError(param, f"={path}: {detail}") from None


def make_layout(layout, recording: RecordedPath | None, floorplan: str | None = None) -> Layout:
    """The :class:`Layout` meant by ``layout``: a Layout, a built-in name, a floor-plan file, or
    ``"auto"`` (a shipped recording's box, else ``two_rooms``); or the floor-plan file
    ``floorplan`` (then ``layout`` must be ``"auto"``)."""
    if floorplan not in (None, ""):
        if layout != "auto":
            raise ParameterError("floorplan", f"={floorplan} and layout={layout!r} both name the "
                                              "floor plan: give one of them")
        return _floorplan(floorplan, "floorplan")
    if isinstance(layout, Layout):
        return layout
    if not isinstance(layout, str):
        raise ParameterError("layout", f"must be a layout name, a floor-plan file or a Layout, "
                                       f"got {layout!r}")
    if layout == "auto":
        if recording is None:
            return builtin_layout("two_rooms")
        if recording.layout() is None:
            raise ParameterError("layout", f"is needed for the recorded path {recording.source}: "
                                           "give a built-in layout or a floor-plan file")
        return recording.layout()
    if Path(layout).suffix.lower() in FLOORPLAN_SUFFIXES:
        return _floorplan(layout, "layout")
    if layout not in LAYOUTS:
        raise ParameterError("layout", f"={layout!r} is neither a built-in layout "
                                       f"({', '.join(LAYOUTS)}) nor a floor-plan file (.yaml, "
                                       ".yml or .json)")
    return builtin_layout(layout)


#: the odometry components by name (a world given a name builds it with its defaults)
ODOMETRIES = {"none": None, "wheel": WheelOdometry}


def make_odometry(odometry):
    """None for no odometry (None or ``"none"``), the odometry named ``odometry`` with its
    defaults, or ``odometry`` itself if it has a ``dead_reckoning`` method."""
    if odometry is None or isinstance(odometry, str):
        if odometry is not None and odometry not in ODOMETRIES:
            raise ParameterError("odometry", f"must be one of {', '.join(ODOMETRIES)} or an "
                                             f"odometry object, got {odometry!r}")
        factory = ODOMETRIES.get(odometry)
        return None if factory is None else factory()
    if not callable(getattr(odometry, "dead_reckoning", None)):
        raise ParameterError("odometry", "must have a dead_reckoning(motion, rng) method, got "
                                         f"{odometry!r}")
    return odometry


def _arena_of(layout, recording, floorplan) -> Arena:
    """The arena of the layout ``layout`` (see :func:`make_layout`), or of a ratinabox
    ``Environment``, which it keeps."""
    from ratinabox.Environment import Environment

    if isinstance(layout, Environment):
        if floorplan not in (None, ""):
            raise ParameterError("floorplan", f"={floorplan} and a ratinabox Environment both "
                                              "name the floor plan: give one of them")
        return Arena(Layout.from_environment(layout), layout)
    return Arena.build(make_layout(layout, recording, floorplan))


def _check_explorer(explorer) -> None:
    if explorer is not None and type(explorer) is not RandomExplorer:
        raise ValueError(f"explorer {explorer!r} cannot steer the arena: its motion is "
                         "ratinabox's random motion or a recorded path (the random explorer is "
                         "accepted and not consulted)")


class ArenaWorld:
    """Continuous motion in a floor plan, sensed every ``dt`` seconds (see the module docstring).

    Parameters
    ----------
    layout : str, Layout or ratinabox Environment
        A built-in layout (``open``, ``two_rooms``, ``four_rooms``, ``corridor``,
        ``alike_rooms``), a floor-plan file (``.yaml``, ``.yml``, ``.json``), a
        :class:`Layout`, ``"auto"``: the box of a shipped recording, else ``two_rooms``; or a
        ratinabox ``Environment`` (2-D, solid), walked as it is (its floor plan
        :meth:`Layout.from_environment`, without regions).  A ratinabox ``Agent``'s world is
        :meth:`from_agent`.
    floorplan : str or None
        A floor-plan file (``.yaml``, ``.yml``, ``.json``; :func:`.floorplan.load_floorplan`),
        the layout instead of ``layout`` (which must then be ``"auto"``).
    path : str or None
        None: ratinabox's random motion.  ``"sargolini"``, ``"tanni"`` or a ``.npz`` / ``.csv``
        file: that recorded path (:mod:`topomap.worlds.arena.paths`), the same for every rng.
    dt : float
        Seconds between two steps (the sensor's rate: 0.1 s is 10 Hz).
    start : float
        Seconds into a recorded path at which ``simulate`` starts.
    sensor : str or sensor object
        ``"range"``, ``"bvc"``, ``"ovc"`` (each with its defaults) or a sensor such as
        ``RangeFinder(n_beams=12, max_range=3.0)``; ``"range"``'s beams reach across the
        layout (``max_range=None``).
    actions : str or action rule
        ``"compass"``, ``"turns"`` (with their defaults) or a rule such as
        ``TurnActions(angular_threshold=1.0)``.
    speed_mean, speed_coherence_time, rotational_velocity_std, \
rotational_velocity_coherence_time, thigmotaxis, wall_repel_distance, wall_repel_strength : float
        ratinabox's random-motion parameters (m/s, s, rad/s, s, in [0, 1], m, -), with its
        defaults, fitted to rats (keyword only, as the parameters after them).
    odometry : str, odometry object or None
        The robot's own dead reckoning, kept as the walks' ``odometry``: None or ``"none"``
        (the default: none), ``"wheel"`` (:class:`~.odometry.WheelOdometry` with its
        defaults) or an object such as ``WheelOdometry(gyro_bias=0.02)``.  Its errors are drawn
        from the walk's seed (a recorded path: from its first step).
    path_tolerance : float
        Metres a recorded position may lie off the floor (tracking noise); it is moved 1 mm
        inside.  Farther off is an error.
    extra_actions : list, optional
        Not supported: the action rule fixes the actions.
    """

    def __init__(self, layout: str | Layout = "auto", floorplan: str | None = None,
                 path: str | None = None, dt: float = 0.1,
                 start: float = 0.0, sensor: str | object = "range",
                 actions: str | object = "compass", odometry: str | object | None = None, *,
                 speed_mean: float = 0.08,
                 speed_coherence_time: float = 0.7, rotational_velocity_std: float = math.radians(120),
                 rotational_velocity_coherence_time: float = 0.08, thigmotaxis: float = 0.5,
                 wall_repel_distance: float = 0.1, wall_repel_strength: float = 1.0,
                 path_tolerance: float = 0.05, extra_actions=None):
        require_ratinabox()
        check_no_extra_actions("arena", extra_actions)
        self.dt = positive("dt", dt)
        self.start = non_negative("start", start)
        self.path_tolerance = non_negative("path_tolerance", path_tolerance)
        self.recording = None if path in (None, "") else RecordedPath(path)
        self.sensor = make_sensor(sensor)
        self.action_rule = make_action_rule(actions)
        self.odometry = make_odometry(odometry)
        values = (speed_mean, speed_coherence_time, rotational_velocity_std,
                  rotational_velocity_coherence_time, thigmotaxis, wall_repel_distance,
                  wall_repel_strength)
        self.motion_params = {name: non_negative(name, v)
                              for name, v in zip(MOTION_PARAMETERS, values)}
        if self.motion_params["thigmotaxis"] > 1:
            raise ParameterError("thigmotaxis", f"must be in [0, 1], got {thigmotaxis!r}")
        self.arena = _arena_of(layout, self.recording, floorplan)

    @classmethod
    def from_agent(cls, agent, **kwargs) -> "ArenaWorld":
        """The world a ratinabox ``Agent`` walks in, walking as it does: its ``Environment``
        (the layout), its ``dt`` and its random-motion parameters (``speed_mean``, ...); a new
        agent with them walks each walk, so the walks are reproducible.  ``kwargs``: the world's
        other arguments (``sensor``, ``actions``, ``odometry``, ``path``, ...)."""
        motion = {name: float(getattr(agent, name)) for name in MOTION_PARAMETERS}
        clash = sorted(set(kwargs) & {*motion, "dt", "layout", "floorplan"})
        if clash:
            raise ParameterError(clash[0], "is the agent's own: from_agent takes it from the "
                                           "agent (give a new agent, or ArenaWorld(...))")
        return cls(layout=agent.Environment, dt=float(agent.dt), **motion, **kwargs)

    # ------------------------------------------------------------------ what the world offers
    #: the world moves by itself (ratinabox's motion or a recording): no explorer steers it
    moves_itself = True

    @property
    def layout(self) -> Layout:
        return self.arena.layout

    @property
    def action_names(self) -> list[str]:
        return list(self.action_rule.action_names)

    @property
    def n_actions(self) -> int:
        return len(self.action_names)

    @property
    def n_features(self) -> int | None:
        """Observations per step, as the sensor says without sensing (None if it does not)."""
        count = getattr(self.sensor, "n_features", None)
        return None if count is None else int(count(self.arena))

    @property
    def region_names(self) -> list[str]:
        return self.layout.region_names

    def region_of(self, positions) -> np.ndarray:
        """The layout's region of each position (``(T,)`` ids into :attr:`region_names`)."""
        return self.layout.region_of(positions)

    @property
    def default_steps(self) -> int:
        """Steps of a walk when the run names none (``data.n_steps`` left out):
        :data:`WALK_STEPS` of random motion, or half of a recorded path (at most as many), so
        that a held-out walk of as many steps fits after it."""
        if self.recording is None:
            return WALK_STEPS
        return max(1, min(WALK_STEPS, self.recording.n_steps(self.start, self.dt) // 2))

    @property
    def path_steps(self) -> int | None:
        """Steps of ``dt`` a recorded path holds after ``start`` (None for random motion)."""
        return None if self.recording is None else self.recording.n_steps(self.start, self.dt)

    # ------------------------------------------------------------------ walking
    def simulate(self, n_steps: int, explorer, rng: np.random.Generator) -> Trajectory:
        """``n_steps`` steps: random motion seeded from ``rng`` (one draw), or the recorded path
        from ``start`` (``rng`` unused).  ``explorer`` must be None or the random explorer: it is
        not consulted."""
        n_steps = check_count(n_steps, "n_steps")
        _check_explorer(explorer)
        if self.recording is not None:
            return self.walk_from(round(self.start / self.dt), n_steps)
        seed = int(rng.integers(2**32))
        samples = random_motion(self.arena.environment, n_steps, self.dt, self.motion_params, seed)
        return self._trajectory(Motion.from_samples(samples, self.dt), {"seed": seed}, seed)

    def walk_from(self, first_step: int, n_steps: int) -> Trajectory:
        """Steps ``first_step`` to ``first_step + n_steps - 1`` of the recorded path (steps of
        ``dt`` from its first sample): a held-out walk is a part the learner did not see."""
        if self.recording is None:
            raise ValueError("walk_from needs a recorded path (path=...); random motion is "
                             "drawn by simulate")
        first = check_count(first_step, "first_step", minimum=0)
        n_steps = check_count(n_steps, "n_steps")
        held = self.recording.n_steps(0.0, self.dt)
        if first + n_steps > held:
            raise ParameterError("n_steps", f"={n_steps} from step {first} exceeds the {held} "
                                 f"steps of {self.dt:g} s the path {self.recording.source} holds")
        samples = self.recording.resample(first * self.dt, self.dt, n_steps + 1)
        samples, moved = self._onto_floor(samples, first)
        motion = Motion.from_samples(samples, self.dt, t0=first * self.dt)
        return self._trajectory(motion, {"first_step": first, "moved_onto_floor": moved}, first)

    def heldout_walk(self, n_steps: int, explorer, rng: np.random.Generator,
                     after: int = 0) -> Trajectory:
        """A walk to score a map learned from ``simulate(after, ...)`` on: for random motion
        another walk, seeded from ``rng``; for a recorded path its LAST ``n_steps`` steps, which
        may not overlap the ``after`` steps from ``start`` that ``simulate`` gives (a
        :class:`ParameterError` naming ``n_steps`` says how many are left).  Its ``meta``
        says which walk it is (``heldout``)."""
        if self.recording is None:
            traj = self.simulate(n_steps, explorer, rng)
            traj.meta["heldout"] = f"another random walk (seed {traj.meta['seed']})"
            return traj
        n_steps = check_count(n_steps, "n_steps")
        _check_explorer(explorer)
        held = self.recording.n_steps(0.0, self.dt)
        learned = round(self.start / self.dt) + check_count(after, "after", minimum=0)
        if n_steps > held - learned:
            raise ParameterError("n_steps", f"={n_steps} steps from the end of the path "
                                 f"{self.recording.source} overlap the {learned} steps learned "
                                 f"from: it holds {held} steps of {self.dt:g} s, so at most "
                                 f"{max(held - learned, 0)} are left")
        traj = self.walk_from(held - n_steps, n_steps)
        traj.meta["heldout"] = (f"the last {n_steps} steps of the path {self.recording.source} "
                                f"(steps {held - n_steps} to {held - 1} of {self.dt:g} s)")
        return traj

    def _onto_floor(self, samples: np.ndarray, first: int) -> tuple[np.ndarray, int]:
        P, moved, worst = self.layout.move_inside(samples, self.path_tolerance)
        if worst is not None and worst[1] > self.path_tolerance:
            t = (first + worst[0]) * self.dt
            raise ValueError(f"path {self.recording.source}: the position at {t:.2f} s lies "
                             f"{worst[1]:.3f} m off the floor of layout {self.layout.name!r}, "
                             f"more than path_tolerance={self.path_tolerance:g} m")
        return P, int(moved.sum())

    def _trajectory(self, motion: Motion, meta: dict, key: int) -> Trajectory:
        try:  # a problem of the sensor's or the rule's parameters, named as the world's parts
            X = self.sensor.sense(self.arena, motion)
        except ParameterError as err:
            raise err.renamed(f"sensor.{err.param}") from None
        try:
            u = np.asarray(self.action_rule.actions(motion), dtype=np.int64)
        except ParameterError as err:
            raise err.renamed(f"actions.{err.param}") from None
        meta = {"world": "arena", "layout": self.layout.name, "dt": self.dt,
                "path": None if self.recording is None else self.recording.source,
                "sensor": repr(self.sensor), "actions": repr(self.action_rule), **meta}
        odometry = None
        if self.odometry is not None:  # its own stream of the walk's seed: the same path
            rng = np.random.default_rng([int(key), ODOMETRY_STREAM])
            odometry = self.odometry.dead_reckoning(motion, rng)
            meta["odometry"] = repr(self.odometry)
        return Trajectory(observations=X, actions=u, positions=motion.positions,
                          odometry=odometry, action_names=self.action_names, meta=meta)

    @property
    def wall_segments(self) -> np.ndarray:
        """``(W, 2, 2)``: every wall of the floor plan as a segment (metres), for drawing."""
        return self.layout.segments

    def plot_room(self, ax, labels: bool = True):
        """Draw the floor plan on ``ax`` (:func:`.plot.plot_layout`; ``labels``: the regions'
        names); returns ``ax``."""
        return plot_layout(self.layout, ax, labels=labels)

    def __repr__(self) -> str:
        source = "random motion" if self.recording is None else self.recording.source
        odometry = "" if self.odometry is None else f", odometry={self.odometry!r}"
        return (f"ArenaWorld(layout={self.layout.name!r}, {source}, dt={self.dt:g}, "
                f"sensor={self.sensor!r}, actions={self.action_rule!r}{odometry})")
