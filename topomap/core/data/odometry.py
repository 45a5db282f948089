"""The robot's own odometry of a trajectory's steps: checked once, its CSV columns, and the
heading of a quaternion.

Odometry is where the robot believes it is by dead reckoning (wheel encoders, a gyro, scan
matching): a ``(T, 3)`` float64 array, one row per step, holding ``x`` and ``y`` in metres and the
heading in radians (anticlockwise from the odometry frame's ``x`` axis), every value finite.  It
drifts, so it is input to learning and never the score; scores use ``positions``, the ground
truth (a motion capture's, a simulator's).
"""

from __future__ import annotations

import math

import numpy as np

from .positions import per_step_rows

__all__ = ["check_odometry", "csv_odometry", "ODOMETRY_COLUMNS", "MAX_ODOMETRY_STEP",
           "yaw_of_quaternion", "quaternion_of_yaw"]

#: the CSV columns of the odometry, in order: x and y in metres, the heading in radians
ODOMETRY_COLUMNS = ("odom_x", "odom_y", "odom_theta")

#: metres: the odometry may move at most this far between two steps of an episode.  A longer step
#: is a glitch (the odometry reset to its origin, a restarted driver), not motion: the fastest of
#: the shipped recorded paths (tanni, a running rat) moves at most 0.20 m per step at 10 Hz and
#: 1.07 m per step at 1 Hz, and 2 m leaves twice that.  An odometry that was reset on purpose
#: starts a new episode there (``lengths``).
MAX_ODOMETRY_STEP = 2.0


def _jump(odometry: np.ndarray, lengths) -> tuple[int, float] | None:
    """``(t, metres)`` of the first move from step ``t - 1`` to ``t`` of one episode longer than
    :data:`MAX_ODOMETRY_STEP`, or None."""
    step = np.hypot(*np.diff(odometry[:, :2], axis=0).T)
    if lengths is not None:  # no step is taken across an episode boundary
        starts = np.cumsum(np.asarray(lengths))[:-1]
        step[starts - 1] = 0.0
    far = np.flatnonzero(step > MAX_ODOMETRY_STEP)
    return None if far.size == 0 else (int(far[0]) + 1, float(step[far[0]]))


def check_odometry(values, n_steps: int, lengths=None) -> np.ndarray:
    """``values`` as a ``(n_steps, 3)`` float64 array (x, y in metres, heading in radians), or a
    one-line ValueError naming ``odometry`` and the step: the wrong shape, NaN or inf, or a move of
    more than :data:`MAX_ODOMETRY_STEP` metres between two steps of an episode (``lengths``: the
    episode lengths, None for one episode)."""
    odo = per_step_rows(values, "odometry", n_steps, (3,), "(T, 3)",
                        f"({n_steps}, 3): x and y in metres and the heading in radians; got")
    jump = _jump(odo, lengths)
    if jump is not None:
        t, metres = jump
        raise ValueError(
            f"odometry moves {metres:.3g} m from step {t - 1} to step {t}, more than "
            f"MAX_ODOMETRY_STEP = {MAX_ODOMETRY_STEP:g} m in one step (a reset or a glitch of the "
            f"robot's odometry?); if it was reset there, start a new episode at step {t}")
    return odo


def csv_odometry(header: list, columns: dict, path) -> np.ndarray | None:
    """The odometry held in a CSV's ``odom_x``, ``odom_y``, ``odom_theta`` columns, or None
    without them; some but not all three is a ValueError naming the file."""
    present = [c for c in ODOMETRY_COLUMNS if c in header]
    if not present:
        return None
    if len(present) != len(ODOMETRY_COLUMNS):
        missing = [c for c in ODOMETRY_COLUMNS if c not in present]
        raise ValueError(f"trajectory file {path} has the odometry column(s) {', '.join(present)} "
                         f"but not {', '.join(missing)}; odometry needs all of "
                         f"{', '.join(ODOMETRY_COLUMNS)}")
    return np.column_stack([columns[c] for c in ODOMETRY_COLUMNS])


def yaw_of_quaternion(x: float, y: float, z: float, w: float) -> float:
    """The heading (radians, in ``(-pi, pi]``, anticlockwise about ``z``) of the orientation
    ``(x, y, z, w)``: the rotation about the vertical axis (REP 103), whatever its norm; the zero
    quaternion, which is no orientation, is a ValueError."""
    if x == 0 and y == 0 and z == 0 and w == 0:
        raise ValueError("orientation is the zero quaternion (0, 0, 0, 0), which is no rotation")
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def quaternion_of_yaw(yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` radians about ``z``."""
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)
