"""Turn commands read off the odometry given with a log (:mod:`topomap.core.motion.commands`),
which sends a robot's log with odometry to the robot route, and the decoder's reach
(:func:`topomap.core.motion.robot.successors`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from topomap.core.motion.commands import MIN_TURN_SHARE, turn_share
from topomap.core.motion.robot import successors
from topomap.core.motion.robot_fit import is_robot_log


def _odometry(turns, step=0.1):
    """(T + 1, 3) poses from per-step ``turns`` [rad], ``step`` m forward along each heading."""
    heading = np.r_[0.0, np.cumsum(turns)]
    xy = np.vstack([[0, 0], np.cumsum(step * np.column_stack([np.cos(heading[1:]),
                                                               np.sin(heading[1:])]), 0)])
    return np.column_stack([xy, np.angle(np.exp(1j * heading))])


# forward 0, turn_left 1, turn_right 2, stop 3; each turns as it says
TURNS = {0: 0.0, 1: 0.2, 2: -0.2, 3: 0.0}


def test_turn_commands_explain_all_their_turns():
    """Each step turns by its command's own amount (+0.2 left, -0.2 right, 0 else): the commands
    explain every turn, share 1 -- with a gyro bias added to every step (a shift of every
    command's mean alike) and with headings wrapping past pi (40 left turns: 8 rad)."""
    u = np.array([1] * 40 + [0, 2, 3, 0] * 10)
    for bias in (0.0, 0.01):
        O = _odometry(np.array([TURNS[a] for a in u[:-1]]) + bias)
        assert turn_share(O, u) == pytest.approx(1.0)


def test_compass_commands_explain_none_of_their_turns():
    """Commands east 0 and north 1 in pairs (0, 0, 1, 1, ...) while the walker turns +0.1, -0.1
    in turn: each command's steps turn +0.1 and -0.1 alike, mean 0 -- recorded with the step
    after (``u[t]``) or the step before (``u[t + 1]``): share 0."""
    u = np.r_[np.tile([0, 0, 1, 1], 25), 0]
    O = _odometry(np.tile([0.1, -0.1], 50))
    assert turn_share(O, u) == pytest.approx(0.0, abs=1e-12)
    assert turn_share(_odometry(np.zeros(9)), np.zeros(10, dtype=int)) == 0.0  # never turns


def _log(u, B=12, T=None):
    T = len(u)
    return SimpleNamespace(X=np.ones((T, B)), u=np.asarray(u), lengths=np.array([T]),
                           gds=np.full(T, -1))


def test_a_log_with_odometry_that_turns_on_command_is_a_robots():
    u = np.array([1] * 40 + [0, 2, 3, 0] * 10)
    O = _odometry(np.array([TURNS[a] for a in u[:-1]]))
    assert MIN_TURN_SHARE < 1 and is_robot_log(_log(u), O)
    assert not is_robot_log(_log(u), None)  # no odometry
    assert not is_robot_log(_log(u, B=2), O)  # two beams are no ring
    compass = np.r_[np.tile([0, 0, 1, 1], 25), 0]
    O2 = _odometry(np.tile([0.1, -0.1], 50))
    assert not is_robot_log(_log(compass), O2)
    # the continuous path's verdict, where given: no odometry learned from the actions
    assert is_robot_log(_log(compass), O2, {"odometry": False})
    assert not is_robot_log(_log(u), O, {"odometry": True})


def test_successors_reach_neighbouring_cells_never_walked_between():
    """Cells at x = 0, 1 and 3, the walk only ever in cell 2 (itself): no walked successors.
    A reach of 1.5 links 0 and 1 (1 apart), not 1 and 2 (2 apart)."""
    centres = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]])
    ptr, idx = successors(np.array([2, 2]), 3)
    assert ptr.tolist() == [0, 1, 2, 3] and idx.tolist() == [0, 1, 2]
    ptr, idx = successors(np.array([2, 2]), 3, centres, 1.5)
    assert ptr.tolist() == [0, 2, 4, 5] and idx.tolist() == [0, 1, 0, 1, 2]
