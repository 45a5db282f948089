"""The default (``motion="auto"``) on a robot's log with odometry: the robot route behind two
guards -- the map's point symmetry and the held-out check
(:mod:`topomap.core.motion.robot_check`), floor its scans saw that its walk never entered
(:mod:`topomap.core.motion.unwalked`) recorded -- else the view clusters, with the reason."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.motion.unwalked import FAR, MARGIN, MAX_UNWALKED_DEPTH, unwalked_floor
from topomap.core.motion.learn import ContinuousFallbackWarning
from topomap.core.motion.robot import RobotMap
from topomap.core.motion.robot_check import (ROBOT_MARGIN_SE, check_reason, continued_poses,
                                              held_out_span, preceding_poses, robot_wins)


def _two_cells(north_range):
    """Cells at (0, 0) and (1, 0), spacing 1, four beams (east, north, west, south): both see a
    wall 2.5 east and 1.5 elsewhere, except that cell 0 sees ``north_range`` north."""
    M = np.full((2, 4), 1.5)
    M[:, 0] = 2.5
    M[0, 1] = north_range
    C = np.array([[0.0, 0.0], [1.0, 0.0]])
    return RobotMap(C, M, 0.01, np.array([0, 1, 2]), np.array([0, 1]), 1.0, np.zeros(2),
                    np.zeros(2, dtype=np.int64))


def test_unwalked_share_and_depth_by_hand():
    """Points every spacing along a beam while still a spacing (``MARGIN``) short of its range:
    the east beams give (1, 0) and (2, 0), 0 and 1 from a cell; the 1.5 beams none.  A north
    beam of 10 from cell 0 adds (0, 1) ... (0, 8), s from cell 0, of which s = 3 ... 8 lie over
    ``FAR`` = 2 from every cell: 6 of 10, lying 1 + 2 + ... + 6 = 21 spacings beyond ``FAR``
    in all, 2.1 a point.  A north beam of 6 adds (0, 1) ... (0, 4): s = 3, 4 over ``FAR``, 2
    of 6, 1 + 2 = 3 spacings beyond, 0.5 a point."""
    assert (FAR, MARGIN) == (2.0, 1.0)
    assert unwalked_floor(_two_cells(1.5)) == (0.0, 0.0)
    assert unwalked_floor(_two_cells(10.0)) == pytest.approx((6 / 10, 21 / 10))
    assert unwalked_floor(_two_cells(6.0)) == pytest.approx((2 / 6, 3 / 6))


def test_continued_poses_go_on_from_the_start_pose():
    """A walk driving 1 m a step along its own heading 0.3 rad, started at (1, 2) facing north:
    it goes on north, 1 m a step, from the start pose (the first step is the start itself)."""
    O = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], dtype=float)
    P = continued_poses(O, np.full(3, 0.3), (1.0, 2.0, math.pi / 2))
    np.testing.assert_allclose(P, [[1, 3, math.pi / 2], [1, 4, math.pi / 2]], atol=1e-12)


def test_preceding_poses_end_at_the_end_pose():
    """The same walk held out before the learned part: it ends at the pose (1, 2) facing north,
    so its steps before lie 2 m and 1 m south of it (the last step is the end pose itself)."""
    O = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], dtype=float)
    P = preceding_poses(O, np.full(3, 0.3), (1.0, 2.0, math.pi / 2))
    np.testing.assert_allclose(P, [[1, 0, math.pi / 2], [1, 1, math.pi / 2]], atol=1e-12)


def test_the_check_holds_out_the_first_part_where_the_last_went_where_the_rest_never_did():
    # 100 steps, a quarter held out: the last quarter in a place of its own (novelty 1), the
    # first quarter in a place the rest shares (novelty 0): the first is held out
    new_last = np.r_[np.zeros(75, int), np.ones(25, int)]
    assert held_out_span(100, 0.25, new_last) == (0, 25)
    assert held_out_span(100, 0.25, None) == (75, 100)  # no places: the last, as always
    assert held_out_span(100, 0.25, np.zeros(100, int)) == (75, 100)  # all ground shared
    # both ends on ground of their own: the last stays held out (the first is no better)
    both = np.r_[np.full(25, 2), np.zeros(50, int), np.ones(25, int)]
    assert held_out_span(100, 0.25, both) == (75, 100)
    line = check_reason({"held_out": 25, "held_out_first": True, "robot": 1.5, "views": 0.8,
                         "gap": -0.7, "se": 0.05})
    assert "first 25 steps" in line


def test_a_first_part_held_out_is_placed_where_its_walk_ended():
    """The check on an arena robot's 4,000 steps with the first quarter held out (the places
    given make the last quarter new ground): the held-out steps' frame ends at the learned
    part's first pose, so the route's map places them near it (measured 0.254 m against the
    views' 0.501 m; a frame started at that pose instead of ended there lies a walk's length
    off) and the figures count the parts."""
    from test_motion_robot import _arena_robot
    from topomap.core.motion.learn import pooled_variances
    from topomap.core.motion.robot_check import robot_check
    from topomap import TopologicalMap

    _, walk, _ = _arena_robot(4000, 10)
    X, u, O = walk.observations, walk.actions, walk.odometry

    def views_map(Xl, ul, labels):
        S = int(labels.max()) + 1
        m = TopologicalMap.from_labels(Xl, ul, labels, lengths=[len(Xl)],
                                       state_symbol=np.arange(S), state_gds=np.full(S, -1),
                                       state_parent=np.full(S, -1), n_actions=walk.n_actions)
        return pooled_variances(m, Xl, labels, 1e-6, 1.0)

    places = np.r_[np.zeros(3000, int), np.ones(1000, int)]
    check = robot_check(X, u, O, 16, views_map, 0.25, 0, places=places)
    assert check["held_out_first"] and (check["learned"], check["held_out"]) == (3000, 1000)
    assert check["robot"] < 0.4 and check["robot"] < check["views"]


def test_the_robot_route_wins_only_by_more_than_its_noise():
    assert robot_wins({"gap": 0.5, "se": 0.1}) is (0.5 > ROBOT_MARGIN_SE * 0.1)
    assert not robot_wins({"gap": 0.1, "se": 0.1})
    assert not robot_wins({"gap": -0.8, "se": 0.05})
    line = check_reason({"held_out": 900, "robot": 1.5, "views": 0.8, "gap": -0.7, "se": 0.05})
    assert "last 900 steps 1.500 m" in line and "0.800 m with the view clusters" in line


def _robot_world(plan_dict, n_steps, seed=0):
    pytest.importorskip("ratinabox")
    from topomap.worlds.arena import ArenaWorld, RangeFinder, floorplan_from_dict

    world = ArenaWorld(floorplan_from_dict(plan_dict, "plan"),
                       sensor=RangeFinder(frame="egocentric", n_beams=60), actions="turns",
                       odometry="wheel")
    return world.simulate(n_steps, None, np.random.default_rng(seed))


@pytest.mark.parametrize("first", [False, True])
def test_a_thinly_walked_plan_records_its_unwalked_floor_and_the_right_judge_decides(
        monkeypatch, first):
    """3,000 steps (5 minutes) in an 8 x 4 m room: the scans see most of the floor, the walk
    enters a corner of it (measured: 64 % of the points along the beams unwalked).  With wheel
    odometry the share is recorded; where the check holds out the log's last part the check
    alone decides (the robot route's map exactly where the check prefers it, else the view
    clusters -- the same as without odometry -- with the check named); where it holds out the
    first part (the last went where the rest never did: made so here), it cannot see unwalked
    floor and the share sends the log back, named."""
    import topomap.core.motion.robot_check as robot_check
    import topomap.core.motion.robot_fit as robot_fit
    from topomap.core.motion.robot_check import robot_wins

    def span(T, holdout, places=None):
        n = int(round(T * holdout))
        return (0, n) if first else (T - n, T)

    monkeypatch.setattr(robot_fit, "held_out_span", span)
    monkeypatch.setattr(robot_check, "held_out_span", span)
    walk = _robot_world({"boundary": [[0, 0], [8, 0], [8, 4], [0, 4]],
                         "holes": [[[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]]]}, 3000)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ContinuousFallbackWarning)
        learner = MapLearner(8, 16, random_state=0).fit_trajectory(walk)
    info = learner.motion_info_
    assert info["unwalked"] > 0.5 and info["unwalked_depth"] > MAX_UNWALKED_DEPTH
    if first:
        assert "check" not in info and info["chosen"] == "views"
        assert "saw floor its walk never entered" in info["reason"]
        assert f"on average {info['unwalked_depth']:.3f} spacings beyond" in info["reason"]
    elif robot_wins(info["check"]):
        assert info["chosen"] == "robot" and learner.robot_map_ is not None
        assert not [w for w in caught if issubclass(w.category, ContinuousFallbackWarning)]
        return
    else:
        assert info["chosen"] == "views" and "held-out check placed" in info["reason"]
    assert getattr(learner, "robot_map_", None) is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContinuousFallbackWarning)
        plain = MapLearner(8, 16, motion={"scan_odometry": False}, random_state=0).fit(
            walk.observations, walk.actions, n_actions=walk.n_actions)
    np.testing.assert_array_equal(learner.labels_, plain.labels_)


@pytest.mark.slow
def test_auto_with_odometry_takes_the_robot_route_where_the_check_prefers_it(monkeypatch):
    """Two 1 m rooms with a table each (8,000 steps; mirror ratio 4.6, 0.1 % unwalked: the
    first two guards pass).  Its own held-out check prefers the route (measured: 0.268 m
    against the views' 0.552 m, 5.3 standard errors), so the default's map is
    ``motion="robot"``'s and ``predict`` places a walk by its odometry; where the check does not
    prefer it (its figures replaced by those it gave before the decoder's reach: 0.570 against
    0.557 m, se 0.22), the default keeps the view clusters and names the check."""
    import topomap.core.motion.robot_fit as robot_fit
    from test_motion_robot import _arena_robot

    _, walk, held = _arena_robot(8000, 300)
    auto = MapLearner(8, 16, random_state=0).fit_trajectory(walk)
    robot = MapLearner(8, 16, motion="robot", random_state=0).fit_trajectory(walk)
    info = auto.motion_info_
    assert info["chosen"] == "robot" and auto.robot_map_ is not None
    assert info["unwalked_depth"] <= MAX_UNWALKED_DEPTH and robot_wins(info["check"])
    np.testing.assert_array_equal(auto.labels_, robot.labels_)
    np.testing.assert_array_equal(
        auto.predict(held.observations, held.actions, odometry=held.odometry),
        robot.predict(held.observations, held.actions, odometry=held.odometry))
    monkeypatch.setattr(robot_fit, "robot_check", lambda *a, **k: {
        "learned": 6000, "held_out": 2000, "robot": 0.570, "views": 0.557, "gap": -0.013,
        "se": 0.22})
    with pytest.warns(ContinuousFallbackWarning, match="held-out check placed"):
        kept = MapLearner(8, 16, random_state=0).fit_trajectory(walk)
    assert kept.motion_info_["chosen"] == "views" and getattr(kept, "robot_map_", None) is None


def test_a_map_whose_cells_lie_beyond_its_scans_reach_gives_way(monkeypatch):
    """The arena robot's cells lie 0.15 of its scans' median range apart (measured 0.055 m
    against 0.38 m): the bar lets its map on to the other guards; with the bar set below that
    share, the cells 'lie farther apart than the scans reach' and the log gets the view
    clusters, the reason named, before any other guard (odometry read from 12 beams that
    register nothing put a 2 x 1 m arena's cells 8.85 m apart)."""
    import topomap.core.motion.robot_fit as robot_fit
    from test_motion_robot import _arena_robot

    _, walk, _ = _arena_robot(3000, 10)
    learner = MapLearner(8, 16, random_state=0).fit_trajectory(walk)
    spacing = learner.motion_info_["cell_spacing_m"]
    reach = float(np.median(walk.observations))
    assert spacing < 0.5 * reach and "more than the scans" not in learner.motion_info_.get(
        "reason", "")
    monkeypatch.setattr(robot_fit, "MAX_SPACING_RANGE", 0.5 * spacing / reach)
    with pytest.warns(ContinuousFallbackWarning, match="lie .* apart, more than the scans"):
        learner = MapLearner(8, 16, random_state=0).fit_trajectory(walk)
    info = learner.motion_info_
    assert info["chosen"] == "views" and "check" not in info and "unwalked" not in info
