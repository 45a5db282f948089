"""MapLearner.partial_fit: the map learned while the steps arrive (topomap.core.online)."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap import MapLearner
from topomap.core import online, online_pass
from topomap.core.online import CONTEXT, decode_symbols
from topomap.worlds import GridRoom, RandomExplorer


def walk(width, height, n_symbols, n_steps, seed):
    room = GridRoom(width=width, height=height, n_symbols=n_symbols)
    return room.simulate(n_steps, RandomExplorer(), np.random.default_rng(seed))


def feed(learner, traj, chunk, **kw):
    X, u = traj.observations, traj.actions
    for i in range(0, len(u), chunk):
        learner.partial_fit(X[i:i + chunk], u[i:i + chunk], n_actions=traj.n_actions, **kw)
    return learner


def test_decode_symbols_tells_aliased_states_apart_by_what_follows():
    # symbol 0 has two states: state 0 goes to state 2 (symbol 1) under action 0 and state 2
    # comes back to 0 under action 1; state 1 goes to 3 (symbol 2) and back: two cycles.  The
    # state of an episode's first step is told by the symbol after it.
    trans = np.zeros((4, 2, 4))
    trans[0, 0, 2] = trans[1, 0, 3] = trans[2, 1, 0] = trans[3, 1, 1] = 10
    state_id = np.array([0, 0, 1, 2])
    ids = np.array([0, 2, 0, 2, 0, 1, 0, 1])
    u = np.array([0, 1, 0, 1, 0, 1, 0, 1])
    starts = np.array([1, 0, 0, 0, 1, 0, 0, 0], dtype=bool)
    labels = decode_symbols(ids, u, starts, state_id, trans, n_ids=3)
    assert labels.tolist() == [1, 3, 1, 3, 0, 2, 0, 2]


def test_decode_symbols_leaves_unknown_ids_out():
    trans = np.ones((2, 1, 2))
    labels = decode_symbols(np.array([0, 5, 1]), np.zeros(3, int), np.array([1, 0, 0], bool),
                            np.array([0, 1]), trans, n_ids=2)
    assert labels.tolist() == [0, -1, 1]


def test_online_recovers_the_places_of_a_room_without_aliasing():
    # 12 cells, 12 symbols: every state is one cell, so the right labels are the places
    traj = walk(4, 3, 12, 3000, seed=1)
    learner = feed(MapLearner(12, 12, window=1000, refit_every=500), traj, chunk=250)
    assert learner.labels_.shape == (3000,)
    assert adjusted_rand_score(traj.places, learner.labels_) == 1.0


@pytest.mark.parametrize("refine", [None, "em"])
def test_online_and_batch_agree_on_an_aliased_room(refine):
    traj = walk(5, 4, 3, 6000, seed=2)
    batch = MapLearner(3, 20, refine=refine).fit(traj.observations, traj.actions, n_actions=4)
    # passes every 1000 steps, 400 steps a call: the last 800 steps are decoded chunks
    learner = feed(MapLearner(3, 20, refine=refine, window=6000, refit_every=1000), traj, 400)
    a_batch = adjusted_rand_score(traj.places, batch.labels_)
    a_online = adjusted_rand_score(traj.places, learner.labels_)
    assert a_online >= a_batch - 0.02
    if refine == "em":  # the refinement finds the cells, online too
        assert a_batch == 1.0 and a_online == 1.0


@pytest.mark.parametrize("seed", [3, 4, 6])
def test_passes_started_from_the_last_map_find_the_cells_of_an_aliased_room(seed):
    # 20 cells showing 3 symbols; the window (2000 steps) holds a third of the walk, so the
    # passes after the one at 2000 steps start EM from the last map's states: online as batch
    # finds the cells (with EM started afresh on every window, ARI 0.921, 0.928 and 0.943)
    traj = walk(5, 4, 3, 6000, seed=seed)
    batch = MapLearner(3, 20, refine="em").fit(traj.observations, traj.actions, n_actions=4)
    learner = feed(MapLearner(3, 20, refine="em", window=2000, refit_every=1000), traj, 400)
    assert learner.refine_info_["warm_start"] and learner.online_["pass_from"] > 0
    assert adjusted_rand_score(traj.places, batch.labels_) == 1.0
    assert adjusted_rand_score(traj.places, learner.labels_) == 1.0


def test_only_em_starts_a_pass_from_the_last_map():
    # CSCG's EM starts from its own random clones: its passes on a window that has lost steps
    # start afresh, and its soft check is made again (no evidence switched to hard)
    traj = walk(5, 4, 3, 3000, seed=3)
    learner = feed(MapLearner(3, 20, refine="cscg", window=1000, refit_every=1000), traj, 500)
    assert learner.online_["pass_from"] > 0
    assert "warm_start" not in learner.refine_info_ and "soft_from" not in learner.refine_info_


@pytest.mark.parametrize("refine, passes", [
    # every 500 steps after the doubling start
    (None, [250, 500, 1000, 1500, 2000, 2500, 3000, 3500, 4000, 4500, 5000]),
    # with EM: the pass at 1500 steps saw more than half the window (2500), the next comes when
    # the window is full; then every 500 again
    ("em", [250, 500, 1000, 1500, 2500, 3000, 3500, 4000, 4500, 5000]),
])
def test_with_em_no_pass_comes_between_half_the_window_and_the_full_window(refine, passes):
    traj = walk(4, 3, 3, 5000, seed=6)
    learner = MapLearner(3, 12, refine=refine, window=2500, refit_every=500)
    seen = []
    for i in range(0, 5000, 250):
        learner.partial_fit(traj.observations[i:i + 250], traj.actions[i:i + 250], n_actions=4)
        seen += [i + 250] if learner.online_["last_work"]["pass"] else []
    assert seen == passes


def test_warm_labelling_gives_a_state_to_every_old_state_and_symbol():
    # steps of old states 0, 0, 1, none, 1, none, 2 showing symbols 3, 3, 1, 1, 2, 3, 1: the
    # pairs sorted by (old state + 1, symbol) are (none, 1), (none, 3), (0, 3), (1, 1), (1, 2),
    # (2, 1) -- old state 1 shows two symbols, so it becomes two states
    labels, state_symbol = online_pass.warm_labelling([0, 0, 1, -1, 1, -1, 2],
                                                      [3, 3, 1, 1, 2, 3, 1])
    assert labels.tolist() == [2, 2, 3, 0, 4, 1, 5]
    assert state_symbol.tolist() == [1, 3, 3, 1, 2, 1]


def test_labels_and_map_follow_every_call():
    traj = walk(5, 4, 3, 2100, seed=3)
    learner = MapLearner(3, 20, window=1000, refit_every=600)
    seen = 0
    for chunk in (300, 300, 500, 1000):
        learner.partial_fit(traj.observations[seen:seen + chunk], traj.actions[seen:seen + chunk],
                            n_actions=4)
        seen += chunk
        assert learner.labels_.shape == (seen,) and (learner.labels_ >= 0).all()
        assert learner.online_["n_steps"] == seen
        assert learner.labels_.max() < learner.map_.n_states  # states of the current map
        # the map's counts: every step the last pass learned from and every step decoded since,
        # and every transition between two of them inside the walk (one episode here)
        since = learner.labels_[learner.online_["pass_from"]:]
        assert learner.map_.state_counts.sum() == since.size
        assert learner.map_.transition_counts.sum() == since.size - 1


def test_a_call_touches_its_own_steps_not_those_before():
    traj = walk(5, 4, 3, 24000, seed=4)
    X, u = traj.observations, traj.actions
    works = {}
    for before in (4000, 20000):
        learner = MapLearner(3, 20, window=3000, refit_every=5000)
        learner.partial_fit(X[:before], u[:before], n_actions=4)  # a pass on the last 3000
        # the steps before the window are decoded with the pass's map
        assert learner.online_["last_work"] == {"decoded": before - 3000, "pass": 3000,
                                                "relabelled": 0}
        learner.partial_fit(X[before:before + 700], u[before:before + 700])
        works[before] = learner.online_["last_work"]
    assert works[4000] == works[20000] == {"decoded": 700 + CONTEXT, "pass": 0, "relabelled": 0}


def test_memory_beyond_the_per_step_record_is_bounded():
    traj = walk(5, 4, 3, 20000, seed=5)
    X, u = traj.observations, traj.actions
    learner = MapLearner(3, 20, window=2000, refit_every=1000)
    mem = []
    for i in range(0, 20000, 1000):
        learner.partial_fit(X[i:i + 1000], u[i:i + 1000], n_actions=4)
        mem.append(learner.online_["memory"])
    assert mem[5]["window"] == mem[-1]["window"]  # the window holds 2000 steps from then on
    assert mem[-1]["per_step"] >= 5 * 4 * 20000  # symbol, action, GDS, start, label: int32 each
    assert mem[-1]["per_step"] <= 2 * 5 * 4 * 20000  # grown by doubling at most


def test_new_episode_cuts_the_transition():
    traj = walk(4, 3, 12, 600, seed=6)
    X, u = traj.observations, traj.actions
    a = MapLearner(12, 12, refit_every=10000)
    a.partial_fit(X[:300], u[:300], n_actions=4)
    b = MapLearner(12, 12, refit_every=10000)
    b.partial_fit(X[:300], u[:300], n_actions=4)
    a.partial_fit(X[300:], u[300:])
    b.partial_fit(X[300:], u[300:], new_episode=True)
    diff = a.map_.transition_counts - b.map_.transition_counts
    assert diff.sum() == 1 and diff[a.labels_[299], u[299], a.labels_[300]] == 1


def test_a_bad_chunk_is_refused_and_loses_nothing():
    traj = walk(4, 3, 12, 600, seed=7)
    X, u = traj.observations, traj.actions
    learner = MapLearner(12, 12).partial_fit(X[:400], u[:400], n_actions=4)
    before = learner.labels_.copy()
    bad = X[400:].copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError, match="observations contain NaN"):
        learner.partial_fit(bad, u[400:])
    with pytest.raises(ValueError, match="features"):
        learner.partial_fit(X[400:, :5], u[400:])
    assert learner.online_["n_steps"] == 400
    np.testing.assert_array_equal(learner.labels_, before)
    learner.partial_fit(X[400:], u[400:])
    assert learner.labels_.shape == (600,)


def test_a_failed_first_pass_keeps_nothing():
    traj = walk(4, 3, 12, 100, seed=8)
    learner = MapLearner(3, 2)  # fewer states than phase 1's symbols
    with pytest.raises(ValueError, match="n_states=2"):
        learner.partial_fit(traj.observations[:5], traj.actions[:5], n_actions=4)
    assert [name for name in vars(learner) if name.endswith("_")] == []  # nothing learned
    learner.set_params(n_states=12).partial_fit(traj.observations[5:], traj.actions[5:],
                                                n_actions=4)
    assert learner.online_["n_steps"] == 95 and learner.labels_.shape == (95,)


def test_a_failed_pass_keeps_the_map_before_it():
    traj = walk(4, 3, 12, 600, seed=8)
    X, u = traj.observations, traj.actions
    learner = MapLearner(12, 12, refit_every=100).partial_fit(X[:300], u[:300], n_actions=4)
    m, labels = learner.map_, learner.labels_.copy()
    learner.set_params(n_states=5)  # below the 12 states of phase 1: the next pass fails
    with pytest.raises(ValueError, match="n_states=5 is below the 12 states"):
        learner.partial_fit(X[300:], u[300:])
    assert learner.map_ is m and learner.online_["n_steps"] == 300
    assert np.array_equal(learner.labels_, labels) and learner.split_history_ == []


def test_n_actions_may_grow_on_any_call():
    traj = walk(4, 3, 12, 600, seed=11)
    X, u = traj.observations, traj.actions
    learner = MapLearner(12, 12, refit_every=10000).partial_fit(X[:300], u[:300])
    assert learner.map_.n_actions == 4
    learner.partial_fit(X[300:400], u[300:400], n_actions=6)  # two actions not taken yet
    assert learner.map_.n_actions == 6 and learner.online_["n_passes"] == 2
    with pytest.raises(ValueError, match="n_actions is 5 but the steps use 6 actions"):
        learner.partial_fit(X[400:], u[400:], n_actions=5)


def test_fit_starts_over_and_settings_are_checked():
    traj = walk(4, 3, 12, 600, seed=9)
    X, u = traj.observations, traj.actions
    learner = MapLearner(12, 12).partial_fit(X[:300], u[:300], n_actions=4)
    learner.fit(X, u)
    assert learner.labels_.shape == (600,)
    with pytest.raises(AttributeError):
        learner.online_
    with pytest.raises(ValueError, match="window"):
        MapLearner(12, 12, window=0).partial_fit(X, u)
    with pytest.raises(ValueError, match="refit_every"):
        MapLearner(12, 12, refit_every=-1).partial_fit(X, u)


def test_auto_size_online():
    traj = walk(4, 3, 4, 4000, seed=10)
    learner = feed(MapLearner(4, "auto", refine="em", window=2000, refit_every=1000), traj, 500)
    assert "chosen" in learner.size_choice_
    assert adjusted_rand_score(traj.places, learner.labels_) > 0.9


def test_a_walk_the_window_holds_is_learned_as_fit_learns_it():
    # every call of 1000 steps makes a pass (refit_every 1000) on all steps seen, K-means
    # included: after the last, the online map is the batch map of the same steps
    traj = walk(5, 4, 3, 3000, seed=4)
    batch = MapLearner(3, 20).fit(traj.observations, traj.actions, n_actions=4)
    learner = feed(MapLearner(3, 20, window=5000, refit_every=1000), traj, chunk=1000)
    assert learner.online_["n_passes"] == 3
    assert np.array_equal(learner.labels_, batch.labels_)
    assert np.array_equal(learner.map_.transition_counts, batch.map_.transition_counts)


def test_symbols_are_fixed_once_steps_leave_the_window():
    traj = walk(5, 4, 3, 4000, seed=5)
    learner = MapLearner(3, 20, window=1500, refit_every=500)
    X = traj.observations + np.random.default_rng(0).normal(0, 0.05, traj.observations.shape)
    u = traj.actions
    codebooks = []
    for i in range(0, 4000, 500):
        learner.partial_fit(X[i:i + 500], u[i:i + 500], n_actions=4)
        codebooks.append(learner._online.codebook.means.copy())
    # passes at 500, 1000 and 1500 steps see every step and re-learn the symbols; from 2000 on
    # the window has lost steps and the codebook of the pass at 1500 stays
    assert not np.array_equal(codebooks[0], codebooks[2])
    assert all(np.array_equal(codebooks[2], c) for c in codebooks[3:])
    assert learner.online_["n_passes"] == 8


def test_majority_match_gives_each_state_the_state_most_of_its_steps_hold():
    from topomap.core.stats import majority_match

    a = np.array([0, 0, 0, 1, 1, 2, -1, 3])
    b = np.array([3, 3, 1, 0, 0, -1, 2, 2])
    # state 0: two steps in 3, one in 1; 1: both in 0; 2: its step has none; 3: in 2
    assert majority_match(a, b, 5, 4).tolist() == [3, 0, -1, 2, -1]


def test_a_warm_start_skips_the_soft_check_only_after_a_map_that_needed_none():
    from topomap.core.refine.methods import EMRefinement

    em, old, sym = EMRefinement(), np.array([0, 1, 1, -1]), np.array([0, 1, 1, 0])
    assert online_pass.warm_start(em, None, sym) == (em, None)
    assert online_pass.warm_start(em, online_pass.PassStart(), sym) == (em, None)
    runner, (labels, state_symbol) = online_pass.warm_start(
        em, online_pass.PassStart(old, exact=True), sym)
    # the last map's refinement skipped the soft rounds: a copy reading the symbols as exact
    assert runner is not em and runner.evidence == "hard" and em.evidence == "auto"
    assert labels.tolist() == [1, 2, 2, 0] and state_symbol.tolist() == [0, 0, 1]
    assert online_pass.warm_start(em, online_pass.PassStart(old), sym)[0] is em
    soft = EMRefinement(evidence="soft")
    assert online_pass.warm_start(soft, online_pass.PassStart(old, True), sym)[0] is soft
    other = object()  # not a built-in refinement: no warm start
    assert online_pass.warm_start(other, online_pass.PassStart(old, True), sym) == (other, None)


def cycle(n_steps):
    """A walk round 4 cells showing 4 symbols, one action: 4 states, no aliasing."""
    cells = np.arange(n_steps) % 4
    return np.eye(4)[cells], np.zeros(n_steps, dtype=np.int64)


@pytest.mark.parametrize("n_steps, refined", [(7, False), (8, True)])
def test_a_pass_refines_only_with_two_steps_per_state(n_steps, refined):
    # the split has 4 states (4 symbols, nothing aliased): 7 steps are fewer than 2 per state,
    # so the pass keeps the split; 8 are exactly 2 per state, so it refines as fit does
    X, u = cycle(n_steps)
    learner = MapLearner(4, 4, refine="em").partial_fit(X, u, n_actions=1)
    assert learner.map_.n_states == 4
    assert hasattr(learner, "refine_info_") == refined
    assert ("refine" in learner.map_.info) == refined
    assert "refine" in MapLearner(4, 4, refine="em").fit(X, u, n_actions=1).map_.info


def test_a_pass_afresh_makes_the_soft_check_as_fit_makes_it():
    # passes at 8 and 16 steps, both on every step seen: the first one's refinement finds no
    # misread symbols, yet the second (afresh, not from the last map) makes its own soft check,
    # so its map is fit's, refine_info_ included
    X, u = cycle(16)
    learner = MapLearner(4, 4, refine="em", window=100, refit_every=8)
    learner.partial_fit(X[:8], u[:8], n_actions=1)
    assert learner.refine_info_["soft"] == "skipped"
    learner.partial_fit(X[8:], u[8:])
    assert learner.online_["n_passes"] == 2 and learner.online_["pass_from"] == 0
    batch = MapLearner(4, 4, refine="em").fit(X, u, n_actions=1)
    assert learner.refine_info_ == batch.refine_info_ and "soft_from" not in batch.refine_info_
    assert np.array_equal(learner.labels_, batch.labels_)


def test_a_pass_from_the_last_map_makes_no_split_and_guards_against_the_map_it_starts_from():
    # 4 cells in a cycle showing symbols 0, 0, 1, 1: the split tells the two cells of each
    # symbol apart (2 splits).  Window 8: the pass at 16 steps has lost the first 8 and starts
    # EM from the last map, whose 4 states each show one symbol, so it starts from 4 states (one
    # per old state and symbol) and makes no split; the guard compares the refined map with them
    cells = np.arange(16) % 4
    X, u = np.eye(2)[cells // 2], np.zeros(16, dtype=np.int64)
    learner = MapLearner(2, 4, refine="em", window=8, refit_every=8)
    learner.partial_fit(X[:8], u[:8], n_actions=1)
    assert len(learner.split_history_) == 2 and learner.map_split_.n_states == 4
    learner.partial_fit(X[8:], u[8:])
    assert learner.online_["pass_from"] == 8 and learner.refine_info_["warm_start"]
    assert learner.split_history_ == [] and learner.stop_reason_ == "started from the last map"
    assert learner.map_split_.n_states == 4
    assert learner.map_split_.info["stop_reason"] == "started from the last map"
    assert learner.refine_info_["kept"] == "refined"
    assert sorted(learner.map_.info["refined_from"]) == [0, 1, 2, 3]
    assert adjusted_rand_score(cells, learner.labels_) == 1.0


@pytest.mark.parametrize("exact", [True, False])
def test_em_continued_from_the_batch_maps_states_gives_the_batch_map(exact):
    # a pass from the last map, given the batch map's own states: EM starts at its optimum
    # (the 20 cells of an aliased room) and stays there, with no split, soft check or not
    from topomap.core.data.trajectory import check_fit_data

    traj = walk(5, 4, 3, 6000, seed=2)
    X, u = traj.observations, traj.actions
    batch = MapLearner(3, 20, refine="em").fit(X, u, n_actions=4)
    assert adjusted_rand_score(traj.places, batch.labels_) == 1.0
    data = check_fit_data(X, u, None, None, 4, None, None)
    start = online_pass.PassStart(batch.labels_.astype(np.int64), exact)
    warm = MapLearner(3, 20, refine="em")._fit(data, batch.labels_phase1_, motion=False,
                                               warm=start)
    assert warm.refine_info_["warm_start"] and warm.split_history_ == []
    assert warm.map_.n_states == 20
    assert adjusted_rand_score(batch.labels_, warm.labels_) == 1.0
