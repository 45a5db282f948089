"""Simulated environments that produce :class:`~topomap.trajectory.Trajectory` data."""

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
