"""A turn the scans read either way: rivals settled by the loops and the room ahead."""

import numpy as np

from topomap.core.motion import registration as R
from topomap.core.motion import turn_rivals as TR
from topomap.core.motion.reckoning import compose

T = 120


def _walk_poses(turn_at=None, turn=np.pi):
    """(T, 3) poses of 1 cm steps turning 0.01 rad a step; ``turn`` more at step ``turn_at``."""
    poses = [np.zeros(3)]
    for t in range(1, T):
        extra = turn if t == turn_at else 0.0
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 0.01 + extra])))
    return np.array(poses)


def _closures(poses):
    """Three closures across step 50 (two forward, one backward) stating ``poses``' turns."""
    ci, cj = np.array([10, 30, 110]), np.array([60, 90, 20])
    return ci, cj, poses[cj, 2] - poses[ci, 2]


def test_clearance_ahead_is_the_nearest_range_within_sixty_degrees_of_the_heading():
    # 60 beams 6 degrees apart: beams 0-10 and 50-59 look ahead (beam 10 at exactly 60 degrees)
    X = np.full((3, 60), 2.0)
    X[0, 10], X[0, 11] = 0.5, 0.1    # beam 11 (66 degrees) is beside, not ahead
    X[1, 50], X[1, 30] = 0.3, 0.05   # beam 50 (-60 degrees) ahead, beam 30 behind
    X[2, 0] = 0.08
    np.testing.assert_allclose(TR.clearance_ahead(X), [0.5, 0.3, 0.08])
    # 12 beams 30 degrees apart: beams 0-2 and 10-11 ahead
    Y = np.full((1, 12), 1.0)
    Y[0, 3], Y[0, 10] = 0.2, 0.4
    np.testing.assert_allclose(TR.clearance_ahead(Y), [0.4])


def test_a_half_turn_rival_the_loops_vote_for_is_refused_with_no_wall_ahead():
    # the registration kept the true turn (0.01 rad) at step 50; its rival turns pi more, and
    # all three closures across step 50 side with the rival (a place matching its reflection):
    # the loops alone take it, but with nothing within REVERSAL_CLEARANCE_M ahead of step 49 a
    # robot cannot have turned about in one step, and the poses stay as they are
    truth, turned = _walk_poses(), _walk_poses(turn_at=50)
    votes = _closures(turned)
    np.testing.assert_allclose(R.resolve_turns(truth, [(50, turned[50])], votes), turned,
                               atol=1e-9)
    open_room = np.full(T, TR.REVERSAL_CLEARANCE_M + 0.01)
    kept = R.resolve_turns(truth, [(50, turned[50])], votes, ahead=open_room)
    np.testing.assert_allclose(kept, truth, atol=0)
    # a wall right ahead of step 49 (only there): the robot may have bounced, the loops decide
    wall = open_room.copy()
    wall[49] = TR.REVERSAL_CLEARANCE_M
    np.testing.assert_allclose(R.resolve_turns(truth, [(50, turned[50])], votes, ahead=wall),
                               turned, atol=1e-9)
    wall[49], wall[50] = open_room[49], 0.0   # the wall at the step itself does not count
    np.testing.assert_allclose(R.resolve_turns(truth, [(50, turned[50])], votes, ahead=wall),
                               truth, atol=0)


def test_a_rival_that_undoes_a_half_turn_is_still_taken_with_no_wall_ahead():
    # the registration kept a wrong half turn at step 50; its rival turns 0.01 rad from step 49
    # (no reversal) and the closures side with it: taken, the truth again, wall or none
    truth, turned = _walk_poses(), _walk_poses(turn_at=50)
    open_room = np.full(T, 1.0)
    fixed = R.resolve_turns(turned, [(50, truth[50])], _closures(truth), ahead=open_room)
    np.testing.assert_allclose(fixed, truth, atol=1e-9)
    # a rival turning a little more than a quarter turn counts as a reversal, a little less not
    for extra, taken in ((TR.TURN_CHECK - 0.02, True), (TR.TURN_CHECK + 0.02, False)):
        other = _walk_poses(turn_at=50, turn=extra)
        out = R.resolve_turns(truth, [(50, other[50])], _closures(other), ahead=open_room)
        np.testing.assert_allclose(out, other if taken else truth, atol=1e-9)



def _walk_turned(extra):
    """(T, 3) poses of :func:`_walk_poses`' steps with ``extra[t]`` rad more turned at step t."""
    poses = [np.zeros(3)]
    for t in range(1, T):
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 0.01 + extra.get(t, 0.0)])))
    return np.array(poses)


def test_a_second_rival_is_weighed_on_the_walk_the_first_one_moved():
    # the registration kept a wrong half turn at step 40 and another at step 80 (which undoes
    # the first's heading, not its path); each step's rival is the true move from the step
    # before, in the kept poses' frame.  Closures across step 40 alone and across step 80 alone
    # state the truth's turns: the first rival is taken, which turns the walk after it by half a
    # turn, so the second kept half turn now puts the walk half a turn off -- in that moved walk
    # its rival undoes a half turn, and taken the poses are the truth again
    truth = _walk_poses()
    kept = _walk_turned({40: np.pi, 80: np.pi})
    rivals = [(t, compose(kept[t - 1], np.array([0.01, 0.0, 0.01]))) for t in (40, 80)]
    ci, cj = np.array([10, 20, 35, 60, 70, 115]), np.array([60, 70, 75, 100, 115, 65])
    closures = (ci, cj, truth[cj, 2] - truth[ci, 2])
    np.testing.assert_allclose(R.resolve_turns(kept, rivals, closures), truth, atol=1e-9)
    # the first rival alone taken (no closure across step 80): the walk half a turn off after
    # step 80, as the kept half turn there says
    first = _walk_turned({80: np.pi})
    out = R.resolve_turns(kept, rivals, (ci[:3], cj[:3], closures[2][:3]))
    np.testing.assert_allclose(out, first, atol=1e-9)
