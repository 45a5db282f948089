"""The office world of Yairi, Togami & Hori (PRICAI 2002), Section 4.1.

A rectangular room holds 25 objects of 15 types ("red wall", "blue desk", chairs, tables,
computers, ...).  Types repeat, so different places look alike (perceptual aliasing).  A robot with
a panoramic camera observes, for every type, the apparent (angular) size of the visible objects of
that type, and moves with 17 actions: "approach a <type> object" for each of the 15 types and
"follow left / right wall".  An action stops when the robot comes within ``reach`` of an object or
when its heading has turned by more than ``max_turn_deg`` degrees.  Two objects are globally
distinctive states (GDS): the robot knows it is at GDS ``k`` when it stands within reach of it.

Geometry
--------
The room is ``[0, width] x [0, height]``; the walls are numbered 0 = south (``y = 0``),
1 = east (``x = width``), 2 = north (``y = height``), 3 = west (``x = 0``).  Objects are discs
(centre, radius).  *Wall objects* (coloured wall segments) touch a wall; every other object keeps a
free corridor of at least :attr:`OfficeWorld.interior_wall_gap` to the walls.  The robot is a point;
it is "within reach" of an object when its distance to the object's *surface* is at most ``reach``.

Places
------
Every object is a place (place id = object index).  Wall following stops at the room corners when
it turns, so the four corner points of the wall-following lane (at :attr:`wall_offset` from both
walls) are places too (ids ``n_objects .. n_objects + 3``, named ``"corner SW"``, ``"corner SE"``,
``"corner NE"``, ``"corner NW"``).  The place of a stop is decided by :meth:`OfficeWorld.place_of`:

1. within reach of a GDS object: that GDS object (so GDS labels and places always agree);
2. the action ended by coming within reach of an object: that object;
3. otherwise: the nearest place that is not a GDS (distance to an object's surface, or to a
   corner point).

Motion
------
An action is a sequence of *legs* (:class:`GoTo`, :class:`GoToWall` or any object with the same two
methods) run by :meth:`OfficeWorld.drive`.  Each leg has a nominal heading; the turn of an action is
the sum of the absolute heading changes between consecutive legs (the robot's initial rotation on
the spot is not counted).  Motion along a leg is straight and computed exactly (ray/circle
intersections), so no reach zone is ever skipped.  The robot starts an action within reach of the
object it stands at; the objects within reach when an action starts never end it (so an action
never ends where it started).  If a straight move would run into one of them, the robot slides
around it (steps of ``step_size`` along a circle of radius ``radius + robot_clearance``).  The end of each action is recorded in the
returned :class:`Pose` (``end_reason`` is ``"reach"``, ``"turn"``, ``"cap"`` when the path length
reached ``max_action_steps * step_size``, ``"blocked"`` when sliding was impossible, or ``"done"``
when a custom action's legs ran out).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from topomap.trajectory import Trajectory

__all__ = [
    "Action",
    "ApproachType",
    "FollowWall",
    "GoTo",
    "GoToWall",
    "OfficeLayout",
    "OfficeWorld",
    "Pose",
    "paper_layout",
    "random_layout",
]

_TOL = 1e-7
_WALL_NORMALS = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
_CORNER_NAMES = ("corner SW", "corner SE", "corner NE", "corner NW")


def _wrap(angle: float) -> float:
    """Wrap an angle in radians to ``(-pi, pi]``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


# --------------------------------------------------------------------------------------------
# Poses and actions
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Pose:
    """Where the robot is and how it got there.

    Attributes
    ----------
    x, y : float
        Position in the room.
    heading : float
        Direction of the last motion (radians, counter-clockwise from the ``+x`` axis).
    place : int
        Place id of this stop (``-1`` if not assigned yet).
    prev_place : int
        Place id of the previous stop (``-1`` at the start).
    end_reason : str
        Why the action that led here ended: ``"start"``, ``"reach"``, ``"turn"``, ``"cap"``,
        ``"blocked"`` or ``"done"`` (see the module docstring).
    turned_deg : float
        Turn of that action in degrees (sum of absolute heading changes between legs).
    path_length : float
        Length of the path driven by that action.
    entered : int
        Object whose reach zone ended the action (``-1`` unless ``end_reason == "reach"``).
    """

    x: float
    y: float
    heading: float = 0.0
    place: int = -1
    prev_place: int = -1
    end_reason: str = "start"
    turned_deg: float = 0.0
    path_length: float = 0.0
    entered: int = -1

    @property
    def xy(self) -> np.ndarray:
        """Position as a ``(2,)`` float array."""
        return np.array([self.x, self.y], dtype=np.float64)


class Action:
    """Base class of the robot's actions.

    Subclasses set :attr:`name` and implement :meth:`execute`; they may override
    :meth:`is_executable` (the default: always executable).  Actions must be deterministic given
    the pose (``rng`` is passed for actions that are meant to be stochastic).  Most actions build
    a list of legs and call :meth:`OfficeWorld.drive`.
    """

    name: str = "action"

    def is_executable(self, world: "OfficeWorld", pose: Pose) -> bool:
        """Return whether the action can be started at ``pose``."""
        return True

    def execute(self, world: "OfficeWorld", pose: Pose, rng: np.random.Generator) -> Pose:
        """Run the action from ``pose`` and return the pose where it stopped (place assigned)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class ApproachType(Action):
    """Move straight towards the nearest visible object of type ``type_index``.

    Executable when an object of that type is visible and the robot is not already within its
    reach.  The action stops within reach of the target, or earlier within reach of any object the
    robot passes close to.

    Parameters
    ----------
    type_index : int
        Object type to approach.
    name : str, optional
        Action name; defaults to ``"approach type <k>"`` (the world names its built-in ones
        ``"approach <type name>"``).
    """

    def __init__(self, type_index: int, name: str | None = None):
        self.type_index = int(type_index)
        self.name = name if name is not None else f"approach type {self.type_index}"

    def is_executable(self, world: "OfficeWorld", pose: Pose) -> bool:
        return world.approach_target(pose, self.type_index) is not None

    def execute(self, world: "OfficeWorld", pose: Pose, rng: np.random.Generator) -> Pose:
        target = world.approach_target(pose, self.type_index)
        if target is None:
            raise ValueError(f"action {self.name!r} is not executable at ({pose.x:.2f}, {pose.y:.2f})")
        centre = world.object_positions[target]
        stop = float(world.object_radii[target]) + world.reach
        return world.drive(pose, [GoTo(centre, stop_distance=stop)])


class FollowWall(Action):
    """Go to the nearest wall and follow it with the wall on the ``side`` ("left" or "right").

    The robot faces the nearest wall (ties go to the lower wall number; in a corner, i.e. within
    :attr:`OfficeWorld.wall_offset` of two walls, the wall along which ``side`` leads out of the
    corner), drives perpendicular to it until it is ``wall_offset`` away (no motion if it is already
    that close), turns 90 degrees along the wall and follows the wall lane, turning another 90
    degrees at each corner.  The turn is counted from the heading facing the wall, so with the
    default ``max_turn_deg = 90`` the robot stops at the next object along the wall or at the
    first corner.  Always executable.
    """

    def __init__(self, side: str, name: str | None = None):
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        self.side = side
        self.name = name if name is not None else f"follow {side} wall"

    def execute(self, world: "OfficeWorld", pose: Pose, rng: np.random.Generator) -> Pose:
        return world.drive(pose, world.wall_following_legs(pose, self.side))


# --------------------------------------------------------------------------------------------
# Legs
# --------------------------------------------------------------------------------------------


class GoTo:
    """Leg: drive straight towards ``point`` until ``stop_distance`` away from it.

    Parameters
    ----------
    point : (2,) array_like
    stop_distance : float
        The leg ends at this distance from ``point``.
    heading : float, optional
        Nominal heading used for turn counting; by default the direction from the leg's start.
    hint : (2,) array_like, optional
        Preferred side when the robot must slide around an obstacle straight ahead.
    """

    def __init__(self, point, stop_distance: float = 0.0, heading: float | None = None, hint=None):
        self.point = np.asarray(point, dtype=np.float64)
        self.stop_distance = float(stop_distance)
        self._heading = heading
        self.hint = None if hint is None else np.asarray(hint, dtype=np.float64)

    def heading(self, p: np.ndarray) -> float:
        """Nominal heading of the leg when it starts at ``p``."""
        if self._heading is not None:
            return float(self._heading)
        v = self.point - p
        return math.atan2(v[1], v[0])

    def guide(self, p: np.ndarray) -> tuple[np.ndarray, float]:
        """Return the unit direction to move in from ``p`` and the distance left."""
        v = self.point - p
        d = math.hypot(v[0], v[1])
        if d < 1e-12:
            return np.array([1.0, 0.0]), -self.stop_distance
        return v / d, d - self.stop_distance


class GoToWall:
    """Leg: drive perpendicular to wall ``wall`` until ``offset`` away from it.

    Parameters
    ----------
    world : OfficeWorld
    wall : int
        0 south, 1 east, 2 north, 3 west.
    offset : float
    hint : (2,) array_like, optional
        Preferred side when sliding around an obstacle (wall following passes the direction it
        will take along the wall).
    """

    def __init__(self, world: "OfficeWorld", wall: int, offset: float, hint=None):
        self.world = world
        self.wall = int(wall)
        self.offset = float(offset)
        self.normal = _WALL_NORMALS[self.wall]
        self.hint = None if hint is None else np.asarray(hint, dtype=np.float64)

    def heading(self, p: np.ndarray) -> float:
        return math.atan2(self.normal[1], self.normal[0])

    def guide(self, p: np.ndarray) -> tuple[np.ndarray, float]:
        return self.normal, self.world.wall_distances(p)[self.wall] - self.offset


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------


@dataclass
class OfficeLayout:
    """Objects of an office room.

    Attributes
    ----------
    width, height : float
        Room size.
    type_names : list of str
        One name per object type; the observation has one entry per type.
    types : (n,) int array
        Type of each object.
    centers : (n, 2) float array
        Object centres.
    radii : (n,) float array
        Object radii (physical size).
    gds : list of int
        Objects that are globally distinctive states, in GDS id order.
    """

    width: float
    height: float
    type_names: list[str]
    types: np.ndarray
    centers: np.ndarray
    radii: np.ndarray
    gds: list[int] = field(default_factory=list)

    def __post_init__(self):
        self.width, self.height = float(self.width), float(self.height)
        if not (math.isfinite(self.width) and self.width > 0):
            raise ValueError(f"width must be a positive number, got {self.width}")
        if not (math.isfinite(self.height) and self.height > 0):
            raise ValueError(f"height must be a positive number, got {self.height}")
        self.type_names = [str(t) for t in self.type_names]
        if not self.type_names:
            raise ValueError("type_names must name at least one type")
        self.types = np.asarray(self.types, dtype=np.int64).reshape(-1)
        self.centers = np.asarray(self.centers, dtype=np.float64).reshape(-1, 2)
        self.radii = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        n = self.types.size
        if n == 0:
            raise ValueError("a layout needs at least one object")
        if self.centers.shape[0] != n or self.radii.size != n:
            raise ValueError(
                f"types ({n}), centers ({self.centers.shape[0]}) and radii ({self.radii.size}) "
                "must describe the same number of objects"
            )
        if self.types.min() < 0 or self.types.max() >= len(self.type_names):
            raise ValueError(f"types must lie in [0, {len(self.type_names)})")
        if not np.all(self.radii > 0):
            raise ValueError("radii must be positive")
        lo = self.centers - self.radii[:, None]
        hi = self.centers + self.radii[:, None]
        if np.any(lo < -1e-9) or np.any(hi[:, 0] > self.width + 1e-9) or np.any(hi[:, 1] > self.height + 1e-9):
            raise ValueError("every object must lie inside the room")
        gap = _surface_gaps(self.centers, self.radii)
        if np.any(gap < -1e-9):
            i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
            raise ValueError(f"objects {i} and {j} overlap")
        self.gds = [int(g) for g in self.gds]
        if len(set(self.gds)) != len(self.gds) or any(g < 0 or g >= n for g in self.gds):
            raise ValueError(f"gds must list distinct object indices in [0, {n})")

    @property
    def n_objects(self) -> int:
        return int(self.types.size)

    @property
    def n_types(self) -> int:
        return len(self.type_names)


def _surface_gaps(centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Pairwise surface-to-surface distances (``inf`` on the diagonal)."""
    d = np.hypot(*(centers[:, None, :] - centers[None, :, :]).transpose(2, 0, 1))
    gap = d - radii[:, None] - radii[None, :]
    np.fill_diagonal(gap, np.inf)
    return gap


# name, radius (m), and whether it is a segment of a wall
_PAPER_TYPES = [
    ("red wall", 0.5, True),
    ("blue wall", 0.5, True),
    ("green wall", 0.5, True),
    ("yellow wall", 0.5, True),
    ("white wall", 0.5, True),
    ("blue desk", 0.7, False),
    ("gray table", 0.6, False),
    ("green table", 0.6, False),
    ("blue table", 0.6, False),
    ("long gray table", 1.0, False),
    ("computer", 0.35, False),
    ("green chair", 0.35, False),
    ("gray chair", 0.35, False),
    ("red chair", 0.35, False),
    ("blue chair", 0.35, False),
]

# (type name, x, y) in a 20 m x 14 m room
_PAPER_OBJECTS = [
    ("red wall", 4.0, 0.5),
    ("yellow wall", 7.5, 0.5),
    ("blue wall", 15.0, 0.5),
    ("green wall", 19.5, 5.0),
    ("red wall", 19.5, 10.0),
    ("blue wall", 15.0, 13.5),
    ("green wall", 8.0, 13.5),
    ("red wall", 5.0, 13.5),
    ("white wall", 0.5, 9.5),
    ("yellow wall", 0.5, 4.5),
    ("blue desk", 4.0, 4.0),
    ("computer", 6.2, 4.0),
    ("green chair", 4.0, 6.2),
    ("blue desk", 16.0, 10.0),
    ("computer", 13.8, 10.0),
    ("green chair", 16.0, 7.8),
    ("long gray table", 10.0, 7.0),
    ("gray chair", 7.6, 7.0),
    ("gray chair", 12.4, 7.0),
    ("blue table", 13.5, 3.5),
    ("blue table", 16.5, 3.5),
    ("green table", 4.0, 10.0),
    ("red chair", 6.2, 10.0),
    ("blue chair", 10.0, 11.2),
    ("gray table", 10.0, 2.8),
]
_PAPER_GDS = [23, 24]  # GDS1 = the blue chair, GDS2 = the gray table


def paper_layout() -> OfficeLayout:
    """The fixed 20 m x 14 m room with 25 objects of 15 types and 2 GDS (after the paper's Fig. 4).

    Ten coloured wall segments (5 colours) line the walls; two desk groups (blue desk, computer,
    green chair) sit in opposite corners of the room, a long gray table with two gray chairs in the
    middle, two blue tables bottom right, a green table and a red chair top left.  The GDS are the
    blue chair (GDS1, top centre) and the gray table (GDS2, bottom centre), each at least 2 m from
    every other object.
    """
    names = [t[0] for t in _PAPER_TYPES]
    radius = {t[0]: t[1] for t in _PAPER_TYPES}
    types = [names.index(o[0]) for o in _PAPER_OBJECTS]
    centers = [(o[1], o[2]) for o in _PAPER_OBJECTS]
    radii = [radius[o[0]] for o in _PAPER_OBJECTS]
    return OfficeLayout(20.0, 14.0, names, types, centers, radii, list(_PAPER_GDS))


_COLOURS = ["red", "blue", "green", "gray", "yellow", "white", "black", "brown", "orange", "purple"]
# kind, radius, on a wall
_KINDS = [
    ("wall", 0.5, True),
    ("desk", 0.7, False),
    ("table", 0.6, False),
    ("chair", 0.35, False),
    ("computer", 0.35, False),
    ("shelf", 0.45, True),
    ("plant", 0.3, False),
    ("cabinet", 0.5, False),
]


def random_layout(
    rng: np.random.Generator,
    n_objects: int = 25,
    n_types: int = 15,
    n_gds: int = 2,
    width: float = 20.0,
    height: float = 14.0,
    reach: float = 1.0,
    wall_offset: float = 1.5,
    interior_wall_gap: float = 2.0,
    min_gap: float = 1.0,
    max_tries: int = 20,
) -> OfficeLayout:
    """Draw a room with ``n_objects`` objects of ``n_types`` types and ``n_gds`` GDS objects.

    Every type is used at least once.  Type names combine a colour and a kind ("blue desk");
    wall-mounted kinds ("wall", "shelf") touch a wall at least ``wall_offset + reach + 1.5`` from a
    corner; the other objects keep ``interior_wall_gap`` to the walls.  Object surfaces are at least
    ``min_gap`` apart, GDS objects at least ``2 * reach + 0.2`` from every other object, and no
    object is within reach of a corner place, so every object can be approached and GDS labels are
    unambiguous.

    Raises
    ------
    ValueError
        If the objects do not fit into the room.
    """
    combos = [(c, k) for k in range(len(_KINDS)) for c in _COLOURS]
    order = rng.permutation(len(combos))
    type_names, type_radius, type_wall = [], [], []
    for k in range(n_types):
        if k < len(combos):
            colour, kind = combos[order[k]]
            name, radius, on_wall = f"{colour} {_KINDS[kind][0]}", _KINDS[kind][1], _KINDS[kind][2]
        else:
            kind = int(rng.integers(len(_KINDS)))
            name, radius, on_wall = f"type {k}", _KINDS[kind][1], _KINDS[kind][2]
        type_names.append(name)
        type_radius.append(radius)
        type_wall.append(on_wall)
    types = np.concatenate([np.arange(n_types), rng.integers(0, n_types, n_objects - n_types)])
    types = rng.permutation(types)
    gds = sorted(rng.choice(n_objects, size=n_gds, replace=False).tolist()) if n_gds else []
    # place GDS objects first: they need the widest free space
    order = gds + [i for i in range(n_objects) if i not in set(gds)]
    corners = _corner_points(width, height, wall_offset)
    gds_gap = 2.0 * reach + 0.2
    for _attempt in range(max_tries):
        centers = np.zeros((n_objects, 2))
        radii = np.array([type_radius[t] for t in types], dtype=np.float64)
        placed: list[int] = []
        ok = True
        for i in order:
            r = radii[i]
            for _try in range(400):
                if type_wall[types[i]]:
                    wall = int(rng.integers(4))
                    length = width if wall in (0, 2) else height
                    margin = wall_offset + reach + 1.5 + r
                    if length - 2 * margin <= 0:
                        continue
                    s = rng.uniform(margin, length - margin)
                    c = {0: (s, r), 1: (width - r, s), 2: (s, height - r), 3: (r, s)}[wall]
                else:
                    lo = interior_wall_gap + r
                    if width - 2 * lo <= 0 or height - 2 * lo <= 0:
                        continue
                    c = (rng.uniform(lo, width - lo), rng.uniform(lo, height - lo))
                c = np.asarray(c)
                if np.any(np.hypot(*(corners - c).T) - r <= reach + 0.1):
                    continue
                good = True
                for j in placed:
                    gap = math.hypot(*(centers[j] - c)) - radii[j] - r
                    need = gds_gap if (i in gds or j in gds) else min_gap
                    if gap < need:
                        good = False
                        break
                if good:
                    centers[i] = c
                    placed.append(i)
                    break
            else:
                ok = False
                break
        if ok:
            return OfficeLayout(width, height, type_names, types, centers, radii, gds)
    raise ValueError(
        f"could not place n_objects={n_objects} objects in a {width} x {height} room; "
        "use a bigger room (width, height) or fewer objects"
    )


def _corner_points(width: float, height: float, offset: float) -> np.ndarray:
    """Corner points of the wall-following lane: SW, SE, NE, NW."""
    return np.array(
        [[offset, offset], [width - offset, offset], [width - offset, height - offset], [offset, height - offset]]
    )


# --------------------------------------------------------------------------------------------
# The world
# --------------------------------------------------------------------------------------------


def _check_positive(name: str, value, integer: bool = False, allow_inf: bool = False):
    ok_type = isinstance(value, (int, np.integer)) if integer else isinstance(value, (int, float, np.integer, np.floating))
    if isinstance(value, bool) or not ok_type:
        kind = "an integer" if integer else "a number"
        raise ValueError(f"{name} must be {kind}, got {value!r}")
    if not (value > 0) or (not allow_inf and not math.isfinite(value)) or math.isnan(value):
        raise ValueError(f"{name} must be positive{'' if allow_inf else ' and finite'}, got {value!r}")


class OfficeWorld:
    """Office room with aliased objects, a panoramic size sensor and 17 object/wall actions.

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

    wall_offset: float = 1.5
    """Distance from the wall of the wall-following lane (and of the corner places)."""
    interior_wall_gap: float = 2.0
    """Free corridor between the walls and objects that are not wall segments (random layouts)."""
    robot_clearance: float = 0.2
    """Closest the robot gets to the surface of an object it slides around."""

    def __init__(
        self,
        layout: str | OfficeLayout = "paper",
        n_objects: int = 25,
        n_types: int = 15,
        n_gds: int = 2,
        width: float = 20.0,
        height: float = 14.0,
        reach: float = 1.0,
        view_range: float | None = 10.0,
        step_size: float = 0.25,
        max_turn_deg: float = 90.0,
        max_action_steps: int = 400,
        seed: int = 0,
        dock: bool = True,
        extra_actions: Sequence[Action] = (),
    ):
        _check_positive("reach", reach)
        if view_range is None:
            view_range = math.inf
        _check_positive("view_range", view_range, allow_inf=True)
        _check_positive("step_size", step_size)
        _check_positive("max_turn_deg", max_turn_deg)
        _check_positive("max_action_steps", max_action_steps, integer=True)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise ValueError(f"seed must be an integer, got {seed!r}")
        if isinstance(layout, OfficeLayout):
            lay = layout
            layout_name = "custom"
        elif isinstance(layout, str):
            if layout not in ("paper", "random"):
                raise ValueError(f"layout must be 'paper', 'random' or an OfficeLayout, got {layout!r}")
            for name, value in (("n_objects", n_objects), ("n_types", n_types)):
                _check_positive(name, value, integer=True)
            if isinstance(n_gds, bool) or not isinstance(n_gds, (int, np.integer)) or n_gds < 0:
                raise ValueError(f"n_gds must be a non-negative integer, got {n_gds!r}")
            _check_positive("width", width)
            _check_positive("height", height)
            if n_types > n_objects:
                raise ValueError(f"n_types ({n_types}) must not exceed n_objects ({n_objects})")
            if n_gds > n_objects:
                raise ValueError(f"n_gds ({n_gds}) must not exceed n_objects ({n_objects})")
            min_size = 2 * (self.interior_wall_gap + 1.0)
            if width < min_size or height < min_size:
                raise ValueError(f"width and height must be at least {min_size} m, got {width} x {height}")
            if layout == "paper":
                given = dict(n_objects=n_objects, n_types=n_types, n_gds=n_gds, width=width, height=height)
                fixed = dict(n_objects=25, n_types=15, n_gds=2, width=20.0, height=14.0)
                for key, value in given.items():
                    if value != fixed[key]:
                        raise ValueError(
                            f"layout='paper' has {key}={fixed[key]}, got {key}={value}; "
                            "use layout='random' for other sizes"
                        )
                lay = paper_layout()
            else:
                lay = random_layout(
                    np.random.default_rng(int(seed)), int(n_objects), int(n_types), int(n_gds),
                    float(width), float(height), float(reach), self.wall_offset, self.interior_wall_gap,
                )
            layout_name = layout
        else:
            raise ValueError(f"layout must be 'paper', 'random' or an OfficeLayout, got {layout!r}")

        self.layout = lay
        self.layout_name = layout_name
        self.width, self.height = lay.width, lay.height
        if min(self.width, self.height) <= 2 * self.wall_offset:
            raise ValueError(f"width and height must exceed {2 * self.wall_offset} m")
        self.n_objects, self.n_types, self.n_gds = lay.n_objects, lay.n_types, len(lay.gds)
        self.reach = float(reach)
        self.view_range = float(view_range)
        self.step_size = float(step_size)
        self.max_turn_deg = float(max_turn_deg)
        self.max_action_steps = int(max_action_steps)
        self.seed = int(seed)
        self.dock = bool(dock)

        self.type_names = list(lay.type_names)
        self.object_types = lay.types.copy()
        self.object_positions = lay.centers.copy()
        self.object_radii = lay.radii.copy()
        self.gds_places = list(lay.gds)
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
        self._corners = _corner_points(self.width, self.height, self.wall_offset)
        self.place_names = names + list(_CORNER_NAMES)
        self.place_positions = np.vstack([self.object_positions, self._corners])
        self.n_places = len(self.place_names)
        self._standing_points = [self.standing_point(p) for p in range(self.n_places)]

        self._builtin = [ApproachType(k, f"approach {self.type_names[k]}") for k in range(self.n_types)]
        self._builtin += [FollowWall("left"), FollowWall("right")]
        extra = list(extra_actions)
        for a in extra:
            if not (hasattr(a, "name") and callable(getattr(a, "is_executable", None)) and callable(getattr(a, "execute", None))):
                raise ValueError(
                    f"extra_actions must hold Action objects with name, is_executable and execute; got {a!r}"
                )
        self.actions: list[Action] = self._builtin + extra
        self.action_names = [str(a.name) for a in self.actions]
        if len(set(self.action_names)) != len(self.action_names):
            raise ValueError(f"extra_actions: action names must be unique, got {self.action_names}")
        self._view_key = None
        self._view_val = None

    # ------------------------------------------------------------------ construction helpers
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
        return (
            f"OfficeWorld(layout={self.layout_name!r}, n_objects={self.n_objects}, n_types={self.n_types}, "
            f"n_gds={self.n_gds}, width={self.width}, height={self.height}, reach={self.reach})"
        )

    # ------------------------------------------------------------------ geometry
    def wall_distances(self, p) -> np.ndarray:
        """Distances from ``p`` to the south, east, north and west walls."""
        return np.array([p[1], self.width - p[0], self.height - p[1], p[0]])

    def surface_distances(self, p) -> np.ndarray:
        """Distances from ``p`` to every object's surface (negative inside an object)."""
        d = self.object_positions - np.asarray(p, dtype=np.float64)
        return np.hypot(d[:, 0], d[:, 1]) - self.object_radii

    def within_reach(self, pose_or_xy) -> np.ndarray:
        """Boolean mask of the objects within ``reach`` of the robot."""
        p = pose_or_xy.xy if isinstance(pose_or_xy, Pose) else np.asarray(pose_or_xy, dtype=np.float64)
        return self.surface_distances(p) <= self.reach + _TOL

    def _view(self, x: float, y: float):
        """Visibility mask, apparent sizes and centre distances of all objects from ``(x, y)``."""
        key = (float(x), float(y))
        if key == self._view_key:
            return self._view_val
        C, R = self.object_positions, self.object_radii
        D = C - np.array(key)
        dist = np.maximum(np.hypot(D[:, 0], D[:, 1]), 1e-12)
        U = D / dist[:, None]
        t = U @ D.T  # t[i, j]: position of object j's centre along the line of sight to object i
        perp2 = dist[None, :] ** 2 - t**2
        occ = (t > 0) & (dist[None, :] < dist[:, None]) & (perp2 < R[None, :] ** 2)
        np.fill_diagonal(occ, False)
        visible = ~occ.any(axis=1) & (dist - R <= self.view_range)
        apparent = 2.0 * np.arctan(R / np.maximum(dist, R))
        self._view_key, self._view_val = key, (visible, apparent, dist)
        return self._view_val

    def visible_objects(self, pose: Pose) -> np.ndarray:
        """Boolean mask of the objects the camera sees from ``pose``.

        An object is hidden when the line of sight to its centre passes within the radius of an
        object whose centre is nearer, or when its surface is farther than ``view_range``.
        Walls never hide anything (the room is convex).
        """
        return self._view(pose.x, pose.y)[0].copy()

    def observe(self, pose: Pose) -> np.ndarray:
        """Noise-free observation at ``pose``: ``(n_types,)`` apparent sizes in radians.

        Entry ``k`` is the largest apparent (angular) size ``2 * atan(radius / distance)`` among
        the visible objects of type ``k`` (0 if none is visible); the distance is to the centre.
        """
        visible, apparent, _ = self._view(pose.x, pose.y)
        obs = np.zeros(self.n_types)
        np.maximum.at(obs, self.object_types[visible], apparent[visible])
        return obs

    def approach_target(self, pose: Pose, type_index: int) -> int | None:
        """Object that "approach" type ``type_index`` would drive to, or None if not executable.

        The nearest (by centre distance) visible object of that type that is not within reach.
        """
        visible, _, dist = self._view(pose.x, pose.y)
        cand = visible & (self.object_types == type_index) & (dist - self.object_radii > self.reach + _TOL)
        if not cand.any():
            return None
        idx = np.flatnonzero(cand)
        return int(idx[np.argmin(dist[idx])])

    def executable_mask(self, pose: Pose) -> np.ndarray:
        """Boolean mask over :attr:`actions`: which can be started at ``pose``."""
        visible, _, dist = self._view(pose.x, pose.y)
        cand = visible & (dist - self.object_radii > self.reach + _TOL)
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
        near = sd <= self.reach + _TOL
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
        near = (sd <= self.reach + _TOL) & (self._gds_of_object >= 0)
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
        near = np.flatnonzero(sd <= self.reach + _TOL)
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
        p = pose.xy
        wd = self.wall_distances(p)
        d = self.wall_offset

        def along(wall):
            n = _WALL_NORMALS[wall]
            return np.array([n[1], -n[0]]) if side == "left" else np.array([-n[1], n[0]])

        def ahead(h):
            return int(np.argmax(_WALL_NORMALS @ h))

        w = int(np.argmin(wd))
        near = [k for k in range(4) if wd[k] <= d + 1e-6]
        if len(near) >= 2:  # in a corner: take the wall along which this side leads out of it
            w = next(k for k in near if ahead(along(k)) not in near)
        h = along(w)
        # first leg: face the wall (zero length when already on the lane); it sets the reference
        # heading, so turning along the wall counts 90 degrees and each corner another 90
        yield GoToWall(self, w, d, hint=h)
        while True:
            nxt = ahead(h)
            x = d if 3 in (w, nxt) else self.width - d
            y = d if 0 in (w, nxt) else self.height - d
            yield GoTo((x, y), heading=math.atan2(h[1], h[0]), hint=h)
            w, h = nxt, along(nxt)

    def drive(self, pose: Pose, legs: Iterable) -> Pose:
        """Drive the legs in order from ``pose`` and return the stop pose (with its place).

        Stops when the robot enters the reach zone of an object ("reach"), when the total turn
        between leg headings exceeds ``max_turn_deg`` ("turn", checked as each leg starts), when the
        path reaches ``max_action_steps * step_size`` ("cap"), when sliding around an obstacle is
        impossible ("blocked"), or when the legs run out ("done", or "reach" if the robot then
        stands within reach of an object it was not at when the action started).  Objects within
        reach at the start never end the action.
        """
        m = _Motion(self, pose)
        reason = None
        prev_heading = None
        n_legs = 0
        for leg in legs:
            n_legs += 1
            if n_legs > self.max_action_steps:
                reason = "cap"
                break
            h = leg.heading(m.p)
            if prev_heading is not None:
                m.turned += abs(math.degrees(_wrap(h - prev_heading)))
            prev_heading = h
            if m.turned > self.max_turn_deg + 1e-9:
                reason = "turn"
                break
            reason = m.run_leg(leg)
            if reason is not None:
                break
        if reason is None:
            sd = self.surface_distances(m.p)
            fresh = np.flatnonzero(m.armed & (sd <= self.reach + _TOL))
            if fresh.size:
                reason, m.entered = "reach", int(fresh[np.argmin(sd[fresh])])
            else:
                reason = "done"
        place = self.place_of(m.p, reason, m.entered)
        if self.dock:
            m.p = self._standing_points[place]
            target = self.place_positions[place] if place < self.n_objects else np.array(
                [self.width / 2, self.height / 2])
            m.heading = math.atan2(target[1] - m.p[1], target[0] - m.p[0])
        return Pose(
            float(m.p[0]), float(m.p[1]), float(m.heading), place, pose.place, reason,
            float(m.turned), float(m.path), int(m.entered) if reason == "reach" else -1,
        )

    # ------------------------------------------------------------------ simulation
    def step(self, pose: Pose, action: int, rng: np.random.Generator) -> Pose:
        """Execute action ``action`` (an index into :attr:`actions`) from ``pose``."""
        return self.actions[action].execute(self, pose, rng)

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
        if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 1:
            raise ValueError(f"n_steps must be a positive integer, got {n_steps!r}")
        if not callable(getattr(explorer, "choose", None)):
            raise ValueError("explorer must have a choose(executable_mask, rng) method")
        T = int(n_steps)
        obs = np.zeros((T, self.n_types))
        actions = np.zeros(T, dtype=np.int64)
        gds = np.full(T, -1, dtype=np.int64)
        places = np.zeros(T, dtype=np.int64)
        positions = np.zeros((T, 2))
        headings, reasons, turns = [], [], []
        pose = self.random_start(rng)
        for t in range(T):
            obs[t] = self.observe(pose)
            places[t] = pose.place
            positions[t] = (pose.x, pose.y)
            gds[t] = self.gds_of(pose)
            headings.append(float(pose.heading))
            mask = self.executable_mask(pose)
            a = explorer.choose(mask, rng)
            if isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 0 <= a < self.n_actions or not mask[a]:
                raise ValueError(f"explorer chose action {a!r}, which is not executable at step {t}")
            actions[t] = int(a)
            if t + 1 < T:
                pose = self.step(pose, int(a), rng)
                reasons.append(pose.end_reason)
                turns.append(float(pose.turned_deg))
        meta = {
            "world": "office",
            "layout": self.layout_name,
            "seed": self.seed,
            "place_names": list(self.place_names),
            "type_names": list(self.type_names),
            "gds_places": [int(g) for g in self.gds_places],
            "reach": self.reach,
            "max_turn_deg": self.max_turn_deg,
            "headings": headings,
            "end_reasons": reasons,
            "turns_deg": turns,
        }
        return Trajectory(
            observations=obs, actions=actions, gds=gds, places=places, positions=positions,
            action_names=list(self.action_names), gds_names=list(self.gds_names), meta=meta,
        )

    # ------------------------------------------------------------------ figures
    def plot_room(self, ax, labels: bool = True, show_corners: bool = True):
        """Draw the room on a matplotlib Axes: walls, objects coloured by type, GDS dashed circles.

        Returns ``ax``.
        """
        import matplotlib.pyplot as plt
        from matplotlib.patches import Circle, Rectangle

        ax.add_patch(Rectangle((0, 0), self.width, self.height, fill=False, lw=2.5, ec="black"))
        cmap = plt.get_cmap("tab20", max(self.n_types, 1))
        for i in range(self.n_objects):
            t = int(self.object_types[i])
            c, r = self.object_positions[i], self.object_radii[i]
            ax.add_patch(Circle(c, r, fc=cmap(t), ec="black", lw=0.8))
            if labels:
                ax.annotate(self.place_names[i].split(" (")[0], c, xytext=(0, r * 12 + 6),
                            textcoords="offset points", ha="center", fontsize=6)
        for k, i in enumerate(self.gds_places):
            c, r = self.object_positions[i], self.object_radii[i]
            ax.add_patch(Circle(c, r + self.reach, fill=False, ls="--", lw=1.2, ec="red"))
            ax.annotate(self.gds_names[k], c + np.array([0, -(r + self.reach) - 0.5]), ha="center",
                        fontsize=7, color="red")
        if show_corners:
            ax.plot(self._corners[:, 0], self._corners[:, 1], "k+", ms=6)
        ax.set_xlim(-0.5, self.width + 0.5)
        ax.set_ylim(-0.5, self.height + 0.5)
        ax.set_aspect("equal")
        return ax


class _Motion:
    """Mutable state of one action while :meth:`OfficeWorld.drive` runs it."""

    def __init__(self, world: OfficeWorld, pose: Pose):
        self.w = world
        self.p = pose.xy
        self.heading = pose.heading
        self.turned = 0.0
        self.path = 0.0
        self.entered = -1
        self.armed = world.surface_distances(self.p) > world.reach + _TOL
        self.cap = world.max_action_steps * world.step_size
        self.R_reach = world.object_radii + world.reach
        self.R_body = world.object_radii + world.robot_clearance

    def _first_entry(self, p, u, mask, R, inward_only: bool):
        """Smallest ``s >= 0`` where ``p + s u`` enters a circle (centre, ``R``) among ``mask``."""
        if not mask.any():
            return math.inf, -1
        f = p - self.w.object_positions
        b = f @ u
        cc = np.einsum("ij,ij->i", f, f) - R**2
        disc = b * b - cc
        s = np.full(b.shape, np.inf)
        hit = mask & (disc >= 0) & (b < 0)
        s[hit] = -b[hit] - np.sqrt(disc[hit])
        if inward_only:  # already on/inside the boundary and moving inwards: blocked at once
            s[mask & (cc <= 1e-12) & (b < -1e-12)] = 0.0
        s = np.where(s < 0, 0.0, s)
        j = int(np.argmin(s))
        return float(s[j]), j

    def run_leg(self, leg) -> str | None:
        """Drive one leg; return a stop reason, or None when the leg is finished."""
        while True:
            u, rem = leg.guide(self.p)
            if rem <= 1e-9:
                return None
            if self.path >= self.cap - 1e-12:
                return "cap"
            ell = min(rem, self.cap - self.path)
            s_e, j_e = self._first_entry(self.p, u, self.armed, self.R_reach, False)
            s_h, j_h = self._first_entry(self.p, u, ~self.armed, self.R_body, True)
            s = min(ell, s_e, s_h)
            if s > 0:
                self.p = self.p + s * u
                self.path += s
                self.heading = math.atan2(u[1], u[0])
            if s_e <= s + 1e-9:
                self.entered = j_e
                return "reach"
            if s_h <= s and s_h < ell:
                reason = self._slide(leg, j_h, u)
                if reason is not None:
                    return reason

    def _slide(self, leg, j: int, u) -> str | None:
        """Slide around object ``j`` until the leg's direction points away from it."""
        w = self.w
        c, Rb = w.object_positions[j], self.R_body[j]
        n = (self.p - c) / max(np.linalg.norm(self.p - c), 1e-12)
        tangent = np.array([-n[1], n[0]])
        dot = float(tangent @ u)
        if abs(dot) < 1e-9:
            hint = getattr(leg, "hint", None)
            sign = 1.0 if hint is None or float(tangent @ hint) >= 0 else -1.0
        else:
            sign = 1.0 if dot > 0 else -1.0
        dphi = sign * w.step_size / Rb
        others = np.ones(w.n_objects, dtype=bool)
        others[j] = False
        while True:
            u, rem = leg.guide(self.p)
            if rem <= 1e-9:
                return None
            v = self.p - c
            n = v / max(np.linalg.norm(v), 1e-12)
            if float(u @ n) >= -1e-12:
                return None
            if self.path >= self.cap - 1e-12:
                return "cap"
            ang = math.atan2(v[1], v[0]) + dphi
            q = c + Rb * np.array([math.cos(ang), math.sin(ang)])
            seg = q - self.p
            L = float(np.linalg.norm(seg))
            su = seg / L
            s_e, j_e = self._first_entry(self.p, su, self.armed, self.R_reach, False)
            if s_e <= L:
                self.p = self.p + s_e * su
                self.path += s_e
                self.heading = math.atan2(su[1], su[0])
                self.entered = j_e
                return "reach"
            m = w.robot_clearance
            if not (m <= q[0] <= w.width - m and m <= q[1] <= w.height - m):
                return "blocked"
            if np.any((w.surface_distances(q) < w.robot_clearance - 1e-9) & others & ~self.armed):
                return "blocked"
            self.p = q
            self.path += L
            self.heading = math.atan2(su[1], su[0])
