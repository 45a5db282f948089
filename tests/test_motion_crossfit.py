"""The pose graph and the cross-fitted check of a continuous log, on small cases whose answer
follows from their construction."""

from dataclasses import replace

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.motion import MotionSettings
from topomap.core.motion.check import gives_way
from topomap.core.motion.crossfit import state_positions, translated_error
from topomap.core.motion.posegraph import pose_graph


def _square_loop(side=10, bias=(0.05, -0.03)):
    """Moves round a square of ``side`` unit steps a side, back to the start, each move off by
    the same ``bias`` (the odometry's drift); the truth beside them."""
    dirs = np.repeat([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]], side, axis=0)
    truth = np.vstack([[0.0, 0.0], np.cumsum(dirs, axis=0)])  # 4 side + 1 steps, last = first
    steps = np.zeros_like(truth)
    steps[1:] = dirs + np.asarray(bias)
    return steps, truth


def test_a_pose_graph_removes_a_constant_drift_round_a_closed_loop():
    steps, truth = _square_loop()
    T = len(steps)
    dead = np.cumsum(steps, axis=0)
    assert np.linalg.norm(dead[-1] - truth[-1]) > 1.0  # 40 moves of drift: off by 2.3
    # every step its own copy but the last, which closes the loop on the first one's
    copy = np.arange(T)
    copy[-1] = 0
    x, m = pose_graph(steps, copy, T - 1, [T], cell=1e-3)
    # least squares spreads the loop's error evenly over its 40 like moves: exactly the bias
    np.testing.assert_allclose(x, truth, atol=1e-5)
    np.testing.assert_allclose(m[0], truth[0], atol=1e-5)


def test_a_pose_graph_without_closures_is_dead_reckoning():
    steps, _ = _square_loop()
    T = len(steps)
    x, _ = pose_graph(steps, np.arange(T), T, [T], cell=1.0)
    np.testing.assert_allclose(x, np.cumsum(steps, axis=0), atol=1e-6)


def test_two_episodes_each_start_at_the_origin_unless_a_copy_joins_them():
    steps = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    x, _ = pose_graph(steps, np.arange(4), 4, [2, 2], cell=1.0)
    np.testing.assert_allclose(x, [[0, 0], [1, 0], [0, 0], [0, 1]], atol=1e-6)


def test_the_translated_error_ignores_where_each_frame_starts():
    rng = np.random.default_rng(0)
    frame = rng.normal(size=(101, 2))
    assert translated_error(frame + [5.0, -3.0], frame) == pytest.approx(0.0)
    placed = frame + [5.0, -3.0]
    placed[:40] += [0.0, 2.0]  # 40 of 101 steps placed 2 off: the median step is still exact
    assert translated_error(placed, frame) == pytest.approx(0.0)
    placed[40:] += [0.0, 2.0]  # now all are: the shift follows them
    assert translated_error(placed, frame) == pytest.approx(0.0)
    # every step 1 off, each in one of four directions in turn: no shift helps
    placed[:100] += np.tile([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]], (25, 1))
    assert translated_error(placed, frame) == pytest.approx(1.0)


def test_state_positions_are_the_means_of_their_steps():
    labels = np.array([0, 1, 0, 1, 2])
    P = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0], [3.0, 1.0], [5.0, 5.0]])
    np.testing.assert_allclose(state_positions(labels, P), [[1, 0], [2, 1], [5, 5]])


def _line(T=8000, seed=0, jitter=0.3, period=None):
    """A walk on [0, 2] (turning at the ends and at random; moves of 0.01 times 1 +- ``jitter``),
    action 0 right, 1 left; views that differ all along the line, or repeat every ``period``."""
    rng = np.random.default_rng(seed)
    x = np.empty(T)
    x[0], d = 0.1, 1
    u = np.empty(T, dtype=np.int64)
    for t in range(T):
        if rng.random() < 0.01:
            d = -d
        nxt = x[t] + d * 0.01 * rng.uniform(1 - jitter, 1 + jitter)
        if not 0.0 <= nxt <= 2.0:
            d = -d
            nxt = x[t] + d * 0.01
        u[t] = 0 if d > 0 else 1
        if t + 1 < T:
            x[t + 1] = nxt
    phase = np.pi * x if period is None else 2 * np.pi * x / period
    Z = np.stack([np.cos(phase), np.sin(phase)], 1)
    return Z + rng.normal(0, 0.01, Z.shape), u, x


def _new_walk_error(learner, x_train):
    """Median distance of a new walk's steps from the mean true position of their state."""
    Z, u, x = _line(8000, seed=1)
    labels = learner.labels_
    pos = np.bincount(labels, x_train) / np.maximum(np.bincount(labels), 1)
    return float(np.median(np.abs(pos[learner.predict(Z, u)] - x)))


def test_the_cross_fitted_check_keeps_the_view_clusters_where_places_are_built_to_lose():
    # views that differ all along the line place a step alone; places cut mostly on the
    # odometry's positions (weight 10), which drift by 30 % of a move each step, lose to them
    Z, u, x = _line()
    kw = dict(n_clusters=16, n_states=32, random_state=0)
    lose = MotionSettings(check={"rule": "crossfit"}, places={"weight": 10.0, "loose_weight": 10.0})
    places = MapLearner(**kw, motion=replace(lose, holdout=0)).fit(Z, u)
    assert places.motion_info_["chosen"] == "places"
    with pytest.warns(UserWarning, match="no nearer"):
        checked = MapLearner(**kw, motion=lose).fit(Z, u)
    check = checked.motion_info_["check"]
    assert checked.motion_info_["chosen"] == "views" and check["places"] > check["views"]
    assert (check["learned"], check["held_out"]) == (6000, 2000)
    assert _new_walk_error(places, x) > _new_walk_error(checked, x)  # the truth agrees


def test_the_cross_fitted_check_keeps_places_that_tell_alike_halves_apart():
    Z, u, x = _line(jitter=0.1, period=1.0)  # the view of x is that of x + 1
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0,
                         motion=MotionSettings(check={"rule": "crossfit"})).fit(Z, u)
    check = learner.motion_info_["check"]
    assert learner.motion_info_["chosen"] == "places" and check["places"] < check["views"]
    halves = x > 1.0
    # each place lies in one half: the view clusters fold the halves onto each other
    purity = sum(max(np.sum(halves & (learner.labels_ == s)),
                     np.sum(~halves & (learner.labels_ == s)))
                 for s in np.unique(learner.labels_)) / x.size
    assert purity > 0.95


def test_an_unknown_check_is_named():
    from topomap.core.checks import ParameterError
    from topomap.core.motion import motion_settings

    with pytest.raises(ParameterError, match="motion.check.*bootstrap, coverage, crossfit, folds.*'cross'"):
        motion_settings({"check": "cross"})
    assert motion_settings({"check": {"rule": "crossfit"}}).check.rule == "crossfit"


def test_each_held_out_block_is_moved_by_its_own_offset():
    from topomap.core.motion.crossfit import aligned_distances

    frame = np.arange(20.0).reshape(10, 2)
    placed = frame.copy()
    groups = np.repeat([0, 1], 5)
    placed[groups == 1] += [7.0, -2.0]  # the second block's frame starts elsewhere
    np.testing.assert_allclose(aligned_distances(placed, frame, groups), 0.0, atol=1e-12)
    placed[0] += [0.0, 3.0]  # one step of five off: the median offset stays, the step is 3 off
    np.testing.assert_allclose(aligned_distances(placed, frame, groups),
                               [3, 0, 0, 0, 0, 0, 0, 0, 0, 0], atol=1e-12)
    # one group for all: the offset (3.5, -1) between the median blocks puts every step 3.6 off
    assert np.all(aligned_distances(placed, frame, np.zeros(10)) > 3.6)


def test_the_median_gap_and_its_noise_over_stretches():
    from topomap.core.motion.crossfit import median_gap

    places = np.tile([1.0, 2.0, 3.0], 10)
    gap, se = median_gap(places, places + 0.5, stretch=3)
    # every stretch holds the same three distances: every draw gives the same gap
    assert gap == pytest.approx(0.5) and se == pytest.approx(0.0)
    assert median_gap(places, places, stretch=30)[1] == float("inf")  # one stretch: no spread
    rng = np.random.default_rng(0)
    noisy = places + rng.normal(0.0, 1.0, places.size)
    assert median_gap(places, noisy, stretch=3)[1] > 0.1


def test_the_default_check_keeps_the_view_clusters_where_places_are_built_to_lose():
    Z, u, x = _line()
    kw = dict(n_clusters=16, n_states=32, random_state=0)
    # positions outweigh the views; the filter's places alone (no pose graph's beside them)
    heavy = {"weight": 10.0, "loose_weight": 10.0, "graph_gate": 0.0}
    places = MapLearner(**kw, motion={"places": heavy, "check": {"holdout": 0}}).fit(Z, u)
    with pytest.warns(UserWarning, match="standard errors"):
        checked = MapLearner(**kw, motion={"places": heavy}).fit(Z, u)
    check = checked.motion_info_["check"]
    assert check["rule"] == "coverage"  # the default rule: no quarter of this walk is new ground
    assert "span" not in check
    assert checked.motion_info_["chosen"] == "views" and check["gap"] < -2 * check["se"]
    assert (check["learned"], check["held_out"]) == (6000, 2000)
    assert _new_walk_error(places, x) > _new_walk_error(checked, x)  # the truth agrees


def test_the_default_check_keeps_places_that_tell_alike_halves_apart():
    Z, u, x = _line(jitter=0.1, period=1.0)  # the view of x is that of x + 1
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, u)
    assert learner.motion_info_["chosen"] == "places"
    assert learner.motion_info_["check"]["rule"] == "coverage"
    halves = x > 1.0
    purity = sum(max(np.sum(halves & (learner.labels_ == s)),
                     np.sum(~halves & (learner.labels_ == s)))
                 for s in np.unique(learner.labels_)) / x.size
    assert purity > 0.95


def test_each_rule_gives_the_places_up_on_its_own_bar():
    # the views nearer by 0.1 cell extents, with a standard error of 0.04: 2.5 errors
    near = {"places": 1.0, "views": 0.9, "gap": -0.1, "se": 0.04}
    assert gives_way(near, "bootstrap", span=False)  # -0.1 < -2 x 0.04
    assert gives_way(near, "coverage", span=False)
    # a standard error of 0.06: 1.7 errors, under the bar of 2 -- the places stay ...
    noisy = dict(near, se=0.06)
    assert not gives_way(noisy, "bootstrap", span=False)
    assert not gives_way(noisy, "coverage", span=False)
    # ... but not on an earlier part held out for ground new to the rest (nearer at all)
    assert gives_way(noisy, "coverage", span=True)
    assert not gives_way(dict(noisy, gap=0.0), "coverage", span=True)
    # crossfit compares the two errors alone, whatever the noise
    assert gives_way(noisy, "crossfit", span=False)
    assert not gives_way({"places": 0.8, "views": 0.9, "gap": 0.1, "se": 1.0}, "crossfit",
                         span=False)


def test_the_pose_graphs_places_stand_in_where_the_filters_drift():
    # the same heavy positions: the filter's drift (30 % of a move a step) makes its places
    # lose to the views; the pose graph closes the walk's loops and its places win
    Z, u, x = _line()
    kw = dict(n_clusters=16, n_states=32, random_state=0)
    heavy = {"weight": 10.0, "loose_weight": 10.0}
    filt = MapLearner(**kw, motion={"places": dict(heavy, graph_gate=0.0),
                                    "check": {"holdout": 0}}).fit(Z, u)
    with pytest.warns(UserWarning, match="standard errors"):
        views = MapLearner(**kw, motion={"places": dict(heavy, graph_gate=0.0)}).fit(Z, u)
    graph = MapLearner(**kw, motion={"places": heavy}).fit(Z, u)
    check = graph.motion_info_["check"]
    assert check["candidate"] == "graph" and check["graph_gain"] > 2 * check["graph_se"]
    assert check["places"] == check["graph"] < check["filter"]
    assert graph.motion_info_["chosen"] == "places" and graph.motion_info_["positions"] == "graph"
    assert views.motion_info_["chosen"] == "views"
    # the truth agrees: the graph's places nearer than the view clusters, those than the filter's
    assert _new_walk_error(graph, x) < _new_walk_error(views, x) < _new_walk_error(filt, x)


def test_without_closures_the_graph_places_cut_the_views_beside_dead_reckoning():
    from topomap.core.motion.odometry import dead_reckoning
    from topomap.core.motion.places import _kmeans, _view_spread, cut_places, graph_places
    from topomap.core.motion.places import place_features

    Z, u, _ = _line(T=3000)
    s = MotionSettings(places={"graph_gate": 1e-9})  # no step is within a gate of a copy
    part = cut_places(s, Z, u, [3000], 8, 2, n_init=1, random_state=0)
    labels = graph_places(s, Z, part, u, [3000], 8, n_init=1, random_state=0, method="auto")
    # every closure then holds at its own step's position: the pose graph is dead reckoning
    P = dead_reckoning(u, np.array([3000]), part.V) / part.extent
    views = Z / _view_spread(Z, part.views, int(part.views.max()) + 1)
    expected = _kmeans(place_features(views, [P], part.info["weight"]), 8, 1, 0, "auto")
    np.testing.assert_array_equal(labels, expected)


def test_the_pose_graphs_places_stand_in_by_two_standard_errors_or_on_new_ground_at_all():
    from topomap.core.motion.crossfit import stands_in

    # nearer by 0.05 cell extents with a standard error of 0.02: 2.5 errors
    assert stands_in(0.05, 0.02, new_ground=False) and stands_in(0.05, 0.02, new_ground=True)
    # nearer by 0.03 (1.5 errors): only on new ground, where nearer at all is asked
    assert not stands_in(0.03, 0.02, new_ground=False) and stands_in(0.03, 0.02, new_ground=True)
    # farther off, or a tie: never
    assert not stands_in(-0.01, 0.001, new_ground=True) and not stands_in(0.0, 0.0, True)
