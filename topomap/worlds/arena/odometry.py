"""A robot's own dead reckoning in the arena: wheel odometry integrated from the true moves with
the errors of wheel encoders and a gyro.

An odometry component has plain typed parameters and one method, ``dead_reckoning(motion, rng)
-> (T, 3)``: x and y (metres) and heading (radians) where the robot believes it is at the start
of each step, in its own odometry frame (its start pose: ``(0, 0, 0)``), given the path's
:class:`~topomap.worlds.arena.kinematics.Motion`.  The world fills
:attr:`Trajectory.odometry <topomap.Trajectory>` with it; it drifts, so it is input to
learning and never the score (``positions`` stays the truth).

:class:`WheelOdometry` integrates each step's driven distance and turn (the heading of step
``t + 1`` is the direction of move ``t``, as :class:`Motion` has it) with:

* a calibration error, drawn once per walk uniformly within ``+-speed_noise`` (distance) and
  ``+-turn_noise`` (turn), and a per-step error ``speed_noise * e`` / ``turn_noise * e``
  (``e`` standard normal), both multiplying the step's distance and turn;
* a constant gyro bias added to every turn, ``gyro_bias`` rad/s at most (magnitude drawn once
  per walk in ``[gyro_bias / 2, gyro_bias]``, either sign);
* wheel slips, ``slip_rate`` per second (a Bernoulli draw per step), each adding up to
  ``slip_size`` metres to the distance and ``+-slip_size`` radians to the turn.

Without errors (every parameter 0) the odometry is the true path seen from the robot's start
pose.  The same model simulates the robots of the research benchmarks.
"""

from __future__ import annotations

import numpy as np

from .checks import non_negative

__all__ = ["WheelOdometry", "ODOMETRY_STREAM"]

#: the stream of a walk's seed the odometry's errors are drawn from (the walk's motion has its
#: own), so a world with and without odometry walks the same path
ODOMETRY_STREAM = 2


def _wrap(angles: np.ndarray) -> np.ndarray:
    return (np.asarray(angles) + np.pi) % (2 * np.pi) - np.pi


class WheelOdometry:
    """Wheel odometry with encoder noise, a gyro bias and slips (see the module docstring).

    Parameters
    ----------
    speed_noise : float
        Relative error of each step's distance (a share: 0.02 is 2 %), per step (the standard
        deviation) and per walk (the largest calibration error).
    turn_noise : float
        Relative error of each step's turn (a share), per step and per walk likewise.
    gyro_bias : float
        rad/s: the largest constant bias added to the turning rate.
    slip_rate : float
        Slips per second.
    slip_size : float
        Metres (and radians) a slip adds at most to a step's distance (and turn).
    """

    def __init__(self, speed_noise: float = 0.02, turn_noise: float = 0.05,
                 gyro_bias: float = 0.01, slip_rate: float = 0.01, slip_size: float = 0.1):
        self.speed_noise = non_negative("speed_noise", speed_noise)
        self.turn_noise = non_negative("turn_noise", turn_noise)
        self.gyro_bias = non_negative("gyro_bias", gyro_bias)
        self.slip_rate = non_negative("slip_rate", slip_rate)
        self.slip_size = non_negative("slip_size", slip_size)

    def dead_reckoning(self, motion, rng: np.random.Generator) -> np.ndarray:
        """``(T, 3)`` x, y (metres), heading (radians) at the start of each of the ``T`` steps of
        ``motion``, from ``(0, 0, 0)``, with errors drawn from ``rng``."""
        dt, moves = motion.dt, len(motion) - 1
        distance = motion.speed[:moves] * dt
        turn = motion.rotational_velocity[:moves] * dt
        c_v, c_w = rng.uniform(-1, 1, 2) * (self.speed_noise, self.turn_noise)
        bias = rng.choice([-1, 1]) * rng.uniform(0.5, 1.0) * self.gyro_bias
        d_hat = distance * (1 + c_v + self.speed_noise * rng.standard_normal(moves))
        turn_hat = turn * (1 + c_w + self.turn_noise * rng.standard_normal(moves)) + bias * dt
        slip = rng.random(moves) < self.slip_rate * dt
        d_hat[slip] += rng.uniform(0, self.slip_size, slip.sum())
        turn_hat[slip] += rng.uniform(-self.slip_size, self.slip_size, slip.sum())
        theta = np.concatenate([[0.0], np.cumsum(turn_hat)])
        xy = np.zeros((moves + 1, 2))
        xy[1:] = np.cumsum(d_hat[:, None] * np.column_stack([np.cos(theta[1:]),
                                                             np.sin(theta[1:])]), axis=0)
        return np.column_stack([xy, _wrap(theta)])

    def __repr__(self) -> str:
        return (f"WheelOdometry(speed_noise={self.speed_noise:g}, turn_noise={self.turn_noise:g}, "
                f"gyro_bias={self.gyro_bias:g}, slip_rate={self.slip_rate:g}, "
                f"slip_size={self.slip_size:g})")
