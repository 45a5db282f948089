"""The robot's pose, its actions, and the legs an action is made of.

An action is a sequence of *legs* (:class:`GoTo`, :class:`GoToWall` or any object with the same two
methods, ``heading(p)`` and ``guide(p)``) that :meth:`OfficeWorld.drive` runs; see
:mod:`topomap.worlds.office.driving` for how a leg is driven and when an action stops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .geometry import WALL_NORMALS

if TYPE_CHECKING:
    from .world import OfficeWorld

__all__ = ["Pose", "Action", "ApproachType", "FollowWall", "GoTo", "GoToWall"]


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
        self.normal = WALL_NORMALS[self.wall]
        self.hint = None if hint is None else np.asarray(hint, dtype=np.float64)

    def heading(self, p: np.ndarray) -> float:
        return math.atan2(self.normal[1], self.normal[0])

    def guide(self, p: np.ndarray) -> tuple[np.ndarray, float]:
        return self.normal, self.world.wall_distances(p)[self.wall] - self.offset
