"""A robot's log WITHOUT odometry, ``motion={"scan_odometry": True}``: the robot route on odometry
read from the scans (:mod:`topomap.core.motion.robot_scans`), behind the guards of a log with
odometry, else the view clusters it gets today; ``predict`` reads a new walk's odometry from its
scans."""

from __future__ import annotations

import time
import warnings
from contextlib import nullcontext
from types import SimpleNamespace

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.motion.commands import MIN_TURN_SHARE
from topomap.core.motion.learn import ContinuousFallbackWarning
from topomap.core.motion.registration import scan_odometry, scan_poses
from topomap.core.motion.robot_fit import predict_robot
from topomap.core.motion.robot_scans import (SOURCE, ScanReading, closed_odometry,
                                             early_scan_reading, is_scan_log, read_scans,
                                             scan_turn_share, walk_odometry)
from topomap.core.motion.settings import motion_settings
from topomap.core.motion.unwalked import MAX_UNWALKED_DEPTH


def _log(T=50, B=12, lengths=None, gds=-1, low=0.5):
    return SimpleNamespace(X=np.full((T, B), low), u=np.zeros(T, dtype=int),
                           lengths=np.array([T] if lengths is None else lengths),
                           gds=np.full(T, gds))


def test_a_robot_log_without_odometry_is_recognised_by_hand():
    """Recognised: no odometry given, and the continuous path learned none from the commands
    (turn commands), one episode, no GDS, a ring of 3 beams or more, no negative reading.  A
    compass walker's commands give odometry (``info["odometry"]`` True): never caught."""
    none = {"odometry": False}
    assert is_scan_log(_log(), None, none)
    assert not is_scan_log(_log(), np.zeros((50, 3)), none)        # odometry given
    assert not is_scan_log(_log(), None, {"odometry": True})        # compass commands
    assert not is_scan_log(_log(), None, {})                        # not the continuous path
    assert not is_scan_log(_log(lengths=[25, 25]), None, none)      # two episodes
    assert not is_scan_log(_log(gds=0), None, none)                 # GDS steps
    assert not is_scan_log(_log(B=2), None, none)                   # no ring of beams
    assert not is_scan_log(_log(low=-1.0), None, none)              # not ranges



def _turning_log(T=400, B=24, turns=True, seed=0):
    """A ring of ``B`` beams seeing one lopsided room from a fixed spot: command 1 turns the robot
    one beam anticlockwise (its scan shifts by one beam), command 2 one beam clockwise, command 0
    not at all -- or, ``turns=False``, the same commands with the scan never turning (a compass
    walker's)."""
    rng = np.random.default_rng(seed)
    k = np.arange(B)
    room = 1.0 + 0.5 * np.cos(2 * np.pi * k / B) + 0.2 * np.sin(6 * np.pi * k / B)
    u = rng.integers(0, 3, T)
    shift = np.cumsum(np.r_[0, np.where(u[:-1] == 1, 1, np.where(u[:-1] == 2, -1, 0))])
    X = np.array([np.roll(room, -k if turns else 0) for k in shift])
    return SimpleNamespace(X=X, u=u, lengths=np.array([T]), gds=np.full(T, -1))


def test_scans_that_turn_as_the_commands_say_are_a_robot_s_by_hand():
    """The scans' turns are explained whole by the commands that made them (every command turns
    by its own whole beam: share 1); of scans that never turn, the rounding of their zero turns
    is explained by three commands no more than chance would (about 2 / 400; the rounding
    follows the FFT's, so only the bar is asserted).  A log whose
    continuous path read odometry off its commands but kept the view clusters is a robot's where
    its scans turn with the commands, never where they do not or where its places were kept."""
    robot, compass = _turning_log(), _turning_log(turns=False)
    assert scan_turn_share(robot.X, robot.u) == pytest.approx(1.0, abs=1e-6)
    assert scan_turn_share(compass.X, compass.u) < MIN_TURN_SHARE
    views = {"odometry": True, "chosen": "views"}
    assert is_scan_log(robot, None, views)
    assert not is_scan_log(compass, None, views)
    assert not is_scan_log(robot, None, {"odometry": True, "chosen": "places"})
    assert not is_scan_log(robot, np.zeros((400, 3)), views)        # odometry given


def test_the_scans_are_read_beside_the_view_clusters_only_where_the_route_may_follow():
    """A log whose scans turn as its commands say gets its scans' odometry read on a thread of
    its own -- the same registration and closed poses as read in turn, to the bit; a compass
    walker's scans (never turning), a log given odometry and the setting off get none."""
    robot, compass = _turning_log(), _turning_log(turns=False)
    on, off = motion_settings("auto"), motion_settings({"scan_odometry": False})
    with early_scan_reading(on, robot, None) as reading:
        assert isinstance(reading, ScanReading)
        raw, poses = reading()
    want_raw, want_poses = read_scans(robot.X)
    np.testing.assert_array_equal(raw, want_raw)
    np.testing.assert_array_equal(poses, want_poses)
    # the candidate closures searched beside the registration: the poses closed in turn
    alternatives = []
    np.testing.assert_array_equal(scan_odometry(robot.X, alternatives=alternatives), raw)
    np.testing.assert_array_equal(scan_poses(robot.X, odometry=raw, alternatives=alternatives),
                                  poses)
    for settings, log, odometry in ((on, compass, None), (on, robot, np.zeros((400, 3))),
                                    (off, robot, None)):
        with early_scan_reading(settings, log, odometry) as reading:
            assert reading is None


def test_a_reading_left_unused_is_stopped_and_its_error_raised_where_asked(monkeypatch):
    """Leaving the reading's ``with`` block asks it to stop (a reading that waits for that
    gives None); an error on its thread is raised where its result is asked for."""
    import topomap.core.motion.robot_scans as robot_scans

    def waiting(X, stop):
        while not stop():
            time.sleep(0.001)
        return None

    monkeypatch.setattr(robot_scans, "read_scans", waiting)
    with ScanReading(np.ones((5, 4))) as reading:
        pass
    assert reading() is None

    def failing(X, stop):
        raise ValueError("a bad scan")

    monkeypatch.setattr(robot_scans, "read_scans", failing)
    with ScanReading(np.ones((5, 4))) as reading, pytest.raises(ValueError, match="a bad scan"):
        reading()


def test_the_setting_is_on_by_default_and_checked():
    assert motion_settings("auto").scan_odometry is True
    assert motion_settings({"scan_odometry": False}).scan_odometry is False
    with pytest.raises(ParameterError, match=r"^motion.scan_odometry must be true or false"):
        motion_settings({"scan_odometry": "yes"})


def _robot_world(plan_dict, n_steps, seed=0):
    pytest.importorskip("ratinabox")
    from topomap.worlds.arena import ArenaWorld, RangeFinder, floorplan_from_dict

    world = ArenaWorld(floorplan_from_dict(plan_dict, "plan"),
                       sensor=RangeFinder(frame="egocentric", n_beams=60), actions="turns")
    return world.simulate(n_steps, None, np.random.default_rng(seed))


def _fit(walk, **motion):
    """The default (the setting on), fitted on the walk's scans and commands alone."""
    return MapLearner(8, 16, motion={"scan_odometry": True, **motion}, random_state=0).fit(
        walk.observations, walk.actions, n_actions=walk.n_actions)


def test_a_thinly_walked_log_without_odometry_keeps_the_view_clusters():
    """3,000 steps (5 minutes) in an 8 x 4 m room, no odometry: the route is tried on the
    odometry read from the scans, and its unwalked-floor guard sends the log back (the walk
    enters a corner of the floor its scans see) -- the same states as with the setting off,
    the warning and the reason.  The default (no ``motion`` given) is the setting on."""
    walk = _robot_world({"boundary": [[0, 0], [8, 0], [8, 4], [0, 4]],
                         "holes": [[[1, 1], [1.5, 1], [1.5, 1.5], [1, 1.5]]]}, 3000)
    with pytest.warns(ContinuousFallbackWarning, match="saw floor its walk never entered"):
        learner = MapLearner(8, 16, random_state=0).fit(walk.observations, walk.actions,
                                                        n_actions=walk.n_actions)
    info = learner.motion_info_
    assert info["chosen"] == "views" and info["odometry_from"] == SOURCE
    assert info["unwalked_depth"] > MAX_UNWALKED_DEPTH
    assert getattr(learner, "robot_map_", None) is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContinuousFallbackWarning)
        plain = _fit(walk, scan_odometry=False)
    assert "odometry_from" not in plain.motion_info_  # off: not tried
    # the map records the setting only where it is off, its default on
    assert "scan_odometry" not in learner.map_.info["motion"]
    assert plain.map_.info["motion"]["scan_odometry"] is False
    np.testing.assert_array_equal(learner.labels_, plain.labels_)
    np.testing.assert_array_equal(learner.map_.means, plain.map_.means)


def test_where_the_guards_pass_the_route_is_taken_and_predict_reads_the_scans(monkeypatch):
    """3,000 steps in two furnished 1 m rooms, no odometry, the floor and check guards made to
    pass (the floor's depth at its bar, its share -- recorded, not a judge -- half the points):
    the map is the robot route's on the scans' odometry, and ``predict`` without odometry
    gives what :func:`~topomap.core.motion.robot_fit.predict_robot` gives with the walk's
    registration closed by its loops (:func:`~topomap.core.motion.robot_scans.closed_odometry`);
    the walk placed again lands in most of its own places (measured 0.96; by chance 1 in 16)."""
    import topomap.core.motion.robot_fit as robot_fit
    from test_motion_robot import _arena_robot

    monkeypatch.setattr(robot_fit, "unwalked_floor", lambda model: (0.5, MAX_UNWALKED_DEPTH))
    monkeypatch.setattr(robot_fit, "robot_check", lambda *a, **k: {
        "learned": 2250, "held_out": 750, "robot": 0.1, "views": 0.5, "gap": 0.4, "se": 0.05})
    import topomap.core.motion.learn as learn

    _, walk, _ = _arena_robot(3000, 10)
    readings = []
    monkeypatch.setattr(learn, "early_scan_reading",
                        lambda *a: readings.append(early_scan_reading(*a)) or readings[-1])
    learner = _fit(walk)
    assert isinstance(readings[0], ScanReading)  # read beside the view clusters
    assert learner.motion_info_["chosen"] == "robot" and learner.robot_map_ is not None
    assert learner.motion_info_["unwalked"] == 0.5
    assert learner.motion_info_["odometry_from"] == SOURCE
    # the scans read beside the view clusters: the same map as read after them
    monkeypatch.setattr(learn, "early_scan_reading", lambda *a: nullcontext())
    in_turn = _fit(walk)
    np.testing.assert_array_equal(in_turn.labels_, learner.labels_)
    np.testing.assert_array_equal(in_turn.robot_map_.centres, learner.robot_map_.centres)
    X = walk.observations[:1500]
    again = learner.predict(X, walk.actions[:1500])
    np.testing.assert_array_equal(again, predict_robot(learner.robot_map_, X, None,
                                                       closed_odometry(X)))
    assert np.mean(again == learner.labels_[:1500]) > 0.5


@pytest.mark.slow
def test_a_robot_log_without_odometry_takes_the_route_and_predicts_from_its_scans(monkeypatch):
    """Two 1 m rooms with a table each (8,000 steps learned, no odometry), point-symmetric but
    for the tables.  A reflection matched within ``SCAN_REACH`` spacings reads a mirror ratio
    near the guard's bar (measured 3.0-3.14 by machine: the simulator's floating point follows
    the processor's vector unit), so the guard is asked above it: the log keeps the view
    clusters, saying why.  Matched with the nearest cell alone (as on wheel odometry) the
    reflection matches worse (a higher ratio; measured 4.2) and the guards pass, the
    unwalked floor held at 0 (this walk reads a share of 1.0-1.1 %): the map is
    the robot route's; ``predict`` without odometry reads the held-out walk's from its scans
    -- the same places as given that odometry -- and places it under half as far from the
    truth as K-means on the views, fewer steps in the wrong room.  Where the check does not
    prefer the route, the view clusters stay, as with the setting off."""
    import topomap.core.motion.robot_fit as robot_fit
    from test_motion_robot import _arena_robot
    from topomap.evaluation.metres import kmeans_view_scores, score_units

    plan, walk, held = _arena_robot(8000, 2000)
    with monkeypatch.context() as m:
        m.setattr(robot_fit, "SYMMETRY_RATIO", 1e9)
        sent_back = _fit(walk).motion_info_
    assert sent_back["chosen"] == "views" and "point reflection" in sent_back["reason"]
    monkeypatch.setattr(robot_fit, "unwalked_floor", lambda model: (0.0, 0.0))
    monkeypatch.setattr(robot_fit, "SCAN_REACH", None)
    learner = _fit(walk)
    info = learner.motion_info_
    ratio = info["symmetry"]["ratio"]
    assert ratio > max(sent_back["symmetry"]["ratio"], robot_fit.SYMMETRY_RATIO)
    assert info["chosen"] == "robot" and info["odometry_from"] == SOURCE
    placed = learner.predict(held.observations, held.actions)
    np.testing.assert_array_equal(placed, predict_robot(
        learner.robot_map_, held.observations, None, closed_odometry(held.observations)))
    pair = (plan.region_of(walk.positions), plan.region_of(held.positions))
    ours = score_units(learner.labels_, walk.positions, placed, held.positions, 16, pair)
    views = kmeans_view_scores(16, walk, held, plan.region_of, random_state=0)
    assert ours["median_error"] < 0.5 * views["median_error"]
    assert ours["wrong_region"] < views["wrong_region"]
    monkeypatch.setattr(robot_fit, "robot_check", lambda *a, **k: {
        "learned": 6000, "held_out": 2000, "robot": 0.570, "views": 0.557, "gap": -0.013,
        "se": 0.22})
    with pytest.warns(ContinuousFallbackWarning, match="held-out check placed"):
        kept = _fit(walk)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContinuousFallbackWarning)
        plain = _fit(walk, scan_odometry=False)
    assert kept.motion_info_["chosen"] == "views" and getattr(kept, "robot_map_", None) is None
    np.testing.assert_array_equal(kept.labels_, plain.labels_)


def test_a_new_walk_s_odometry_is_each_episode_closed_by_its_own_loops():
    """``predict``'s odometry of a walk without one: each episode read from its own scans and
    closed by its own loops -- two episodes give what each gives alone; a one-step episode
    stands at the origin (nothing to register)."""
    B = 36
    a = 2 * np.pi * np.arange(B) / B
    rng = np.random.default_rng(0)
    X = 1.0 + 0.3 * np.cos(a) + 0.2 * np.sin(2 * a) + rng.normal(0, 0.01, (120, B))
    both = walk_odometry(X, [80, 40])
    np.testing.assert_array_equal(both[:80], closed_odometry(X[:80]))
    np.testing.assert_array_equal(both[80:], closed_odometry(X[80:]))
    np.testing.assert_array_equal(walk_odometry(X[:1], [1]), np.zeros((1, 3)))


def test_the_view_clusters_leave_the_second_core_to_a_reading_of_the_scans(monkeypatch):
    """While the scans are read on a thread of their own, the continuous path's choice (the view
    clusters' K-means among it) runs on one OpenMP thread; without a reading, on as many as
    outside the fit.  Each fit's labels are the same either way."""
    from threadpoolctl import threadpool_info, threadpool_limits

    import topomap.core.motion.learn as learn
    from test_motion_robot import _arena_robot

    def openmp():
        return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "openmp"]

    seen, choose = [], learn.choose_places
    monkeypatch.setattr(learn, "choose_places", lambda *a, **k: seen.append(openmp()) or
                        choose(*a, **k))
    _, walk, _ = _arena_robot(3000, 10)
    with threadpool_limits(limits=2, user_api="openmp"):  # two, whatever the machine's cores
        outside = openmp()
        read = _fit(walk)
        assert outside and seen[-1] == [1] * len(outside)
        monkeypatch.setattr(learn, "early_scan_reading", lambda *a: nullcontext())
        in_turn = _fit(walk)
        assert seen[-1] == outside == [2] * len(outside)
    np.testing.assert_array_equal(read.labels_, in_turn.labels_)
