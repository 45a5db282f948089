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

Modules
-------
``layout``   the rooms: :class:`OfficeLayout`, :func:`paper_layout`, :func:`random_layout`
``actions``  :class:`Pose`, the actions and the legs they are made of
``driving``  driving legs: reach zones, turns, sliding around obstacles
``sensing``  the panoramic camera: occlusion, apparent sizes, approach targets
``world``    :class:`OfficeWorld`: places, docking, simulation
``plot``     drawing the room
"""

from .actions import Action, ApproachType, FollowWall, GoTo, GoToWall, Pose
from .layout import OfficeLayout, paper_layout, random_layout
from .world import OfficeWorld

__all__ = ["Action", "ApproachType", "FollowWall", "GoTo", "GoToWall", "OfficeLayout",
           "OfficeWorld", "Pose", "paper_layout", "random_layout"]
