"""The robot's own odometry as input: checked, and turned into moves in the robot's frame.

Odometry is the robot's dead reckoning, ``(T, 3)``: x [m], y [m] and heading [rad] of every
step in the robot's own frame (a ROS ``/odom``).  It drifts -- with a few per cent of speed and
turn-rate noise and a gyro bias of 0.01 rad/s the heading is off by ~0.6 rad after a minute and
the position by metres after half an hour -- but over a few seconds it is good to centimetres:
the learner takes it as the moves between steps, never as positions to score against.
"""

from __future__ import annotations

import numpy as np

from ..checks import ParameterError
from ..data.odometry import MAX_ODOMETRY_STEP
from ..data.odometry import check_odometry as checked_odometry

__all__ = ["MAX_ODOMETRY_STEP", "check_odometry", "odometry_moves"]

def check_odometry(odometry, n_steps: int, lengths=None) -> np.ndarray | None:
    """``odometry`` as a (T, 3) float64 array (None stays None), checked by
    :func:`topomap.core.data.odometry.check_odometry` (the same checks as a trajectory's): a
    :class:`ParameterError` naming ``odometry`` and the step when it is not ``(n_steps, 3)``, not
    finite, or jumps more than :data:`MAX_ODOMETRY_STEP` metres between two steps of one episode
    (``lengths``: the episode lengths, None for one episode)."""
    if odometry is None:
        return None
    try:
        return checked_odometry(odometry, n_steps, lengths)
    except ValueError as err:
        raise ParameterError("odometry", str(err).removeprefix("odometry").strip()) from None


def odometry_moves(odometry, lengths) -> np.ndarray:
    """(T, 3) the move into every step in the frame of the step before it: forward [m], left [m]
    and turn [rad] (0 at the first step of an episode), so that moves do not depend on the
    frame the odometry was started in."""
    O = np.asarray(odometry, dtype=np.float64)
    d = np.zeros_like(O)
    dx, dy = np.diff(O[:, 0]), np.diff(O[:, 1])
    c, s = np.cos(O[:-1, 2]), np.sin(O[:-1, 2])
    d[1:, 0] = c * dx + s * dy
    d[1:, 1] = -s * dx + c * dy
    d[1:, 2] = np.angle(np.exp(1j * np.diff(O[:, 2])))
    d[np.cumsum(lengths)[:-1]] = 0.0
    return d
