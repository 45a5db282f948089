"""The order of a robot's beams read from its log (topomap.core.motion.beams)."""

import numpy as np
import pytest

from topomap.core.motion.beams import beam_order, described, in_route_frame

B = 36
ROOM = (4.0, 3.0)


def _box_scans(poses):
    """(T, B) ranges [m] from each pose (x, y, heading) to the walls of a ROOM-sized box, beam k
    at ``2 pi k / B`` anticlockwise from the heading (the route's numbering)."""
    x, y, h = (poses[:, i:i + 1] for i in range(3))
    a = h + 2 * np.pi * np.arange(B) / B
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 1e-12, (ROOM[0] - x) / c, np.where(c < -1e-12, -x / c, np.inf))
        ty = np.where(s > 1e-12, (ROOM[1] - y) / s, np.where(s < -1e-12, -y / s, np.inf))
    return np.minimum(tx, ty)


def _walk(T=1500, seed=0):
    """Poses of a robot in the box: straight drives of 0.02 m a step and turns of 0.1 rad a
    step, kept 0.5 m off the walls (it turns where a step would take it nearer)."""
    rng = np.random.default_rng(seed)
    P = np.empty((T, 3))
    P[0] = (2.0, 1.5, 0.3)
    turning = 0
    for t in range(1, T):
        x, y, h = P[t - 1]
        ahead = (x + 0.02 * np.cos(h), y + 0.02 * np.sin(h))
        near = not (0.5 < ahead[0] < ROOM[0] - 0.5 and 0.5 < ahead[1] < ROOM[1] - 0.5)
        if turning or near or rng.random() < 0.02:
            turning = turning - 1 if turning else int(rng.integers(5, 20))
            P[t] = (x, y, h + 0.1)
        else:
            P[t] = (*ahead, h)
    return P


@pytest.mark.parametrize("reverse", [False, True])
@pytest.mark.parametrize("shift", [0, 1, 9, B // 2, B - 5])
def test_the_beams_are_put_back_in_the_route_s_order(reverse, shift):
    # scans numbered clockwise and/or from another beam: the order found brings back the
    # route's numbering exactly (a permutation of columns), and None where it is so already
    P = _walk()
    X = _box_scans(P)
    cols = np.arange(B)[::-1] if reverse else np.arange(B)
    cols = np.roll(cols, shift)
    given = X[:, cols]
    order = beam_order(given, P)
    if not reverse and shift == 0:
        assert order is None and in_route_frame(given, order) is given
        return
    assert np.array_equal(in_route_frame(given, order), X)
    # the column that looks ahead is where beam 0 went
    assert described(order) == {"ahead": int(np.flatnonzero(cols == 0)[0]),
                                "clockwise": reverse}


def test_a_log_that_never_drives_or_turns_keeps_its_beams():
    # no turn and no drive: nothing tells the direction or the front, the scans stay as they are
    P = np.tile([2.0, 1.5, 0.3], (50, 1))
    assert beam_order(_box_scans(P)[:, ::-1], P) is None


def test_a_robot_with_reversed_beams_is_mapped_as_with_the_route_s_order(tmp_path):
    """The same arena robot with its beams reversed and starting behind it: the route finds the
    order, records it, learns on the scans put back in order and places a new walk the same way
    (the map file keeps the order)."""
    pytest.importorskip("ratinabox")
    from test_motion_robot import _arena_robot
    from topomap import MapLearner
    from topomap.core.motion.robot_io import load_robot_map, save_robot_map
    from topomap.core.motion.robot import place_walk

    _, walk, held = _arena_robot(3000, 300)
    cols = np.roll(np.arange(60)[::-1], 30)
    learner = MapLearner(8, 16, motion="robot", random_state=0).fit(
        walk.observations[:, cols], walk.actions, odometry=walk.odometry)
    info = learner.motion_info_
    assert info["chosen"] == "robot" and info["beams"] == {"ahead": 29, "clockwise": True}
    model = learner.robot_map_
    assert np.array_equal(walk.observations[:, cols][:, model.beam_order], walk.observations)
    placed = learner.predict(held.observations[:, cols], held.actions, odometry=held.odometry)
    by_hand = place_walk(model, held.observations, held.odometry)[0]
    assert np.array_equal(placed, by_hand)
    again = load_robot_map(save_robot_map(model, tmp_path / "robot_map.npz"))
    assert np.array_equal(again.beam_order, model.beam_order)
