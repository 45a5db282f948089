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

__all__ = ["MAX_ODOMETRY_STEP", "check_odometry", "odometry_moves"]

#: metres: a step of dead reckoning longer than this is a jump (a reset of the odometry, a wrong
#: unit, a lost message), not motion -- no indoor robot drives 2 m between two steps of a log
#: recorded at 1 Hz or faster (a robot at 1 m/s moves 0.1 m a step at 10 Hz)
MAX_ODOMETRY_STEP = 2.0


def check_odometry(odometry, n_steps: int, lengths=None) -> np.ndarray | None:
    """``odometry`` as a (T, 3) float64 array (None stays None); a :class:`ParameterError` naming
    ``odometry`` and the step when it is not ``(n_steps, 3)``, not finite, or jumps more than
    :data:`MAX_ODOMETRY_STEP` metres between two steps of one episode (``lengths``: the episode
    lengths, None for one episode)."""
    if odometry is None:
        return None
    try:
        O = np.array(odometry, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("odometry", "must be a (T, 3) array of x [m], y [m], heading [rad] "
                                         f"numbers, got {type(odometry).__name__}") from None
    if O.ndim != 2 or O.shape != (n_steps, 3):
        raise ParameterError("odometry", f"must have shape ({n_steps}, 3) (x [m], y [m], heading "
                                          f"[rad] of each of the {n_steps} steps), got "
                                          f"{O.shape}")
    bad = np.flatnonzero(~np.isfinite(O).all(axis=1))
    if bad.size:
        raise ParameterError("odometry", f"step {int(bad[0])} is not finite: {O[bad[0]].tolist()}")
    step = np.hypot(*np.diff(O[:, :2], axis=0).T)
    if lengths is not None:
        step[np.cumsum(lengths)[:-1] - 1] = 0.0  # no move is read across episodes
    jump = np.flatnonzero(step > MAX_ODOMETRY_STEP)
    if jump.size:
        t = int(jump[0]) + 1
        raise ParameterError("odometry", f"jumps {step[t - 1]:.3g} m at step {t} (from step "
                                          f"{t - 1}): more than {MAX_ODOMETRY_STEP:g} m in one "
                                          "step is a reset or a wrong unit, not motion")
    return O


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
