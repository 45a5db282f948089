"""Dead reckoning for the robot route (:mod:`topomap.core.motion.robot`): poses from moves along
headings, poses of a log without odometry, and keyframes.

A move is ``(forward [m], left [m], turn [rad])`` in the frame of the step before
(:func:`~topomap.core.motion.inputs.odometry_moves`); a pose is ``(x [m], y [m], heading
[rad])``.  The robot route replaces the wheel odometry's own heading, which drifts by
~0.6 rad a minute, by the heading of :func:`~topomap.core.motion.scans.scan_headings` and keeps
the odometry's travel (:func:`reckon`), and it places a walk one keyframe at a time
(:func:`keyframes`): steps of a few centimetres each carry too little of a move for a cell
spacing of 0.1-0.2 m.
"""

from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from . import scans as S
from .inputs import odometry_moves

__all__ = ["forward_moves", "reckon", "command_poses", "keyframes", "compose", "relative_pose",
           "KEYFRAME_MAX_STEPS", "STOP"]

#: steps: a keyframe at least this often, so a robot standing still or turning on the spot is
#: still placed every 5 s at 10 Hz (the research route's value; not tuned)
KEYFRAME_MAX_STEPS = 50
#: the ``stop`` command's action id in turn / forward / stop logs (the arena's ``actions=turns``
#: and ``data=rosbag``: forward, turn_left, turn_right, stop)
STOP = 3


def forward_moves(poses) -> np.ndarray:
    """(T, 3) the move into every step of one walk's ``poses`` (T, 3) in the frame of the step
    before (0 at the first step)."""
    poses = np.asarray(poses, dtype=np.float64)
    return odometry_moves(poses, [len(poses)])


def reckon(moves, heading) -> np.ndarray:
    """(T, 3) poses from ``(0, 0)``: each step's ``moves`` (forward, left; T, 2 or more) taken
    along ``heading`` (T,) of the step before; the heading column is ``heading`` itself."""
    moves, heading = np.asarray(moves, dtype=np.float64), np.asarray(heading, dtype=np.float64)
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    dx = c * moves[1:, 0] - s * moves[1:, 1]
    dy = s * moves[1:, 0] + c * moves[1:, 1]
    xy = np.vstack([[0.0, 0.0], np.column_stack([np.cumsum(dx), np.cumsum(dy)])])
    return np.column_stack([xy, heading])


def command_poses(X, u, stop: int = STOP) -> np.ndarray:
    """(T, 3) poses of a log without odometry: one unit forward a step unless the command is
    ``stop``, the headings summed from the scans' turns (:func:`~.scans.scan_turns`).  The unit
    is one step's travel, unknown: such poses compare only with poses of the same robot."""
    Xd = S.despike(X)
    turns = np.r_[0.0, S.scan_turns(Xd[:-1], Xd[1:])]
    moves = np.column_stack([(np.asarray(u) != stop).astype(float), np.zeros(len(u))])
    return reckon(moves, np.cumsum(turns))


def keyframes(poses, delta: float, max_steps: int = KEYFRAME_MAX_STEPS) -> np.ndarray:
    """Indices of one walk's keyframes: step 0, then a new one after every ``delta`` [m] of
    travel along ``poses`` (T, 3) or every ``max_steps`` steps, whichever comes first."""
    poses = np.asarray(poses, dtype=np.float64)
    step = np.r_[0.0, np.hypot(*np.diff(poses[:, :2], axis=0).T)]
    ks, acc = [0], 0.0
    for t in range(1, len(poses)):
        acc += step[t]
        if acc >= delta or t - ks[-1] >= max_steps:
            ks.append(t)
            acc = 0.0
    return np.array(ks, dtype=np.int64)


@register_jitable
def compose(a, b) -> np.ndarray:
    """The pose ``b`` (x, y, heading), given in the frame of pose ``a``, in ``a``'s frame's."""
    c, s = np.cos(a[2]), np.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


@register_jitable
def relative_pose(a, b) -> np.ndarray:
    """Pose ``b`` in the frame of pose ``a``."""
    c, s, dx, dy = np.cos(a[2]), np.sin(a[2]), b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]])
