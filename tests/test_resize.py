"""Bringing a refined labelling to the told number of states (topomap.core.refine.resize)."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.metrics import adjusted_rand
from topomap.core.refine.resize import _merge_loss, _pairs, _relabel, merge_to, resize, split_to
from topomap.core.split.criteria import EntropyCriterion
from topomap.core.stats import count_tables, episode_masks


#: the symbols of a 6-place ring: each symbol at two places, told apart by their neighbours
#: (no rotation maps the ring onto itself)
SYMS = np.array([0, 1, 0, 2, 1, 2])


def ring_walk(n_places=6, T=800, seed=0):
    """Places 0..n-1 on a ring, walked at random: action 0 steps forward, 1 back."""
    rng = np.random.default_rng(seed)
    x, places, acts = 0, [], []
    for _ in range(T):
        a = int(rng.integers(2))
        places.append(x)
        acts.append(a)
        x = (x + (1 if a == 0 else -1)) % n_places
    return np.array(places), np.array(acts)


def test_merging_rejoins_the_duplicates_of_a_place():
    places, u = ring_walk()
    # each place's steps dealt at random to two states of its symbol: 12 states for 6 places
    rng = np.random.default_rng(1)
    labels = places * 2 + rng.integers(2, size=places.size)
    state_symbol = SYMS[np.arange(12) // 2]
    has_next = episode_masks(places.size, [places.size])[1]
    out, sym, merged = merge_to(labels, state_symbol, u, 2, has_next, 6, np.full(12, -1))
    assert merged == 6 and sym.size == 6
    assert adjusted_rand(places, out) == 1.0
    assert all(sym[out[t]] == SYMS[places[t]] for t in range(places.size))


def test_merging_never_joins_symbols_or_gds_states():
    places, u = ring_walk()
    has_next = episode_masks(places.size, [places.size])[1]
    gds = np.full(6, -1)
    gds[[0, 2]] = [4, 9]  # the two places of symbol 0 are GDS 4 and 9: never merged
    out, sym, merged = merge_to(places, SYMS, u, 2, has_next, 1, gds)
    assert merged == 2 and sorted(sym.tolist()) == [0, 0, 1, 2]
    assert len(np.unique(out[places == 0])) == 1 and out[places == 0][0] != out[places == 2][0]


def _brute_force_merges(labels, state_symbol, u, has_next, n_target):
    """Every pair's loss recomputed after every merge; the least (then the smallest pair) wins."""
    is_gds = np.zeros(state_symbol.size, bool)
    while state_symbol.size > n_target:
        _, N, C = count_tables(labels, u, state_symbol.size, 2, has_next)
        pairs = _pairs(state_symbol, is_gds)
        if not pairs:
            break
        i, j = min(pairs, key=lambda p: (_merge_loss(C, N, *p), p))
        labels, state_symbol = _relabel(labels, state_symbol, i, j)
        is_gds = np.delete(is_gds, j)
    return labels, state_symbol


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cached_losses_give_the_brute_force_merges(seed):
    places, u = ring_walk(n_places=9, T=600, seed=seed)
    rng = np.random.default_rng(seed)
    labels = places * 3 + rng.integers(3, size=places.size)  # 27 states, 3 per place
    state_symbol = (np.arange(27) // 3) % 3
    has_next = episode_masks(places.size, [places.size])[1]
    want = _brute_force_merges(labels, state_symbol, u, has_next, 5)
    got = merge_to(labels, state_symbol, u, 2, has_next, 5, np.full(27, -1))
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def test_splitting_separates_a_compound_state():
    places, u = ring_walk()
    labels = SYMS[places]  # the aliased pairs share a state: 3 states for 6 places
    masks = episode_masks(places.size, [places.size])
    out, sym, n_split = split_to(labels, np.arange(3), u, 2, masks, 6, np.full(3, -1),
                                 EntropyCriterion())
    assert n_split == 3 and adjusted_rand(places, out) == 1.0


def test_resize_says_what_it_did():
    places, u = ring_walk()
    masks = episode_masks(places.size, [places.size])
    _, sym, info = resize(places, SYMS, u, 2, masks, 6, np.full(6, -1), EntropyCriterion())
    assert info == {"from": 6, "to": 6, "merged": 0, "split": 0} and sym.size == 6


def test_resize_merges_the_duplicates_of_every_place():
    """Each place's steps dealt at random to two states of its symbol (12 states): the two
    halves of a place have one future, so the six least costly merges rejoin the places."""
    places, u = ring_walk()
    masks = episode_masks(places.size, [places.size])
    labels = places * 2 + np.random.default_rng(2).integers(2, size=places.size)
    out, sym, info = resize(labels, SYMS[np.arange(12) // 2], u, 2, masks, 6, np.full(12, -1),
                            EntropyCriterion())
    assert info == {"from": 12, "to": 6, "merged": 6, "split": 0}
    assert adjusted_rand(places, out) == 1.0 and np.array_equal(sym[out], SYMS[places])


def test_resize_splits_the_aliased_places_apart():
    """One state per symbol (3 states, each two places of the ring): the paper's split tells the
    two places of a symbol apart by their neighbours, three splits to six states."""
    places, u = ring_walk()
    masks = episode_masks(places.size, [places.size])
    out, sym, info = resize(SYMS[places], np.arange(3), u, 2, masks, 6, np.full(3, -1),
                            EntropyCriterion())
    assert info == {"from": 3, "to": 6, "merged": 0, "split": 3}
    assert adjusted_rand(places, out) == 1.0 and np.array_equal(sym[out], SYMS[places])


def test_resize_leaves_gds_states_whole():
    """Place 0 is GDS 5 (symbol 0's other place, 2, is not).  Asked for 2 states, the merges
    join the two places of symbols 1 and 2 and stop there, at 4 states: the GDS state is never
    merged with place 2.  With the GDS state holding place 2's steps too (a compound state, the
    only one), a split to 7 states never splits it."""
    places, u = ring_walk()
    masks = episode_masks(places.size, [places.size])
    gds = np.array([5, -1, -1, -1, -1, -1])
    out, sym, info = resize(places, SYMS, u, 2, masks, 2, gds, EntropyCriterion())
    assert info == {"from": 6, "to": 4, "merged": 2, "split": 0}
    assert len(np.unique(out[(places == 0) | (places == 2)])) == 2
    labels = np.where(places == 2, 0, places)
    out, _, info = resize(labels, SYMS, u, 2, masks, 7, gds, EntropyCriterion())
    assert info["to"] == 7 and np.unique(out[labels == 0]).tolist() == [0]


def _ring_observations(places, seed=0):
    rng = np.random.default_rng(seed)
    return np.eye(3)[SYMS[places]] + 0.01 * rng.standard_normal((places.size, 3))


@pytest.mark.parametrize("told", [5, 8])
def test_the_refined_map_has_the_told_size(told):
    places, u = ring_walk()
    X = _ring_observations(places)
    learner = MapLearner(n_clusters=3, n_states=told, refine="em", random_state=0).fit(X, u)
    assert learner.map_.n_states == told
    free = MapLearner(n_clusters=3, n_states=told, refine="em", refined_size="free",
                      random_state=0).fit(X, u)
    assert free.map_.n_states == 6  # the refinement alone finds the six places
    assert adjusted_rand(places, free.labels_) == 1.0


def test_refined_size_is_checked():
    with pytest.raises(ValueError, match="^refined_size must be 'told' or 'free'"):
        MapLearner(refined_size="exact").fit(np.zeros((5, 2)), np.zeros(5, int))


def test_auto_chooses_the_refined_size_on_held_out_steps():
    places, u = ring_walk(T=3000)
    X = _ring_observations(places)
    # heading="off": the ring's two moves return a view after six repetitions, so the default
    # would start from (symbol, position) pairs, six of them, and try no size below six
    learner = MapLearner(n_clusters=3, n_states="auto", refine="em", heading="off",
                         random_state=0).fit(X, u)
    choice = learner.size_choice_["refined"]
    assert set(choice["scores"]) >= {3, 6, 12} and choice["own"] == 6
    assert choice["chosen"] == max(choice["scores"], key=choice["scores"].get) == 6
    assert learner.map_.n_states == 6 and adjusted_rand(places, learner.labels_) == 1.0


def test_auto_with_a_free_size_scores_nothing_more():
    places, u = ring_walk(T=3000)
    X = _ring_observations(places)
    learner = MapLearner(n_clusters=3, n_states="auto", refine="em", refined_size="free").fit(X, u)
    assert "refined" not in learner.size_choice_
