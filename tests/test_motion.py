"""Maps from continuous motion: run lengths, learned odometry, copies of views, the learner's
continuous branch -- on small logs whose answer follows from their construction."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.motion.odometry import (action_vectors, dead_reckoning, odometric_positions,
                                          reckoned_steps)
from topomap.core.motion import MotionSettings, is_continuous, mean_run
from topomap.worlds import GridRoom, RandomExplorer

#: the rule these tests of the folds and their votes are about (not the default)
FOLDS = MotionSettings(check={"rule": "folds"})


def test_mean_run_counts_runs_within_episodes():
    # one episode: runs 00 | 111 | 2 -> 6 steps / 3 runs
    assert mean_run([0, 0, 1, 1, 1, 2], [6]) == 2.0
    # episodes [0 0] and [0 1 1 1]: the boundary starts a run -> runs 00 | 0 | 111
    assert mean_run([0, 0, 0, 1, 1, 1], [2, 4]) == 2.0


def test_dead_reckoning_sums_moves_and_restarts_per_episode():
    V = np.array([[1.0, 0.0], [0.0, 2.0]])
    u = np.array([0, 1, 0, 1, 0])
    P = dead_reckoning(u, [3, 2], V)
    # episode 1: 0, +(1,0), +(0,2); episode 2 restarts: 0, +(1,0) (the action of its step 3)
    np.testing.assert_array_equal(P, [[0, 0], [1, 0], [1, 2], [0, 0], [0, 2]])


def _line_walk(cycles=3):
    """x = 0..9..0 repeatedly, one cell a step; symbol of cell x is x mod 5 (cells k and k + 5
    look alike, 5 apart)."""
    x = np.concatenate([np.arange(10), np.arange(8, 0, -1)] * cycles + [[0]])
    u = np.where(np.diff(x, append=x[-1] - 1) > 0, 0, 1)
    return x, x % 5, u


def test_copies_keep_alike_cells_apart_when_the_gate_is_tighter_than_their_distance():
    x, sym, u = _line_walk()
    V = np.array([[1.0, 0.0], [-1.0, 0.0]])  # exact odometry
    steps = reckoned_steps(u, [x.size], V)
    P, copy, n_copies = odometric_positions(sym, steps, [x.size], gate=2.0)
    assert n_copies == 10           # one copy per cell: alike cells are 5 apart
    np.testing.assert_allclose(P[:, 0], x)  # every copy sits where the walk is: no pull
    np.testing.assert_array_equal(copy, x)  # the copies are numbered as the walk meets them
    _, _, n_copies = odometric_positions(sym, steps, [x.size], gate=7.0)
    assert n_copies == 5            # a gate wider than 5 joins alike cells


def _plane_walk(T, seed=0):
    """A random walk in the open plane with 8 compass moves of random length (the heading turns
    by one eighth at a time); views are a fixed linear image of the position (12 features) plus
    a little noise."""
    rng = np.random.default_rng(seed)
    moves = np.stack([np.cos(np.arange(8) * np.pi / 4), np.sin(np.arange(8) * np.pi / 4)], 1)
    u = np.empty(T, dtype=np.int64)
    a = 0
    for t in range(T):
        a = (a + rng.choice([-1, 0, 1], p=[0.25, 0.5, 0.25])) % 8
        u[t] = a
    step = moves[u] * rng.uniform(0.5, 1.5, (T, 1)) * 0.01
    p = np.vstack([[0.0, 0.0], np.cumsum(step[:-1], axis=0)])
    Z = p @ rng.normal(size=(2, 12)) + rng.normal(0, 1e-3, (T, 12))
    return Z, u, moves


def test_action_vectors_are_the_moves_up_to_a_linear_map_of_the_plane():
    Z, u, moves = _plane_walk(20000)
    from sklearn.cluster import KMeans
    fsym = KMeans(40, n_init=1, random_state=0).fit_predict(Z)
    V, ratios = action_vectors(Z, fsym, u, [u.size], 8)
    A, *_ = np.linalg.lstsq(V, moves, rcond=None)
    assert np.abs(V @ A - moves).max() < 0.1
    assert ratios.max() <= 0.35
    # isotropic: the mean step's covariance is the identity / 2 (moves are used alike)
    np.testing.assert_allclose(V[u].T @ V[u] / u.size, np.eye(2) / 2, atol=1e-9)


def test_actions_that_do_not_move_the_robot_give_no_odometry():
    Z, u, _ = _plane_walk(20000)
    from sklearn.cluster import KMeans
    fsym = KMeans(40, n_init=1, random_state=0).fit_predict(Z)
    unrelated = np.random.default_rng(1).integers(0, 8, u.size)  # ids drawn apart from the moves
    V, ratios = action_vectors(Z, fsym, unrelated, [u.size], 8)
    assert not V.any() and ratios.min() > 0.35 / 2


def _alike_halves(T=8000, seed=0):
    """A walk on the line [0, 2] (turning at the ends and at random) whose two halves look
    alike: the view of x is that of x + 1 (period 1).  Action 0 moves right, 1 left."""
    rng = np.random.default_rng(seed)
    x = np.empty(T)
    x[0], d = 0.1, 1
    u = np.empty(T, dtype=np.int64)
    for t in range(T):
        if rng.random() < 0.01:
            d = -d
        nxt = x[t] + d * 0.01 * rng.uniform(0.7, 1.3)
        if not 0.0 <= nxt <= 2.0:
            d = -d
            nxt = x[t] + d * 0.01
        u[t] = 0 if d > 0 else 1
        if t + 1 < T:
            x[t + 1] = nxt
    phase = 2 * np.pi * x
    Z = np.stack([np.cos(phase), np.sin(phase), np.cos(2 * phase)], 1)
    return Z + rng.normal(0, 0.01, Z.shape), u, x


def _mixed_share(labels, x):
    """Share of the steps in the alike middles of the halves ([0.2, 0.8] and [1.2, 1.8]) held by
    states that hold steps of both."""
    left, right = (x > 0.2) & (x < 0.8), (x > 1.2) & (x < 1.8)
    mixed = 0
    for s in np.unique(labels):
        a, b = np.sum(left & (labels == s)), np.sum(right & (labels == s))
        mixed += min(a, b)
    return mixed / np.sum(left | right)


def test_continuous_log_gets_places_that_tell_alike_halves_apart():
    Z, u, x = _alike_halves()
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0).fit(Z, u)
    assert learner.motion_info_["mean_run"] > 3
    assert learner.labels_.shape == (Z.shape[0],) and learner.map_.n_states == 8
    assert _mixed_share(learner.labels_, x) < 0.02
    assert learner.motion_info_["chosen"] == "places"  # the held-out check keeps them
    # every view is seen in both halves: the middle gate keeps two copies of each
    assert learner.motion_info_["copies"][1] >= 2 * learner.motion_info_["view_clusters"]
    # the views alone (the paper's split) cannot: they fold the halves onto each other
    views = MapLearner(n_clusters=4, n_states=8, motion="discrete", random_state=0).fit(Z, u)
    assert not hasattr(views, "motion_info_")
    assert _mixed_share(views.labels_, x) > 0.2
    # the map decodes a new stream of the same kind, one state per row
    Zt, ut, _ = _alike_halves(2000, seed=1)
    assert learner.predict(Zt, ut).shape == (2000,)


def test_the_check_holds_out_successive_quarters_and_keeps_the_places_on_their_share():
    from topomap.core.motion.check import keeps_places

    Z, u, _ = _alike_halves()  # 8,000 steps: quarters of 2,000
    # fold i learns from the steps before 6,000 - 2,000 i and decodes the 2,000 after them; a
    # fourth fold would learn from no step, so four folds asked for give three
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0,
                         motion=MotionSettings(check={"rule": "folds", "folds": 4})).fit(Z, u)
    check = learner.motion_info_["check"]
    assert [f["learned"] for f in check["folds"]] == [6000, 4000, 2000]
    assert [f["held_out"] for f in check["folds"]] == [2000, 2000, 2000]
    for name in ("places", "views"):
        for f in check["folds"]:  # a share of the steps with a reference, counted
            assert f["misplaced_steps"][name] == pytest.approx(
                f["misplaced"][name] * f["referenced"], abs=1e-4 * f["referenced"])
        pooled = (sum(f["misplaced_steps"][name] for f in check["folds"])
                  / sum(f["referenced"] for f in check["folds"]))
        assert check["mean_misplaced"][name] == pytest.approx(pooled, abs=1e-4)
    assert keeps_places(check["mean_misplaced"], 0.9)
    assert learner.motion_info_["chosen"] == "places"


def test_the_held_out_frame_carries_the_filter_on_from_the_copies_learned_before_the_cut():
    from topomap.core.motion.check import held_out_frame
    from topomap.core.motion.places import Places

    x, sym, u = _line_walk(cycles=4)  # cells 0..9 and back, symbol x mod 5, exact odometry
    Z = np.eye(5)[sym]
    cut = 40                          # the first two sweeps learn a copy of every cell
    V = np.array([[1.0, 0.0], [-1.0, 0.0]])
    P, _, _ = odometric_positions(sym[:cut], reckoned_steps(u[:cut], [cut], V), [cut], gate=2.0)
    part = Places(sym[:cut], None, V, 1.0, P, {})
    two = MotionSettings(places={"gates": (2.0,)})
    frame, joined = held_out_frame(two, part, Z, u, [x.size], cut)
    np.testing.assert_allclose(frame[:, 0], x[cut:])  # every later step where it is
    assert joined.all()                               # joining a copy made before the cut
    # with a wider gate alike cells share copies, pulled between their positions
    wide, _ = held_out_frame(MotionSettings(places={"gates": (7.0,)}), part, Z, u, [x.size], cut)
    assert np.abs(wide[:, 0] - x[cut:]).max() > 0.5


def test_held_out_steps_where_the_learned_part_never_went_join_no_earlier_copy():
    from topomap.core.motion.check import held_out_frame
    from topomap.core.motion.places import Places

    x, sym, u = _line_walk(cycles=4)  # cells 0..9 and back, symbol x mod 5, exact odometry
    Z = np.eye(5)[sym]
    cut = 5                           # the learned part saw cells 0..4 only
    V = np.array([[1.0, 0.0], [-1.0, 0.0]])
    P, _, _ = odometric_positions(sym[:cut], reckoned_steps(u[:cut], [cut], V), [cut], gate=2.0)
    part = Places(sym[:cut], None, V, 1.0, P, {})
    two = MotionSettings(places={"gates": (2.0,)})
    frame, joined = held_out_frame(two, part, Z, u, [x.size], cut)
    # cells 5..9 look like 0..4 but lie 5 cells off: their copies are made after the cut
    np.testing.assert_array_equal(joined, x[cut:] <= 4)
    np.testing.assert_allclose(frame[:, 0], x[cut:])


def _distinct_line(T=8000, seed=0):
    """The walk of :func:`_alike_halves` seen through views that differ all along [0, 2]."""
    _, u, x = _alike_halves(T, seed)
    phase = np.pi * x
    Z = np.stack([np.cos(phase), np.sin(phase)], 1)
    return Z + np.random.default_rng(seed).normal(0, 0.01, Z.shape), u, x


def test_every_rule_gives_the_views_unchecked_where_no_view_was_told_apart():
    # the distinct line's filter keeps 35 copies for 32 view clusters: asked for more than 1.5
    # copies a cluster, the default rule (and ``crossfit``) give the view clusters without a
    # check, the labels those of the ``folds`` rule's same fallback
    Z, u, _ = _distinct_line()
    folds = MapLearner(n_clusters=16, n_states=32, random_state=0,
                       motion=MotionSettings(check={"rule": "folds", "min_copies": 1.5})).fit(Z, u)
    for rule in ("coverage", "crossfit"):
        gated = MapLearner(n_clusters=16, n_states=32, random_state=0,
                           motion=MotionSettings(check={"rule": rule, "min_copies": 1.5})).fit(Z, u)
        info = gated.motion_info_
        assert info["chosen"] == "views"
        assert info["check"] == "the middle gate kept one copy per view cluster"
        np.testing.assert_array_equal(gated.labels_, folds.labels_)
    # at the default 1.0 copies a cluster, 35 copies tell sightings apart: the check runs
    checked = MapLearner(n_clusters=16, n_states=32, random_state=0).fit(Z, u)
    assert isinstance(checked.motion_info_["check"], dict)
    assert checked.motion_info_["copies"][1] > checked.motion_info_["view_clusters"]


def test_the_check_falls_back_to_the_views_where_they_place_steps_alone():
    # every view is seen at one place: positions add nothing the views do not say, so the
    # places cannot misplace fewer held-out steps than the view clusters do
    Z, u, _ = _distinct_line()
    learner = MapLearner(n_clusters=16, n_states=32, random_state=0, motion=FOLDS).fit(Z, u)
    info = learner.motion_info_
    assert info["odometry"] and info["chosen"] == "views"
    misplaced = info["check"]["mean_misplaced"]  # over the two held-out quarters
    assert misplaced["places"] > 0.9 * misplaced["views"]
    # the filter keeps one copy per view cluster but for a few drift resets (35 for 32): asked
    # for more than 1.5 per cluster, the check is not run at all
    assert info["view_clusters"] < info["copies"][1] < 1.5 * info["view_clusters"]
    unchecked_views = MapLearner(n_clusters=16, n_states=32, random_state=0,
                                 motion=MotionSettings(check={"rule": "folds", "min_copies": 1.5})).fit(Z, u)
    assert unchecked_views.motion_info_["check"] == "the middle gate kept one copy per view " \
                                                   "cluster"
    np.testing.assert_array_equal(unchecked_views.labels_, learner.labels_)
    # the states are then the view clusters: K-means on the views with as many clusters
    unchecked = MapLearner(n_clusters=16, n_states=32, random_state=0,
                           motion=MotionSettings(check={"holdout": 0})).fit(Z, u)
    assert unchecked.motion_info_["chosen"] == "places"
    from sklearn.cluster import KMeans

    kmeans = KMeans(32, n_init=4, random_state=0).fit(Z)  # the yardstick's own clusters
    assert _same_partition(learner.labels_, kmeans.labels_)
    # each state's Gaussian has the one variance pooled over the states and the features,
    # a hundredth of the mean squared distance of a view to its cluster's mean
    cov = learner.map_.covariances
    assert np.all(cov == cov[0, 0])
    m = learner.map_
    spread = np.mean((Z - m.means[learner.labels_]) ** 2)
    np.testing.assert_allclose(cov[0, 0], 0.01 * (spread + learner.reg_covar))


def test_the_places_are_not_checked_where_the_middle_gate_told_no_view_apart():
    from topomap.core.motion.check import tells_apart

    s = MotionSettings()  # gates 2.5, 3.0, 3.5: the middle one, 3.0, is the check's frame
    assert s.check.min_copies == 1.0
    # 64 view clusters: more than 64 copies of the middle gate, whatever the others
    assert not tells_apart(s, {"view_clusters": 64, "copies": [308, 64, 308]})
    assert tells_apart(s, {"view_clusters": 64, "copies": [64, 65, 64]})
    assert tells_apart(MotionSettings(places={"gates": (3.0,)}, check={"min_copies": 2.0}),
                       {"view_clusters": 8, "copies": [17]})
    assert not tells_apart(MotionSettings(places={"gates": (3.0,)}, check={"min_copies": 2.0}),
                           {"view_clusters": 8, "copies": [16]})


def test_view_purity_counts_the_steps_in_their_places_view_cluster():
    from topomap.core.motion.check import view_purity

    # place 0: views 0, 0, 1 -> its view cluster is 0, its third step is not in it; place 1:
    # views 1, 1 -> both in it; place 2: view 2 -> in it.  5 of 6 steps
    assert view_purity([0, 0, 0, 1, 1, 2], [0, 0, 1, 1, 1, 2]) == pytest.approx(5 / 6)
    # one place over three views, two steps in view 0: half the steps (the other way round,
    # every view cluster lies within one place, but the places cut across the views)
    assert view_purity([0, 0, 0, 0], [0, 0, 1, 2]) == pytest.approx(0.5)
    # places that are the view clusters, renumbered: every step
    assert view_purity([2, 2, 0, 1], [0, 0, 1, 2]) == 1.0
    # one place across two views seen equally often: half the steps
    assert view_purity([0, 0, 0, 0], [3, 3, 1, 1]) == pytest.approx(0.5)


def test_places_that_cut_across_the_views_give_way_to_the_view_clusters():
    from topomap.core.motion.check import view_purity
    from topomap.core.motion.places import view_clusters

    Z, u, _ = _alike_halves(2000)
    places = MapLearner(n_clusters=4, n_states=8, random_state=0,
                        motion=MotionSettings(check={"holdout": 0})).fit(Z, u)
    assert places.motion_info_["chosen"] == "places"
    purity = view_purity(places.labels_, view_clusters(Z, 8, n_init=4, random_state=0))
    assert 0 < purity < 1
    below = MapLearner(n_clusters=4, n_states=8, random_state=0,
                       motion={"check": {"rule": "folds", "min_purity": purity - 1e-6}}).fit(Z, u)
    assert below.motion_info_.get("check") != "the places cut across the view clusters"
    above = MapLearner(n_clusters=4, n_states=8, random_state=0,
                       motion={"check": {"rule": "folds", "min_purity": purity + 1e-6}}).fit(Z, u)
    info = above.motion_info_
    assert info["chosen"] == "views" and info["check"] == "the places cut across the view clusters"
    assert info["purity"] == round(purity, 4)
    assert _same_partition(above.labels_, view_clusters(Z, 8, n_init=4, random_state=0))


def test_view_clusters_are_numbered_by_first_appearance():
    from topomap.core.motion.places import view_clusters

    Z = np.array([[5.0, 5.0], [0.0, 0.0], [5.0, 5.1], [0.0, 0.1], [9.0, 0.0], [0.1, 0.0]])
    np.testing.assert_array_equal(view_clusters(Z, 3, n_init=4, random_state=0),
                                  [0, 1, 0, 1, 2, 1])


def test_pooled_variances_rank_a_view_by_its_distance_to_each_state_mean():
    from topomap.core.map.model import TopologicalMap
    from topomap.core.motion.learn import pooled_variances

    # state 0: views -0.1, 0.1 (mean 0, variance 0.01); state 1: views 0, 20 (mean 10,
    # variance 100); one variance for both: (0.01 + 0.01 + 100 + 100) / 4 = 50.005
    X = np.array([[-0.1], [0.1], [0.0], [20.0]])
    labels = np.array([0, 0, 1, 1])
    for cov_type, pooled in (("diag", [[50.005], [50.005]]), ("full", [[[50.005]], [[50.005]]])):
        m = TopologicalMap.from_labels(X, np.zeros(4, dtype=np.int64), labels,
                                       state_symbol=np.arange(2), state_gds=np.full(2, -1),
                                       state_parent=np.full(2, -1), n_actions=1,
                                       covariance_type=cov_type, reg_covar=0.0)
        p = pooled_variances(m, X, labels, reg_covar=0.0)
        np.testing.assert_allclose(p.covariances, pooled)
        np.testing.assert_array_equal(p.means, m.means)
        # a view at 3 is nearer state 0 (3 away, not 7): the pooled map says so, the map of each
        # state's own variance gives it to the broad state 1
        assert p.predict(np.array([[3.0]]), np.zeros(1, dtype=np.int64))[0] == 0
        assert m.predict(np.array([[3.0]]), np.zeros(1, dtype=np.int64))[0] == 1


def test_a_scaled_pooled_variance_keeps_a_step_at_its_nearest_centre():
    from topomap.core.map.model import TopologicalMap
    from topomap.core.motion.learn import pooled_variances

    # 100 views -0.1 / 0.1 (state 0), then 100 views 0.9 / 1.1 (state 1): the pooled variance is
    # 0.01, and state 1 was never left for state 0 (that transition: 1e-6 / 2 after smoothing,
    # a cost of log(2e6) = 14.5 nats)
    X = np.r_[np.tile([-0.1, 0.1], 50), np.tile([0.9, 1.1], 50)][:, None]
    labels = np.repeat([0, 1], 100)
    u = np.zeros(200, dtype=np.int64)
    m = TopologicalMap.from_labels(X, u, labels, state_symbol=np.arange(2),
                                   state_gds=np.full(2, -1), state_parent=np.full(2, -1),
                                   n_actions=1, reg_covar=0.0)
    walk = np.array([[1.0], [1.0], [1.0], [0.45]])  # the last view is nearer state 0's mean
    # at the variance 0.01 it gains (0.55^2 - 0.45^2) / (2 * 0.01) = 5 nats in state 0, less than
    # the transition costs: the decoding keeps it in state 1
    plain = pooled_variances(m, X, labels, reg_covar=0.0)
    np.testing.assert_allclose(plain.covariances, [[0.01], [0.01]])
    assert plain.predict(walk, u[:4]).tolist() == [1, 1, 1, 1]
    # at a hundredth of it, 500 nats: the nearest centre wins
    sharp = pooled_variances(m, X, labels, reg_covar=0.0, scale=0.01)
    np.testing.assert_allclose(sharp.covariances, [[1e-4], [1e-4]])
    assert sharp.predict(walk, u[:4]).tolist() == [1, 1, 1, 0]


def test_the_check_counts_steps_placed_far_off_not_the_median_distance():
    from topomap.core.motion.check import frame_error, keeps_places, misplaced_share

    frame = np.zeros((4, 2))
    near = np.array([[0.5, 0], [0.5, 0], [0.5, 0], [0.5, 0]])  # every step half a cell off
    room = np.array([[0.1, 0], [0.1, 0], [0.1, 0], [0, 3.0]])  # one step in the other room
    assert misplaced_share(near, frame, far=2.0) == 0.0
    assert misplaced_share(room, frame, far=2.0) == 0.25
    assert misplaced_share(room, frame, far=3.5) == 0.0
    assert frame_error(room, frame) < frame_error(near, frame)  # the median misses that step
    assert keeps_places({"places": 0.1, "views": 0.25}, margin=0.8)      # 0.1 <= 0.2
    assert not keeps_places({"places": 0.22, "views": 0.25}, margin=0.8)  # fewer, not by 20 %
    assert keeps_places({"places": 0.22, "views": 0.25}, margin=1.0)
    assert not keeps_places({"places": 0.25, "views": 0.25}, margin=1.0)  # alike: the views
    assert not keeps_places({"places": 0.0, "views": 0.0}, margin=1.0)    # none: in doubt
    # 0.010 against 0.021: at most 0.9 times, but 0.011 fewer, under a least gain of 0.02
    assert keeps_places({"places": 0.010, "views": 0.021}, margin=0.9)
    assert not keeps_places({"places": 0.010, "views": 0.021}, margin=0.9, min_gain=0.02)
    assert keeps_places({"places": 0.10, "views": 0.125}, margin=0.9, min_gain=0.02)  # 0.025


def test_the_check_counts_every_held_out_step_with_a_reference_once():
    from topomap.core.motion.check import keeps_places, pooled_shares

    # the last quarter: 1,000 steps with a reference, places misplace 200, view clusters 400;
    # the one before: only 100 steps joined an earlier copy, places misplace 50, views none.
    # A mean of the two shares (0.35 against 0.20) would give the places up on the quarter
    # with a tenth of the steps; counted once each, 250 / 1,100 against 400 / 1,100
    folds = [{"referenced": 1000, "misplaced_steps": {"places": 200, "views": 400}},
             {"referenced": 100, "misplaced_steps": {"places": 50, "views": 0}}]
    shares = pooled_shares(folds)
    assert shares == {"places": round(250 / 1100, 4), "views": round(400 / 1100, 4)}
    assert keeps_places(shares, margin=0.9, min_gain=0.02)
    assert not keeps_places({"places": 0.35, "views": 0.20}, margin=0.9, min_gain=0.02)
    # folds alike in their steps with a reference: the mean of their shares
    even = [{"referenced": 400, "misplaced_steps": {"places": 40, "views": 100}},
            {"referenced": 400, "misplaced_steps": {"places": 120, "views": 100}}]
    assert pooled_shares(even) == {"places": 0.2, "views": 0.25}


def test_the_held_out_steps_are_cut_into_stretches_of_their_gain():
    from topomap.core.motion.check import gain_blocks

    # steps misplaced by the places 1 0 0 0 1, by the view clusters 1 1 1 0 0: the view
    # clusters misplace 0 1 1 0 -1 more; stretches of 2 steps, the last one of 1
    assert gain_blocks([1, 0, 0, 0, 1], [1, 1, 1, 0, 0], 2) == [[2, 1], [2, 1], [1, -1]]
    assert gain_blocks([True, False], [False, False], 5) == [[2, -1]]


def test_a_gain_won_in_one_stretch_of_the_walk_is_noise():
    from topomap.core.motion.check import gain_noise

    # 400 held-out steps in two parts of two stretches of 100: the view clusters misplace 40
    # more, a gain of 0.1 -- all of it in one stretch: deviations 30, -10, -10, -10 from 10
    # each; 1,200 x 4 / 3 = 1,600, sqrt 40, over 400 steps: a noise of 0.1, the gain only
    # once its noise
    lumped = [{"blocks": [[100, 40], [100, 0]]}, {"blocks": [[100, 0], [100, 0]]}]
    assert gain_noise(lumped) == pytest.approx((0.1, 0.1))
    # the same gain spread over the walk: 12, 8, 10, 10; 8 x 4 / 3, sqrt 3.266 / 400
    spread = [{"blocks": [[100, 12], [100, 8]]}, {"blocks": [[100, 10], [100, 10]]}]
    gain, noise = gain_noise(spread)
    assert gain == pytest.approx(0.1) and noise == pytest.approx(np.sqrt(32 / 3) / 400)
    # stretches of unequal steps: 30 of 300 and -5 of 100, a gain of 25 / 400; deviations
    # 30 - 18.75 = 11.25 and -5 - 6.25 = -11.25: 253.125 x 2, sqrt 22.5, over 400
    gain, noise = gain_noise([{"blocks": [[300, 30]]}, {"blocks": [[100, -5]]}])
    assert gain == pytest.approx(0.0625) and noise == pytest.approx(22.5 / 400)
    # one stretch has no spread to measure: no bar it could pass; no steps, no gain
    assert gain_noise([{"blocks": [[100, 10]]}]) == (0.1, float("inf"))
    assert gain_noise([{"blocks": []}]) == (0.0, float("inf"))


def test_the_bar_of_the_noise_is_off_at_zero_confidence():
    from topomap.core.motion.check import clears_noise

    # the preset two_rooms walk: a gain of 0.054 against a noise of 0.061
    assert clears_noise(0.054, 0.061, 0.0)
    assert not clears_noise(0.054, 0.061, 1.0)
    assert clears_noise(0.054, 0.061, 0.85)          # 0.054 > 0.05185
    assert not clears_noise(0.1, 0.05, 2.0)           # exactly twice: not more
    # one stretch: the noise unknown (infinite) -- no bar passes it, and none is asked at 0
    assert clears_noise(0.1, float("inf"), 0.0)
    assert not clears_noise(0.1, float("inf"), 2.0)


def test_most_of_three_quarters_each_alone_outvote_a_mean_of_two():
    from topomap.core.motion.check import keeps_places, outvoted

    def folds(*pairs):
        return [{"misplaced": {"places": p, "views": v}} for p, v in pairs]

    # the last quarter favours the view clusters, the two before it the places by 0.147 and
    # 0.064: two of three each find the places 0.02 or more below, though the mean of the last
    # two (0.3528 against 0.3708) is only 0.018 below
    three = folds((0.5133, 0.4024), (0.1922, 0.3392), (0.5430, 0.6074))
    assert outvoted(three, votes=3, min_gain=0.02)
    assert not keeps_places({"places": 0.3528, "views": 0.3708}, margin=0.9, min_gain=0.02)
    # one part by far (0.264) and one by 0.016, under the least gain: one vote of three
    assert not outvoted(folds((0.8277, 0.712), (0.2084, 0.2248), (0.4451, 0.7089)), 3, 0.02)
    assert outvoted(folds((0.8277, 0.712), (0.2084, 0.2248), (0.4451, 0.7089)), 3, 0.01)
    assert not outvoted(three, votes=0, min_gain=0.02)        # no vote
    assert not outvoted(three[:2], votes=3, min_gain=0.02)    # a part missing: no vote
    assert not outvoted(three[:2], votes=2, min_gain=0.02)    # one of two is not most
    # a default fit holds out three quarters, the mean read on the last two
    Z, u, _ = _alike_halves()
    check = MapLearner(n_clusters=4, n_states=8, random_state=0,
                       motion=FOLDS).fit(Z, u).motion_info_["check"]
    assert [f["learned"] for f in check["folds"]] == [6000, 4000, 2000]
    for name in ("places", "views"):
        pooled = (sum(f["misplaced_steps"][name] for f in check["folds"][:2])
                  / sum(f["referenced"] for f in check["folds"][:2]))
        assert check["mean_misplaced"][name] == pytest.approx(pooled, abs=1e-4)
    assert "outvoted" in check


def _same_partition(a, b) -> bool:
    pairs = np.unique(np.stack([a, b]), axis=1)
    return pairs.shape[1] == np.unique(a).size == np.unique(b).size


def test_a_log_too_short_to_tell_is_not_continuous():
    auto, gds = MotionSettings(), np.full(1200, -1)

    def continuous(symbols, settings=auto, g=gds):
        return is_continuous(settings, symbols, [1200], g)

    assert not continuous(np.zeros(1200, int))                  # one symbol: one run
    assert not continuous(np.repeat([0, 1, 2], 400))            # 3 runs < 2 x 3 symbols
    assert continuous(np.tile(np.repeat([0, 1, 2], 4), 100))    # 300 runs of 4 steps
    assert continuous(np.tile(np.repeat([0, 1, 2], 2), 200))    # runs of 2 steps (a robot)
    assert not continuous(np.tile([0, 1, 2], 400))              # runs of 1 step (a grid)
    assert is_continuous(auto, np.tile([0, 1, 2], 400), [1200], gds, odometry=True)
    assert not is_continuous(auto, np.tile([0, 1, 2], 400), [1200], np.r_[0, gds[1:]],
                             odometry=True)                     # odometry, but a GDS step
    assert not continuous(np.tile(np.repeat([0, 1, 2], 4), 100),
                          MotionSettings(min_steps=1201))        # too short a log
    assert not continuous(np.tile(np.repeat([0, 1, 2], 4), 100),
                          g=np.r_[0, gds[1:]])                   # a GDS step
    assert continuous(np.zeros(1200, int), MotionSettings(mode="continuous"))
    assert not continuous(np.tile(np.repeat([0, 1, 2], 4), 100), MotionSettings(mode="discrete"))


def test_discrete_worlds_keep_the_map_of_the_split():
    traj = GridRoom(6, 5, 4).simulate(3000, RandomExplorer(), np.random.default_rng(0))
    kw = dict(n_clusters=4, n_states=30, random_state=0)
    auto = MapLearner(**kw).fit_trajectory(traj)
    discrete = MapLearner(motion="discrete", **kw).fit_trajectory(traj)
    assert not hasattr(auto, "motion_info_")
    assert auto.map_.to_dict() == discrete.map_.to_dict()


@pytest.mark.parametrize("motion, message", [
    ("bogus", r"^motion\.mode must be one of auto, discrete, continuous"),
    (3, r"^motion must be one of"),
    ({"gate": 3}, r"^motion\.gate is not a motion setting"),
    ({"places": {"gate": 3}}, r"^motion\.places\.gate is not a motion\.places setting"),
    ({"places": 3}, r"^motion\.places must be PlaceSettings or a mapping of its fields"),
    ({"places": {"gates": []}}, r"^motion\.places\.gates must be a non-empty list"),
    (MotionSettings(places={"weight": 0}), r"^motion\.places\.weight must be a positive number"),
    (MotionSettings(places={"pull": 1.5}), r"^motion\.places\.pull must be at most 1"),
    ({"check": {"holdout": 1.0}}, r"^motion\.check\.holdout must be a number in \[0, 1\)"),
    ({"check": {"margin": 0}}, r"^motion\.check\.margin must be a number in \(0, 1\]"),
    ({"check": {"far": -1.0}}, r"^motion\.check\.far must be a positive number"),
    ({"places": {"n_init": 0}}, r"^motion\.places\.n_init must be a positive integer"),
    ({"check": {"folds": 1.5}}, r"^motion\.check\.folds must be a positive integer"),
    ({"places": {"fallback_variance": 2.0}},
     r"^motion\.places\.fallback_variance must be a number in \(0, 1\]"),
    ({"places": {"fallback_variance": 0}},
     r"^motion\.places\.fallback_variance must be a number in \(0, 1\]"),
    ({"check": {"min_gain": -0.1}}, r"^motion\.check\.min_gain must be a number in \[0, 1\)"),
    ({"check": {"votes": -1}}, r"^motion\.check\.votes must be a non-negative integer"),
    ({"check": {"min_copies": 0}}, r"^motion\.check\.min_copies must be a positive number"),
    ({"check": {"confidence": -1.0}}, r"^motion\.check\.confidence must be a number >= 0"),
    ({"check": {"confidence": float("nan")}},
     r"^motion\.check\.confidence must be a number >= 0"),
    ({"check": {"block_runs": 0}}, r"^motion\.check\.block_runs must be a positive number"),
    ({"check": {"min_purity": 1.0}}, r"^motion\.check\.min_purity must be a number in \[0, 1\)"),
    ({"check": {"rule": "cross"}}, r"^motion\.check\.rule must be one of bootstrap, coverage, crossfit, folds"),
])
def test_bad_motion_is_named(motion, message):
    Z, u, _ = _alike_halves(500)
    learner = MapLearner(n_clusters=4, n_states=8, motion=motion)
    with pytest.raises(ParameterError, match=message):
        learner.check_params()
    with pytest.raises(ParameterError, match=message):
        learner.fit(Z, u)
    assert not hasattr(learner, "map_")  # nothing half-written


def test_place_features_weigh_the_positions_beside_the_view():
    from topomap.core.motion.places import place_features

    views = np.array([[0.0], [0.0]])
    # three gates, each putting the second step 2 cell extents east of the first
    positions = [np.array([[0.0, 0.0], [2.0, 0.0]])] * 3
    F = place_features(views, positions, 0.5)
    assert F.shape == (2, 1 + 2 * 3)
    # the gates share the weight: the squared distance is 0.5**2 times the positions' mean one
    assert np.linalg.norm(F[1] - F[0]) == pytest.approx(0.5 * 2.0)



def _places_of_two_rooms_of_two_views(weight):
    """Two alike rooms 20 cell extents apart; in each, steps of two views one cluster's extent
    apart, drift putting either view at reckoned x = 0 or 1.6 cell extents (ten steps of every
    view, position and room); two places a room.  Within a room the four kinds of step are the
    corners of a rectangle 1 (view) by 1.6 * weight (position): 2-means cuts it across its
    longer side, so by the view where 1.6 * weight < 1.  Returns, for the keys ``room``,
    ``view`` and ``x``, whether the places are exactly the steps alike in the given keys."""
    from sklearn.cluster import KMeans
    from topomap.core.motion.places import place_features

    view, x, room = (np.repeat(a.ravel(), 10) for a in np.meshgrid([0.0, 1.0], [0.0, 1.6],
                                                                     [0.0, 20.0]))
    P = np.column_stack([x + room, np.zeros_like(x)])
    labels = KMeans(4, n_init=10, random_state=0).fit_predict(
        place_features(view[:, None], [P, P, P], weight))
    keys = {"room": room, "view": view, "x": x}

    def alike_in(*names):
        kinds = np.unique(np.column_stack([keys[n] for n in names]), axis=0,
                          return_inverse=True)[1].ravel()
        return all(np.unique(labels[kinds == k]).size == 1 for k in np.unique(kinds)) and \
            np.unique(labels).size == np.unique(kinds).size
    return alike_in


def test_places_follow_the_view_where_drift_is_a_cell_or_so_and_keep_alike_rooms_apart():
    # the weight where odometry is loose (0.5): 1.6 * 0.5 < 1, the places are each room's views
    assert _places_of_two_rooms_of_two_views(MotionSettings().places.loose_weight)("room", "view")
    # at weight 1 (the default's own): 1.6 > 1, each room's drifted positions, views mixed
    assert _places_of_two_rooms_of_two_views(MotionSettings().places.weight)("room", "x")


def test_the_positions_weigh_less_where_the_odometry_closes_loops_loosely():
    from topomap.core.motion.places import position_weight

    s = MotionSettings(places={"weight": 1.0, "loose_return": 0.26, "loose_weight": 0.5})
    assert position_weight(s, [0.2, 0.25]) == 1.0    # both returns within 0.26: tight
    assert position_weight(s, [0.2, 0.26]) == 1.0    # at the bar: still tight
    assert position_weight(s, [0.2, 0.3]) == 0.5     # the weaker direction keeps 0.3: loose
    assert position_weight(s, [0.3, 0.2]) == 0.5     # whichever direction it is


def test_the_held_out_parts_cut_their_places_with_the_whole_logs_weight():
    from topomap.core.motion.places import cut_places

    Z, u, _ = _alike_halves(2000)
    whole = cut_places(MotionSettings(), Z, u, [u.size], 8, 2)
    # a walk on a line: the odometry keeps one direction, and its return ratio is the one read
    assert not np.asarray(whole.info["action_vectors"])[:, 1].any()
    ratio = whole.info["return_ratios"][0]
    loose = cut_places(MotionSettings(places={"loose_return": ratio / 2}), Z, u, [u.size], 8, 2)
    tight = cut_places(MotionSettings(places={"loose_return": ratio * 1.001}), Z, u, [u.size], 8, 2)
    assert loose.info["weight"] == 0.5 and tight.info["weight"] == 1.0
    # a given weight wins over the log's own (what the held-out check passes on)
    given = cut_places(MotionSettings(places={"loose_return": ratio / 2}), Z, u, [u.size], 8, 2,
                       weight=1.0)
    assert given.info["weight"] == 1.0
    np.testing.assert_array_equal(given.places, tight.places)
    # the check's first part (the first 1,500 steps) closes its loops a little more loosely
    # than the whole log: a bar between the two leaves the whole log tight, and the parts
    # cut with the whole log's weight, not their own
    part = cut_places(MotionSettings(), Z[:1500], u[:1500], [1500], 8, 2)
    bar = (ratio + part.info["return_ratios"][0]) / 2
    assert part.info["return_ratios"][0] > bar > ratio
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0,
                         motion=MotionSettings(places={"loose_return": bar},
                                                 check={"rule": "folds"})).fit(Z, u)
    folds = learner.motion_info_["check"]["folds"]
    assert learner.motion_info_["weight"] == 1.0 and folds
    assert all(f["weight"] == 1.0 for f in folds)


def test_places_at_the_default_weight_are_checked_where_the_loosely_weighted_ones_give_way():
    Z, u, x = _alike_halves()
    # every log loose (a bar of 0.001), its loose weight so small that the places are all but
    # the view clusters, which cannot tell the alike halves apart: the check gives them up,
    # and the places at weight 1 -- those the check keeps on this log -- are checked in turn
    motion = MotionSettings(places={"loose_return": 0.001, "loose_weight": 0.01},
                            check={"rule": "folds"})
    learner = MapLearner(n_clusters=4, n_states=8, random_state=0, motion=motion).fit(Z, u)
    info = learner.motion_info_
    assert info["loose"]["weight"] == 0.01 and info["loose"]["chosen"] == "views"
    assert info["chosen"] == "places" and info["weight"] == 1.0
    assert _mixed_share(learner.labels_, x) < 0.02
    # no second try where the default weight is the loose one
    same = MotionSettings(places={"loose_return": 0.001, "loose_weight": 1.0},
                          check={"rule": "folds"})
    info = MapLearner(n_clusters=4, n_states=8, random_state=0, motion=same).fit(Z, u).motion_info_
    assert "loose" not in info and info["chosen"] == "places"
