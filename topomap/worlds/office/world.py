"""The office world: a room of aliased objects, places, docking and the simulated walk.

Places
------
Every object is a place (place id = object index).  Wall following stops at the room corners when
it turns, so the four corner points of the wall-following lane (at :attr:`OfficeWorld.wall_offset`
from both walls) are places too (ids ``n_objects .. n_objects + 3``, named ``"corner SW"``,
``"corner SE"``, ``"corner NE"``, ``"corner NW"``).  The place of a stop is decided by
:meth:`OfficeWorld.place_of`:

1. within reach of a GDS object: that GDS object (so GDS labels and places always agree);
2. the action ended by coming within reach of an object: that object;
3. otherwise: the nearest place that is not a GDS (distance to an object's surface, or to a
   corner point).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from ...core.checks import ParameterError, check_count
from ...core.data.trajectory import Trajectory
from ..checks import check_choice, check_simulate_args
from ..explorers import show
from .actions import Action, ApproachType, FollowWall, Pose
from .geometry import CORNER_NAMES, TOL, check_positive, corner_points
from .layout import OfficeLayout, paper_layout, random_layout
from .driving import Drive, wall_following_legs
from .plot import plot_room
from .sensing import Camera

__all__ = ["OfficeWorld"]

#: wall-following lane, interior corridor and sliding clearance (metres)
WALL_OFFSET, INTERIOR_WALL_GAP, ROBOT_CLEARANCE = 1.5, 2.0, 0.2
_PAPER_SIZE = dict(n_objects=25, n_types=15, n_gds=2, width=20.0, height=14.0)


def make_layout(layout, n_objects, n_types, n_gds, width, height, reach, seed):
    """The room of an :class:`OfficeWorld`: ``(OfficeLayout, name)``; validates the sizes."""
    if isinstance(layout, OfficeLayout):
        return layout, "custom"
    if not isinstance(layout, str) or layout not in ("paper", "random"):
        raise ValueError(f"layout must be 'paper', 'random' or an OfficeLayout, got {layout!r}")
    for name, value in (("n_objects", n_objects), ("n_types", n_types)):
        check_positive(name, value, integer=True)
    check_count(n_gds, "n_gds", minimum=0)
    check_positive("width", width)
    check_positive("height", height)
    if n_types > n_objects:
        raise ValueError(f"n_types ({n_types}) must not exceed n_objects ({n_objects})")
    if n_gds > n_objects:
        raise ValueError(f"n_gds ({n_gds}) must not exceed n_objects ({n_objects})")
    min_size = 2 * (INTERIOR_WALL_GAP + 1.0)
    if width < min_size or height < min_size:
        raise ValueError(f"width and height must be at least {min_size} m, got {width} x {height}")
    if layout == "random":
        return random_layout(np.random.default_rng(int(seed)), int(n_objects), int(n_types),
                             int(n_gds), float(width), float(height), reach=float(reach),
                             wall_offset=WALL_OFFSET, interior_wall_gap=INTERIOR_WALL_GAP), layout
    given = dict(n_objects=n_objects, n_types=n_types, n_gds=n_gds, width=width, height=height)
    for key, value in given.items():
        if value != _PAPER_SIZE[key]:
            raise ValueError(f"layout='paper' has {key}={_PAPER_SIZE[key]}, got {key}={value}; "
                             "use layout='random' for other sizes")
    return paper_layout(), layout


class OfficeWorld:
    """Office room with aliased objects, a panoramic size sensor and 17 object/wall actions.

    The room (``layout`` to ``height``) may be given by position, the rest by keyword only.

    Parameters
    ----------
    layout : {"paper", "random"} or OfficeLayout
        ``"paper"``: the fixed room of :func:`paper_layout` (requires the default counts and room
        size); ``"random"``: a room drawn by :func:`random_layout` from ``seed``; an
        :class:`OfficeLayout` is used as it is, and then ``n_objects``, ``n_types``, ``n_gds``,
        ``width`` and ``height`` are taken from it (the arguments are ignored).
    n_objects, n_types, n_gds : int
        Number of objects, object types (the observation dimension) and GDS objects.
    width, height : float
        Room size in metres.
    reach : float
        An action stops when the robot comes this close to an object's surface; the robot
        recognises a GDS within this distance.
    view_range : float or None
        Objects whose surface is farther away are not seen (``inf`` or None: unlimited).
    step_size : float
        Step length when sliding around an obstacle; unit of ``max_action_steps``.
    max_turn_deg : float
        An action stops when its heading has turned by more than this many degrees.
    max_action_steps : int
        Safety cap: an action stops after driving ``max_action_steps * step_size`` metres.
    seed : int
        Seed of the random layout (unused by the paper layout).
    dock : bool
        After every action the robot moves to the standing point of the place where it stopped
        (:meth:`standing_point`), facing the place -- the "hill-climbing to a distinctive place"
        of Kuipers' spatial semantic hierarchy.  Observations at a place then differ only by
        sensor noise, and aliasing comes from places that look alike, as in the paper.  With
        ``dock=False`` the robot stays where the action ended, so one place is seen from many
        points around it.
    extra_actions : sequence of Action
        Appended after the built-in actions.

    Attributes
    ----------
    actions : list of Action
        ``n_types`` :class:`ApproachType` actions, then "follow left wall" and "follow right
        wall", then ``extra_actions``.
    action_names, type_names, place_names, gds_names : list of str
    place_positions : (n_places, 2) float array
        Object centres, then the corner points.
    gds_places : list of int
        Place (= object) id of each GDS.
    object_types, object_positions, object_radii : arrays
    """


    wall_offset: float = WALL_OFFSET
    """Distance from the wall of the wall-following lane (and of the corner places)."""
    interior_wall_gap: float = INTERIOR_WALL_GAP
    """Free corridor between the walls and objects that are not wall segments (random layouts)."""
    robot_clearance: float = ROBOT_CLEARANCE
    """Closest the robot gets to the surface of an object it slides around."""

    def __init__(self, layout: str | OfficeLayout = "paper", n_objects: int = 25,
                 n_types: int = 15, n_gds: int = 2, width: float = 20.0, height: float = 14.0, *,
                 reach: float = 1.0, view_range: float | None = 3.0, step_size: float = 0.25,
                 max_turn_deg: float = 90.0, max_action_steps: int = 400, seed: int = 0,
                 dock: bool = True, extra_actions: Sequence[Action] = ()):
        view_range = math.inf if view_range is None else view_range
        check_positive("reach", reach)
        check_positive("view_range", view_range, allow_inf=True)
        check_positive("step_size", step_size)
        check_positive("max_turn_deg", max_turn_deg)
        check_positive("max_action_steps", max_action_steps, integer=True)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise ParameterError("seed", f"must be an integer, got {seed!r}")
        lay, self.layout_name = make_layout(layout, n_objects, n_types, n_gds, width, height,
                                            reach, seed)
        self.layout = lay
        self.width, self.height = lay.width, lay.height
        if min(self.width, self.height) <= 2 * self.wall_offset:
            raise ValueError(f"width and height must exceed {2 * self.wall_offset} m")
        self.n_objects, self.n_types, self.n_gds = lay.n_objects, lay.n_types, len(lay.gds)
        self.reach, self.view_range = float(reach), float(view_range)
        self.step_size, self.max_turn_deg = float(step_size), float(max_turn_deg)
        self.max_action_steps, self.seed, self.dock = int(max_action_steps), int(seed), bool(dock)
        self.type_names = list(lay.type_names)
        self.object_types = lay.types.copy()
        self.object_positions = lay.centers.copy()
        self.object_radii = lay.radii.copy()
        self.camera = Camera(self.object_types, self.object_positions, self.object_radii,
                             self.n_types, self.view_range, self.reach)
        self._init_places()
        self._init_actions(extra_actions)

    def _init_places(self) -> None:
        """GDS ids, place names and positions, and every place's standing point."""
        self.gds_places = list(self.layout.gds)
        self.gds_names = [f"GDS{k + 1}" for k in range(self.n_gds)]
        self._gds_of_object = np.full(self.n_objects, -1, dtype=np.int64)
        for k, obj in enumerate(self.gds_places):
            self._gds_of_object[obj] = k
        counts: dict[int, int] = {}
        names = []
        for i, t in enumerate(self.object_types):
            counts[int(t)] = counts.get(int(t), 0) + 1
            name = f"{self.type_names[t]} {counts[int(t)]}"
            if self._gds_of_object[i] >= 0:
                name += f" ({self.gds_names[self._gds_of_object[i]]})"
            names.append(name)
        self._corners = corner_points(self.width, self.height, self.wall_offset)
        self.place_names = names + list(CORNER_NAMES)
        self.place_positions = np.vstack([self.object_positions, self._corners])
        self.n_places = len(self.place_names)
        self._standing_points = [self.standing_point(p) for p in range(self.n_places)]

    def _init_actions(self, extra_actions) -> None:
        """The built-in approach and wall-following actions, then ``extra_actions``."""
        self._builtin = [ApproachType(k, f"approach {self.type_names[k]}")
                         for k in range(self.n_types)]
        self._builtin += [FollowWall("left"), FollowWall("right")]
        extra = list(extra_actions)
        for a in extra:
            if not (hasattr(a, "name") and callable(getattr(a, "is_executable", None))
                    and callable(getattr(a, "execute", None))):
                raise ValueError("extra_actions must hold Action objects with name, is_executable "
                                 f"and execute; got {a!r}")
        self.actions: list[Action] = self._builtin + extra
        self.action_names = [str(a.name) for a in self.actions]
        if len(set(self.action_names)) != len(self.action_names):
            raise ValueError(f"extra_actions: action names must be unique, got {self.action_names}")

    @classmethod
    def from_layout(cls, layout: OfficeLayout, **options) -> "OfficeWorld":
        """Build a world on a hand-made :class:`OfficeLayout`; ``options`` as in the constructor."""
        if not isinstance(layout, OfficeLayout):
            raise ValueError(f"layout must be an OfficeLayout, got {type(layout).__name__}")
        return cls(layout=layout, **options)

    @property
    def n_actions(self) -> int:
        return len(self.actions)

    def __repr__(self) -> str:
        return (f"OfficeWorld(layout={self.layout_name!r}, n_objects={self.n_objects}, "
                f"n_types={self.n_types}, n_gds={self.n_gds}, width={self.width}, "
                f"height={self.height}, reach={self.reach})")

    # ------------------------------------------------------------------ geometry and sensing
    def wall_distances(self, p) -> np.ndarray:
        """Distances from ``p`` to the south, east, north and west walls."""
        return np.array([p[1], self.width - p[0], self.height - p[1], p[0]])

    def surface_distances(self, p) -> np.ndarray:
        """Distances from ``p`` to every object's surface (negative inside an object)."""
        d = self.object_positions - np.asarray(p, dtype=np.float64)
        return np.hypot(d[:, 0], d[:, 1]) - self.object_radii

    def observe(self, pose: Pose) -> np.ndarray:
        """Noise-free observation at ``pose``: ``(n_types,)`` apparent sizes in radians (see
        :mod:`topomap.worlds.office.sensing`)."""
        return self.camera.observe(pose.x, pose.y)

    def approach_target(self, pose: Pose, type_index: int) -> int | None:
        """Object that "approach" type ``type_index`` would drive to, or None if not executable:
        the nearest (by centre distance) visible object of that type that is not within reach."""
        return self.camera.approach_target(pose.x, pose.y, type_index)

    def executable_mask(self, pose: Pose) -> np.ndarray:
        """Boolean mask over :attr:`actions`: which can be started at ``pose``."""
        cand = self.camera.approachable(pose.x, pose.y)
        mask = np.zeros(self.n_actions, dtype=bool)
        mask[: self.n_types] = np.bincount(self.object_types[cand], minlength=self.n_types) > 0
        mask[self.n_types : self.n_types + 2] = True
        for k in range(len(self._builtin), self.n_actions):
            mask[k] = bool(self.actions[k].is_executable(self, pose))
        return mask

    # ------------------------------------------------------------------ places
    def place_of(self, xy, end_reason: str = "done", entered: int = -1) -> int:
        """Place id of a stop at ``xy`` (rules in the module docstring)."""
        p = np.asarray(xy, dtype=np.float64)
        sd = self.surface_distances(p)
        near = sd <= self.reach + TOL
        gds_near = near & (self._gds_of_object >= 0)
        if gds_near.any():
            idx = np.flatnonzero(gds_near)
            return int(idx[np.argmin(sd[idx])])
        if end_reason == "reach" and entered >= 0:
            return int(entered)
        cd = np.hypot(*(self._corners - p).T)
        od = np.where(self._gds_of_object >= 0, np.inf, np.maximum(sd, 0.0))
        return int(np.argmin(np.concatenate([od, cd])))

    def gds_of(self, pose: Pose) -> int:
        """GDS id recognised at ``pose`` (-1 if none): the nearest GDS object within reach.

        By the rules of :meth:`place_of` this is also the GDS whose place is ``pose.place``.
        """
        sd = self.surface_distances(pose.xy)
        near = (sd <= self.reach + TOL) & (self._gds_of_object >= 0)
        if not near.any():
            return -1
        idx = np.flatnonzero(near)
        return int(self._gds_of_object[idx[np.argmin(sd[idx])]])

    def standing_point(self, place: int) -> np.ndarray:
        """A position where the robot stands at ``place`` (used for the start of a run).

        For an object: ``0.8 * reach`` from its surface, towards the room centre if that spot is
        free (inside the room, not within reach of another object), else rotated in 30-degree
        steps.  For a corner: the corner point.
        """
        if not 0 <= place < self.n_places:
            raise ValueError(f"place must be in [0, {self.n_places}), got {place}")
        if place >= self.n_objects:
            return self._corners[place - self.n_objects].copy()
        c, r = self.object_positions[place], self.object_radii[place]
        to_centre = np.array([self.width / 2, self.height / 2]) - c
        base = math.atan2(to_centre[1], to_centre[0])
        first = None
        for k in range(12):
            ang = base + (k + 1) // 2 * (math.pi / 6) * (1 if k % 2 else -1)
            q = c + (r + 0.8 * self.reach) * np.array([math.cos(ang), math.sin(ang)])
            if not (0.3 <= q[0] <= self.width - 0.3 and 0.3 <= q[1] <= self.height - 0.3):
                continue
            if first is None:
                first = q
            sd = self.surface_distances(q)
            sd[place] = np.inf
            if np.all(sd > self.reach + 0.05):
                return q
        return first if first is not None else c + np.array([r + 0.8 * self.reach, 0.0])

    def pose_at(self, x: float, y: float, heading: float = 0.0, prev_place: int = -1) -> Pose:
        """A :class:`Pose` at ``(x, y)`` with its place assigned by :meth:`place_of`."""
        sd = self.surface_distances((x, y))
        near = np.flatnonzero(sd <= self.reach + TOL)
        entered = int(near[np.argmin(sd[near])]) if near.size else -1
        place = self.place_of((x, y), "reach" if entered >= 0 else "done", entered)
        return Pose(float(x), float(y), float(heading), place, prev_place)

    def random_start(self, rng: np.random.Generator) -> Pose:
        """Pose at the standing point of a uniformly drawn place, facing that place."""
        place = int(rng.integers(self.n_places))
        q = self.standing_point(place)
        target = self.place_positions[place] if place < self.n_objects else np.array([self.width / 2, self.height / 2])
        v = target - q
        pose = self.pose_at(q[0], q[1], math.atan2(v[1], v[0]))
        return pose

    # ------------------------------------------------------------------ motion
    def wall_following_legs(self, pose: Pose, side: str) -> Iterable:
        """Legs of "follow ``side`` wall" from ``pose`` (an endless generator; see FollowWall)."""
        return wall_following_legs(self, pose, side)

    def drive(self, pose: Pose, legs: Iterable) -> Pose:
        """Drive the legs in order from ``pose`` and return the stop pose (with its place).

        Stops when the robot enters the reach zone of an object ("reach"), when the total turn
        between leg headings exceeds ``max_turn_deg`` ("turn", checked as each leg starts), when the
        path reaches ``max_action_steps * step_size`` ("cap"), when sliding around an obstacle is
        impossible ("blocked"), or when the legs run out ("done", or "reach" if the robot then
        stands within reach of an object it was not at when the action started).  Objects within
        reach at the start never end the action.  With ``dock`` the robot then moves to the
        standing point of its place, facing it.
        """
        m = Drive(self, pose)
        reason = m.run(legs)
        place = self.place_of(m.p, reason, m.entered)
        if self.dock:
            docked = self.docked_pose(place)
            m.p, m.heading = docked.xy, docked.heading
        return Pose(
            float(m.p[0]), float(m.p[1]), float(m.heading), place, pose.place, reason,
            float(m.turned), float(m.path), int(m.entered) if reason == "reach" else -1,
        )

    def docked_pose(self, place: int, prev_place: int = -1) -> Pose:
        """Where the robot stands at ``place`` after docking: its standing point, facing the
        place (a corner: facing the room centre)."""
        p = self._standing_points[place]
        target = self.place_positions[place] if place < self.n_objects else np.array(
            [self.width / 2, self.height / 2])
        heading = math.atan2(target[1] - p[1], target[0] - p[0])
        return Pose(float(p[0]), float(p[1]), float(heading), int(place), int(prev_place))

    def place_graph(self):
        """The true topology for navigation (:mod:`topomap.worlds.navigation`): with docking, an
        action's result depends only on the place it starts from, so the office is a graph of
        places.  Without docking it is not (ValueError)."""
        from ..navigation import explored_graph

        if not self.dock:
            raise ValueError("navigation in the office world needs env.dock=true: without "
                             "docking an action's result depends on where in a place it starts")
        poses = [self.docked_pose(p) for p in range(self.n_places)]
        rng = np.random.default_rng(0)  # the built-in actions are deterministic

        def step(p):
            mask = self.executable_mask(poses[p])
            return [self.step(poses[p], a, rng).place if mask[a] else -1
                    for a in range(self.n_actions)]

        return explored_graph(self.n_places, self.n_actions, list(range(self.n_places)), step,
                              lambda p: self.observe(poses[p]), lambda p: self.gds_of(poses[p]))

    def step(self, pose: Pose, action: int, rng: np.random.Generator) -> Pose:
        """Execute action ``action`` (an index into :attr:`actions`) from ``pose``."""
        return self.actions[action].execute(self, pose, rng)

    # ------------------------------------------------------------------ simulation
    def simulate(self, n_steps: int, explorer, rng: np.random.Generator) -> Trajectory:
        """Explore for ``n_steps`` steps and return the trajectory.

        Starts at :meth:`random_start`; at each step records the position, place, GDS id and
        noise-free observation, asks ``explorer.choose(executable_mask, rng)`` for an action and
        executes it (the last step's action is chosen but not executed).

        Returns
        -------
        Trajectory
            With ``observations``, ``actions``, ``gds``, ``places``, ``positions``,
            ``action_names``, ``gds_names`` and ``meta`` holding ``world``, ``layout``,
            ``place_names``, ``type_names``, ``gds_places``, ``headings`` (T floats) and, per
            transition, ``end_reasons`` and ``turns_deg`` (T - 1 entries each).
        """
        T = check_simulate_args(n_steps, explorer)
        obs = np.zeros((T, self.n_types))
        actions = np.zeros(T, dtype=np.int64)
        gds = np.full(T, -1, dtype=np.int64)
        places = np.zeros(T, dtype=np.int64)
        positions = np.zeros((T, 2))
        headings, reasons, turns = [], [], []
        pose = self.random_start(rng)
        for t in range(T):
            obs[t], places[t], positions[t] = self.observe(pose), pose.place, (pose.x, pose.y)
            gds[t] = self.gds_of(pose)
            headings.append(float(pose.heading))
            mask = self.executable_mask(pose)
            show(explorer, obs[t], mask, gds[t], t)
            actions[t] = check_choice(explorer.choose(mask, rng), mask, t)
            if t + 1 < T:
                pose = self.step(pose, int(actions[t]), rng)
                reasons.append(pose.end_reason)
                turns.append(float(pose.turned_deg))
        meta = {
            "world": "office", "layout": self.layout_name, "seed": self.seed,
            "place_names": list(self.place_names), "type_names": list(self.type_names),
            "gds_places": [int(g) for g in self.gds_places], "reach": self.reach,
            "max_turn_deg": self.max_turn_deg, "headings": headings, "end_reasons": reasons,
            "turns_deg": turns,
        }
        return Trajectory(
            observations=obs, actions=actions, gds=gds, places=places, positions=positions,
            action_names=list(self.action_names), gds_names=list(self.gds_names), meta=meta,
        )

    def plot_room(self, ax, labels: bool = True, show_corners: bool = True):
        """Draw the room (see :func:`topomap.worlds.office.plot.plot_room`).  Returns ``ax``."""
        return plot_room(self, ax, labels=labels, show_corners=show_corners)
