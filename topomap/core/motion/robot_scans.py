"""The robot route on a robot's log WITHOUT odometry: its odometry read from its scans
(``MotionSettings(scan_odometry=True)``; off by default, docs/robot-logs.md).

A log of egocentric range scans and turn commands given no odometry is recognised as today
(:func:`is_scan_log`: the continuous path learned no odometry from its commands -- they move a
robot differently with its heading -- one episode, no GDS, a ring of beams a row; a compass
walker's commands do give odometry and are never caught).  Its odometry is then read from the
scans (:func:`~.registration.scan_odometry`, point-to-line ICP against keyframes) and closed by
loops (:func:`~.registration.scan_poses`; its headings, closed already, are not solved again),
and the robot route (:func:`~.robot_fit.fit_robot`) learns on those poses behind the guards of a
log with odometry (point symmetry -- a cell's reflection matched within
:data:`~.symmetry.SCAN_REACH` spacings, as this odometry's maps bend by centimetres --, unwalked
floor, the held-out check, whose held-out steps are placed by their unclosed registration, as a
new walk would be).  Where a guard fails the map is the view clusters the log got before, with the
warning and the reason.  ``predict`` without odometry places a new walk by its own registration
(:func:`walk_odometry`).

Measured (``benchmarks/notes/robots.md``, 2026-12-03; 12 walks of four 1 m plans and the three
of ``robot_office@0.3333``): never above K-means on the views (the guards send 10 walks of 15
back), 0.10-0.21x its error on the 5 where the route is taken; the fit 4.5x as long as
without the setting (14.7 s of CPU for 18,000 steps); it is off by default.
"""

from __future__ import annotations

import time

import numpy as np

from .registration import scan_odometry, scan_poses
from .robot_fit import MIN_BEAMS, fit_robot

__all__ = ["is_scan_log", "fit_scan_robot", "walk_odometry", "SOURCE"]

#: ``motion_info_["odometry_from"]`` of a map whose odometry was read from its scans
SOURCE = "scans"


def is_scan_log(data, odometry, info: dict) -> bool:
    """Whether a continuous log is a robot's log of range scans and turn commands without
    odometry: none given, one episode, no GDS, :data:`~.robot_fit.MIN_BEAMS` beams or more a
    row, non-negative readings, and no odometry learned from its actions by the continuous path
    (``info["odometry"]`` False)."""
    return (odometry is None and info.get("odometry") is False and len(data.lengths) == 1
            and not np.any(data.gds >= 0) and data.X.shape[1] >= MIN_BEAMS
            and bool(np.all(data.X >= 0)))


def fit_scan_robot(learner, data, settings, fallback, start: float | None = None) -> bool:
    """:func:`~.robot_fit.fit_robot` with ``mode="auto"``'s guards on the log's odometry read
    from its scans (closed by loops; the held-out check places by the unclosed registration);
    ``fallback`` as there; ``motion_info_["odometry_from"]`` is :data:`SOURCE` (the seconds
    go to ``timings_["places"]``, as the route's)."""
    start = time.perf_counter() if start is None else start
    alternatives: list = []
    raw = scan_odometry(data.X, alternatives=alternatives)
    poses = scan_poses(data.X, odometry=raw, alternatives=alternatives)
    views, info, build = fallback
    return fit_robot(learner, data, settings, poses, (views, {**info, "odometry_from": SOURCE},
                                                      build), start=start, place_odometry=raw,
                     headings=poses[:, 2])


def walk_odometry(X, lengths) -> np.ndarray:
    """(T, 3) odometry of a new walk's scans ``X`` (T, B), each episode of ``lengths`` read from
    its own scans (:func:`~.registration.scan_odometry`)."""
    ends = np.cumsum(lengths)
    return np.concatenate([scan_odometry(X[a:b]) for a, b in zip(ends - lengths, ends)])
