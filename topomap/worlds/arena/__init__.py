"""The arena: continuous motion in a floor plan, built on ratinabox (``pip install "topomap[arena]"``).

A robot's log, and a rat's path, are continuous motion sampled at the sensor's rate.  The arena
simulates that with ratinabox (George et al. 2024, eLife, doi 10.7554/eLife.85274): its
``Environment`` holds the floor plan, its ``Agent`` moves at random the way rats do, and its two
recorded rat paths (Sargolini et al. 2006; Tanni et al. 2022) can be replayed.  The package
imports without ratinabox (its components and their configs are known); building a world, or
reading a rat's path, without it is a one-line
:class:`~topomap.worlds.minigrid.MissingDependencyError` saying how to install it.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``layouts``         floor plans: :class:`Layout`, the built-in layouts and their regions
``floorplan``       a user's floor plan from a YAML or JSON file, checked entry by entry
``walkable``        whether a floor plan can be walked: one floor, passages a walker fits through
``geometry``        rays against walls, points against polygons, whole paths at once (numpy)
``kinematics``      :class:`Motion` (the moves a path's samples make), ratinabox's random motion
``paths``           recorded paths (ratinabox's rats, the user's files), resampled every ``dt``
``sensors``         range finder; boundary-vector, object-vector, place and grid cells
``actions``         discrete actions read off the motion: compass octants, differential-drive turns
``odometry``        the robot's wheel odometry: dead reckoning with encoder noise, gyro bias, slips
``world``           :class:`ArenaWorld`: the world that ties them together
``plot``            the floor plan drawn on a matplotlib Axes
``checks``          argument checks the components share; ratinabox asked for
==================  ===========================================================================
"""

from ..minigrid import MissingDependencyError
from .actions import ACTION_RULES, CompassActions, TurnActions
from .floorplan import floorplan_from_dict, load_floorplan
from .layouts import LAYOUTS, Layout, builtin_layout
from .kinematics import Motion
from .odometry import WheelOdometry
from .paths import DATASETS, RecordedPath
from .sensors import (SENSORS, BoundaryVectorCells, GridCells, ObjectVectorCells, PlaceCells,
                      RangeFinder)
from .world import Arena, ArenaWorld

__all__ = ["ArenaWorld", "Arena", "Layout", "LAYOUTS", "builtin_layout", "load_floorplan",
           "floorplan_from_dict", "Motion", "RecordedPath", "DATASETS", "RangeFinder",
           "BoundaryVectorCells", "ObjectVectorCells", "PlaceCells", "GridCells", "SENSORS", "CompassActions",
           "TurnActions", "ACTION_RULES", "WheelOdometry", "MissingDependencyError"]
