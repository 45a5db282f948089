"""Phase 2 at scale: the incremental engine and the compiled merge give the plain numpy results,
bit for bit (tests/reference_splitting.py holds the numpy code that rebuilds everything)."""

import numpy as np
import pytest
import reference_splitting as ref
from hypothesis import given, settings
from hypothesis import strategies as st

from topomap.core.sums import pairwise_sum, sparse_pairwise_sum
from topomap.core.split.criteria import EntropyCriterion
from topomap.core.split.engine import Splitter, merge_groups
from topomap.core.stats import (conditional_entropy, count_tables, episode_masks,
                                sparse_conditional_entropy, weighted_entropy)


def bits(x):
    return np.asarray(x, dtype=np.float64).view(np.int64)


def wild(rng, shape):
    """Values over a wide range of magnitudes, so the order of additions shows in the result."""
    return rng.standard_normal(shape) * np.exp(rng.uniform(-20, 20, shape))


@pytest.mark.parametrize("n", list(range(1, 140)) + [255, 1000, 8193, 100003])
def test_pairwise_sum_is_numpys_sum(n):
    a = wild(np.random.default_rng(n), n)
    assert bits(0.0 + pairwise_sum(a, 0, n)) == bits(a.sum())


@pytest.mark.parametrize("n,density", [(10, 0.5), (200, 0.1), (9000, 0.01), (300_000, 0.002),
                                       (1000, 1.0), (50, 0.0)])
def test_sparse_pairwise_sum_is_the_dense_sum(n, density):
    rng = np.random.default_rng(n)
    dense = np.zeros(n)
    pos = np.flatnonzero(rng.random(n) < density)
    dense[pos] = -np.abs(wild(rng, pos.size))
    assert bits(sparse_pairwise_sum(pos, dense[pos], n)) == bits(dense.sum())


@pytest.mark.parametrize("seed", range(15))
def test_sparse_conditional_entropy_is_the_dense_one(seed):
    rng = np.random.default_rng(seed)
    S, A = int(rng.integers(2, 80)), int(rng.integers(1, 18))
    dense = rng.integers(1, rng.integers(2, 5000), (S * A, S)) * (rng.random((S * A, S)) < 0.05)
    r, c = np.nonzero(dense)
    codes, n = (r << 32) | c, dense[r, c]
    assert bits(sparse_conditional_entropy(codes, n, (S * A, S))) == bits(conditional_entropy(dense))


counts_strategy = st.integers(0, 10**6).flatmap(lambda seed: st.tuples(
    st.just(seed), st.integers(2, 30), st.integers(1, 25), st.sampled_from([2, 4, 30, 1000])))


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(counts_strategy)
def test_compiled_merge_is_the_numpy_merge(args):
    seed, G, K, high = args
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, high, (G, K)) * (rng.random((G, K)) < rng.uniform(0.1, 1))
    if rng.random() < 0.3:  # duplicated rows: exact ties
        counts[rng.integers(0, G, G // 2)] = counts[0]
    counts[counts.sum(1) == 0, 0] = 1
    side = merge_groups(counts)
    assert np.array_equal(side, ref.merge_groups(counts))
    halves = np.stack([counts[~side].sum(axis=0), counts[side].sum(axis=0)])
    gain = (weighted_entropy(halves.sum(axis=0))[0] - weighted_entropy(halves).sum()) / counts.sum()
    assert bits(EntropyCriterion().propose(counts)[1]) == bits(max(gain, 0.0))


def test_merge_groups_hand_cases():
    assert merge_groups(np.array([[10, 0], [9, 1], [0, 10]])).tolist() == [False, False, True]
    assert merge_groups(np.array([[5, 0], [5, 0], [5, 0]])).tolist() == [False, False, True]
    assert merge_groups(np.array([[1, 2], [3, 4]])).tolist() == [False, True]


def random_walk(seed, T, n_places=12, n_symbols=5, n_actions=3, episodes=1):
    """A walk on a random graph with aliased symbols (phase-1 labels = the true symbols)."""
    rng = np.random.default_rng(seed)
    succ = rng.integers(0, n_places, (n_places, n_actions))
    symbol = np.concatenate([np.arange(n_symbols), rng.integers(0, n_symbols, n_places - n_symbols)])
    p, labels, actions = 0, [], []
    for _ in range(T):
        a = int(rng.integers(n_actions))
        labels.append(symbol[p])
        actions.append(a)
        p = succ[p, a]
    cuts = np.sort(rng.choice(np.arange(1, T), episodes - 1, replace=False)) if episodes > 1 else []
    lengths = np.diff(np.concatenate([[0], cuts, [T]])).astype(int)
    return np.array(labels), np.array(actions), lengths, n_symbols, n_actions


@pytest.mark.parametrize("seed, episodes", [(0, 1), (1, 1), (2, 4), (3, 7), (4, 2)])
def test_the_engine_splits_exactly_as_the_numpy_code(seed, episodes):
    labels, u, lengths, S, A = random_walk(seed, 1500, episodes=episodes)
    expected = ref.splits(labels, u, S, A, lengths, 12)
    has_prev, has_next = episode_masks(len(u), lengths)
    splitter = Splitter(labels, u, A, has_prev, has_next, symbol=list(range(S)), gds=[-1] * S,
                        obs_entropy=np.zeros(S), criterion=EntropyCriterion())
    for state, score, x in expected:
        best = splitter.best()
        assert (best.state, bits(best.score)) == (state, bits(score))
        splitter.apply(best)
        assert np.array_equal(splitter.labels, x)
        n, ac, tc = count_tables(x, u, splitter.n_states, A, has_next)
        for kept, counted in zip(splitter.count_tables(), (n, ac, tc)):
            assert kept.dtype == counted.dtype and np.array_equal(kept, counted)
        ent = splitter.entropies()
        assert bits(ent["H_u"]) == bits(conditional_entropy(ac))
        assert bits(ent["H_x"]) == bits(conditional_entropy(tc.reshape(-1, splitter.n_states)))
    assert len(expected) == 12


@pytest.mark.parametrize("seed, episodes", [(5, 1), (6, 9)])
@pytest.mark.parametrize("n_threads", [1, 2, 3])
def test_the_tables_kept_through_splits_are_the_tables_built_afresh(seed, episodes, n_threads,
                                                                     monkeypatch):
    # after each split the engine cuts the split state's table in two and moves the instances
    # next to the moved steps (the transitions merged beside them on threads); every state's
    # table must be the one its steps give from scratch
    from topomap.core.split import threads
    from topomap.core.split.kernels import instance_table, transition_table

    monkeypatch.setattr(threads, "n_threads", lambda: n_threads)
    monkeypatch.setattr(threads, "THREAD_STEPS", 0)  # a thread for every merge, however small

    labels, u, lengths, S, A = random_walk(seed, 1200, episodes=episodes)
    has_prev, has_next = episode_masks(len(u), lengths)
    splitter = Splitter(labels, u, A, has_prev, has_next, symbol=list(range(S)), gds=[-1] * S,
                        obs_entropy=np.zeros(S), criterion=EntropyCriterion())
    engine = splitter.engine
    for _ in range(10):
        splitter.apply(splitter.best())
        size = (splitter.n_states + 1) * A
        for s in range(splitter.n_states):
            fresh = instance_table(engine.labels, engine.u, engine.members[s], engine.centre, A,
                                   size)
            assert [a.tolist() for a in engine.tables[s]] == [a.tolist() for a in fresh]
        fresh = transition_table(engine.labels, engine.u, has_next, splitter.n_states, A)
        assert [a.tolist() for a in engine.transitions] == [a.tolist() for a in fresh]


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_gain_is_the_numpy_gain_bit_for_bit(seed):
    from topomap.core.split.engine import entropy_gain

    rng = np.random.default_rng(seed)
    G, C = int(rng.integers(2, 12)), int(rng.integers(1, 400))
    counts = rng.integers(0, 10 ** int(rng.integers(1, 6)), (G, C)) * (rng.random((G, C)) < 0.3)
    side = rng.random(G) < 0.5
    halves = np.stack([counts[~side].sum(axis=0), counts[side].sum(axis=0)])
    expected = (weighted_entropy(halves.sum(axis=0))[0]
                - weighted_entropy(halves).sum()) / counts.sum()
    assert bits(entropy_gain(counts, side)) == bits(expected)


def test_the_gain_by_hand():
    from topomap.core.split.engine import entropy_gain

    # two rows that never share a column: H(I) = 1 bit, each half 0 bits
    assert entropy_gain(np.array([[3, 0], [0, 3]]), np.array([False, True])) == 1.0
    # both rows in the same half: nothing gained
    assert entropy_gain(np.array([[3, 0], [0, 3]]), np.array([False, False])) == 0.0


@pytest.mark.parametrize("K", list(range(1, 20)) + [31, 64, 127, 128, 129, 200])
def test_a_merged_pair_sum_is_numpys_sum(K):
    """The merge's pair sum, read straight into numpy's eight accumulators up to 128 columns and
    through a buffer above, is numpy's ``table[work[a] + work[b]].sum()`` bit for bit (a table of
    values over a wide range of magnitudes, so the order of additions shows)."""
    from topomap.core.split.merge_kernels import _merged_sum

    rng = np.random.default_rng(K)
    work = rng.integers(0, 50, (3, K))
    table = np.abs(wild(rng, 101))
    for a, b in [(0, 1), (1, 2), (2, 0)]:
        got = _merged_sum(work, table, a, b, np.empty(K))
        assert bits(got) == bits(table[work[a] + work[b]].sum())


def test_the_sum_of_a_pair_by_hand():
    from topomap.core.split.merge_kernels import _merged_sum

    table = np.arange(10.0) ** 2  # table[c] = c^2
    work = np.array([[1, 0, 2], [0, 3, 1]])
    assert _merged_sum(work, table, 0, 1, np.empty(3)) == 1 + 9 + 9


@pytest.mark.parametrize("seed,K", [(0, 129), (1, 150), (2, 9), (3, 40)])
def test_wide_count_matrices_merge_as_numpy_does(seed, K):
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 30, (int(rng.integers(3, 9)), K)) * (rng.random((1, K)) < 0.4)
    counts[counts.sum(1) == 0, 0] = 1
    assert np.array_equal(merge_groups(counts), ref.merge_groups(counts))


@pytest.mark.parametrize("seed", range(6))
def test_merge_and_gain_in_one_call_is_the_two_calls(seed):
    from topomap.core.split.engine import entropy_gain, merge_and_gain

    rng = np.random.default_rng(seed)
    G, K = int(rng.integers(2, 40)), int(rng.integers(1, 70))
    counts = rng.integers(0, 10 ** int(rng.integers(1, 4)), (G, K)) * (rng.random((G, K)) < 0.4)
    counts[counts.sum(1) == 0, 0] = 1
    side, gain = merge_and_gain(counts)
    assert np.array_equal(side, merge_groups(counts))
    assert bits(gain) == bits(entropy_gain(counts, side))


def test_merge_and_gain_edge_cases():
    from topomap.core.split.engine import merge_and_gain
    from topomap.core.split.merge_kernels import count_range

    assert count_range(np.array([[3, 0], [-2, 4]])) == (-2, 5)
    assert merge_and_gain(np.array([[1, 2]])) is None  # one group: nothing to split
    side, gain = merge_and_gain(np.array([[3, 0], [0, 3]]))
    assert side.tolist() == [False, True] and gain == 1.0
    side, gain = merge_and_gain(np.zeros((2, 2), dtype=np.int64))
    assert side.tolist() == [False, True] and np.isnan(gain)
    with pytest.raises(ValueError, match="non-negative"):
        merge_and_gain(np.array([[1, -1], [0, 2]]))
