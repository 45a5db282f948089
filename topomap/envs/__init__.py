"""Simulated environments that produce :class:`~topomap.trajectory.Trajectory` data."""

from .gridroom import GridRoom
from .minigrid_env import MiniGridWorld
from .office import (
    Action,
    ApproachType,
    FollowWall,
    GoTo,
    GoToWall,
    OfficeLayout,
    OfficeWorld,
    Pose,
    paper_layout,
    random_layout,
)
from .random_graph import RandomGraphWorld

__all__ = [
    "Action",
    "ApproachType",
    "FollowWall",
    "GoTo",
    "GoToWall",
    "GridRoom",
    "MiniGridWorld",
    "OfficeLayout",
    "OfficeWorld",
    "Pose",
    "RandomGraphWorld",
    "paper_layout",
    "random_layout",
]
