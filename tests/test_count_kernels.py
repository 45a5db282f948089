"""The compiled counts of the split and the map on small cases worked out by hand."""

import numpy as np
import pytest

from topomap.core.map.observations import observation_models
from topomap.core.split.engine import members_of
from topomap.core.split.kernels import (_code_pair, instance_table, merge_tallies, tally_codes,
                                        transition_table)
from topomap.core.stats import count_tables


def test_merge_tallies_moves_counts_and_drops_zeros():
    codes, counts = np.array([2, 5, 9]), np.array([1, 3, 2])
    # take one off 2 (-> 0, dropped) and two off 5; add 7 (new) once and 9 twice
    out_codes, out_counts = merge_tallies(codes, counts, np.array([2, 5]), np.array([1, 2]),
                                          np.array([7, 9]), np.array([1, 2]))
    assert out_codes.tolist() == [5, 7, 9]
    assert out_counts.tolist() == [1, 1, 4]


def test_merge_tallies_refuses_a_code_not_in_the_table_or_too_many_taken_off():
    with pytest.raises(ValueError, match="not in the table"):
        merge_tallies(np.array([2, 5]), np.array([1, 1]), np.array([3]), np.array([1]),
                      np.array([5]), np.array([1]))
    with pytest.raises(ValueError, match="more taken off"):
        merge_tallies(np.array([2, 5]), np.array([1, 1]), np.array([5]), np.array([2]),
                      np.array([2]), np.array([1]))


def test_tally_codes_sorts_and_counts():
    # keys and columns below 4: codes (1, 3), (0, 2), (1, 3), (1, 0)
    codes = np.array([(1 << 32) | 3, 2, (1 << 32) | 3, 1 << 32])
    for size in (4, 1000):  # a counting sort by key; a sort when the codes are few
        out, n = tally_codes(codes, size)
        assert out.tolist() == [2, 1 << 32, (1 << 32) | 3] and n.tolist() == [1, 1, 2]


def _codes(x, u, steps, A, centred):
    """The codes at ``steps`` (no split: the code before is the code after)."""
    pairs = [_code_pair(x, u, t, A, np.int64(32), centred, 0, 99) for t in steps]
    assert all(before == after for before, after in pairs)
    return [after for _, after in pairs]


def test_code_pairs_and_transition_table():
    x, u, A = np.array([0, 1, 1, 0]), np.array([1, 0, 1, 0]), 2
    # transitions at t = 0, 1, 2: (0*2+1 -> 1), (1*2+0 -> 1), (1*2+1 -> 0)
    assert _codes(x, u, [0, 1, 2], A, False) == [(1 << 32) | 1, (2 << 32) | 1, (3 << 32) | 0]
    # the instance centred at t = 1: key x[0]*A+u[0] = 1, column x[2]*A+u[1] = 2
    assert _codes(x, u, [1], A, True) == [(1 << 32) | 2]
    has_next = np.array([True, False, True, False])
    codes, counts = transition_table(x, u, has_next, 2, A)
    assert codes.tolist() == [(1 << 32) | 1, (3 << 32) | 0] and counts.tolist() == [1, 1]


def test_instance_table_counts_the_centres_by_hand():
    # A = 2; centres are t = 1..4 except t = 3 (an episode boundary after it)
    x, u, A = np.array([0, 1, 0, 1, 0, 1]), np.array([1, 0, 1, 0, 1, 1]), 2
    centre = np.array([False, True, True, False, True, False])
    # t = 1: key x0*2+u0 = 1, column x2*2+u1 = 0; t = 2: key 2, column 3; t = 4: key 2, column 3
    codes, counts = instance_table(x, u, np.array([1, 2, 3, 4]), centre, A, 6)
    assert codes.tolist() == [(1 << 32) | 0, (2 << 32) | 3] and counts.tolist() == [1, 2]
    codes, counts = instance_table(x, u, np.array([0, 3, 5]), centre, A, 6)
    assert codes.size == 0 and counts.size == 0


def test_members_of_sorts_steps_by_state():
    members = members_of(np.array([2, 0, 2, 1, 0]), 4, np.empty(0, dtype=np.int32))
    assert [m.tolist() for m in members] == [[1, 4], [3], [0, 2], []]
    assert members[0].dtype == np.int32


def test_count_tables_by_hand_and_bad_labels():
    x, u = np.array([0, 1, 1, 0]), np.array([1, 0, 1, 0])
    state, action, trans = count_tables(x, u, 2, 2, np.array([True, True, True, False]))
    assert state.tolist() == [2, 2]
    assert action.tolist() == [[1, 1], [1, 1]]
    assert trans[0, 1, 1] == 1 and trans[1, 0, 1] == 1 and trans[1, 1, 0] == 1
    assert trans.sum() == 3
    with pytest.raises(ValueError, match="labels must lie in"):
        count_tables(np.array([0, 2]), np.array([0, 0]), 2, 1, np.array([True, False]))


def test_observation_models_through_a_lookup():
    X = np.array([[0.0], [2.0], [10.0], [4.0]])
    states = np.array([0, 1, 2, 0])  # states 0 and 1 share model 0, state 2 is model 1
    means, cov, n = observation_models(X, states, 2, lookup=np.array([0, 0, 1]))
    assert n.tolist() == [3.0, 1.0]
    assert means[:, 0].tolist() == [2.0, 10.0]
    direct = observation_models(X, np.array([0, 0, 1, 0]), 2)
    assert np.array_equal(cov, direct[1])


def test_diagonal_models_in_two_passes_by_hand():
    # two features (the two-pass path): model 0 holds rows 0, 1, 3, model 1 row 2
    X = np.array([[0.0, 1.0], [2.0, 1.0], [10.0, 1.0], [4.0, 1.0]])
    means, cov, n = observation_models(X, np.array([0, 1, 2, 0]), 2, reg_covar=1e-3,
                                       lookup=np.array([0, 0, 1]))
    assert n.tolist() == [3.0, 1.0]
    assert means.tolist() == [[2.0, 1.0], [10.0, 1.0]]
    # feature variances 14 and 0: reg = 1e-3 * 7; model 0's first variance (4 + 0 + 4) / 3
    assert np.allclose(cov, [[8 / 3 + 0.007, 0.007], [0.007, 0.007]], rtol=0, atol=1e-15)


def test_diagonal_models_in_two_passes_are_the_separate_sums():
    from topomap.core.map.observations import (feature_variance, model_counts, model_squares,
                                               model_sums)
    rng = np.random.default_rng(3)
    X = rng.normal(size=(500, 4)) * 3 + 1
    model, lookup = rng.integers(0, 6, 500), rng.integers(0, 3, 6)
    means, cov, n = observation_models(X, model, 3, reg_covar=1e-3, lookup=lookup)
    n_ref = model_counts(model, 3, lookup)
    means_ref = model_sums(X, model, 3, lookup) / np.maximum(n_ref, 1)[:, None]
    reg = 1e-3 * float(np.mean(feature_variance(X)))
    cov_ref = model_squares(X, model, means_ref, lookup) / np.maximum(n_ref, 1)[:, None] + reg
    for a, b in ((n, n_ref), (means, means_ref), (cov, cov_ref)):
        assert np.array_equal(a.view(np.int64), b.view(np.int64))


def test_touched_codes_around_the_moved_steps_by_hand():
    from topomap.core.split.kernels import touched_codes

    # A = 2, one episode; state 1 split, steps 2 and 3 moved to the new state 3
    x, u, A = np.array([0, 1, 3, 3, 2]), np.array([1, 0, 1, 0, 1]), 2
    has_prev, has_next = np.arange(5) > 0, np.arange(5) < 4
    out, ins, starts, near = touched_codes(np.array([2, 3]), has_prev, has_next,
                                           has_prev & has_next, x, u, A, np.int64(32), 1, 3)
    assert out.shape == (4, 0)  # every centre next to them (1, 2, 3) was in state 1
    # t = 1: key 0*2+1, column x2*2+u1 = 6 (2 before); t = 2: key 2, column 7 (3); t = 3: key
    # 3*2+1 = 7 (3), column 4; step 4 is no centre
    assert ins.tolist() == [[(1 << 32) | 2, (2 << 32) | 3, (3 << 32) | 4],
                            [(1 << 32) | 6, (2 << 32) | 7, (7 << 32) | 4], [0, 1, 1]]
    # transitions from t = 1 (key 2, to 3, 1 before), 2 (key 7 / 3, to 3 / 1), 3 (key 6 / 2, to 2)
    assert starts.tolist() == [[(2 << 32) | 1, (3 << 32) | 1, (2 << 32) | 2],
                               [(2 << 32) | 3, (7 << 32) | 3, (6 << 32) | 2]]
    assert near.tolist() == [False, True, True, True]
    # step 1 moved out of state 1; the centre at t = 2 lies in state 0
    x = np.array([0, 3, 0, 1, 2])
    out, ins, starts, near = touched_codes(np.array([1]), has_prev, has_next,
                                           has_prev & has_next, x, u, A, np.int64(32), 1, 3)
    # t = 2: key x1*2+u1 = 6 (2 before), column x3*2+u2 = 3
    assert out.tolist() == [[2], [0], [(2 << 32) | 3], [(6 << 32) | 3]] and ins.shape == (3, 0)
    assert near.tolist() == [True, False, False, False]


def test_split_table_cuts_by_key():
    from topomap.core.split.kernels import split_table

    codes = np.array([(0 << 32) | 5, (1 << 32) | 2, (1 << 32) | 4, (3 << 32) | 1])
    counts = np.array([1, 2, 3, 4])
    chosen = np.array([False, True, False, False])
    (kc, kn), (wc, wn) = split_table(codes, counts, chosen, np.int64(32))
    assert kc.tolist() == [5, (3 << 32) | 1] and kn.tolist() == [1, 4]
    assert wc.tolist() == [(1 << 32) | 2, (1 << 32) | 4] and wn.tolist() == [2, 3]


def test_count_matrix_by_hand():
    from topomap.core.split.merge_kernels import count_matrix_kernel

    # codes (key, column): (1, 4) x2, (1, 7) x1, (3, 4) x5
    codes = np.array([(1 << 32) | 4, (1 << 32) | 7, (3 << 32) | 4])
    for size in (8, 1000):  # by a presence mask; by sorting when the codes are few
        matrix, keys, cols = count_matrix_kernel(codes, np.array([2, 1, 5]), size)
        assert keys.tolist() == [1, 3] and cols.tolist() == [4, 7]
        assert matrix.tolist() == [[2, 1], [5, 0]]
