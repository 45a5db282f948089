"""Clone budgets sized by the data (topomap.core.refine.budget)."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap.core.refine.budget import (distinct_rows, evidence_budget, place_lower_bound,
                                        split_budget)
from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.sequence import SymbolSequence
from test_refine import ring_walk


def shared_view_ring(k):
    """A ring where view 0 is seen at ``k`` places, each between two views of its own:
    0, 1, 0, 2, ..., 0, k (2k places, k + 1 views)."""
    return [v for i in range(1, k + 1) for v in (0, i)]


@pytest.mark.parametrize("k", [3, 6, 10])
def test_a_view_shared_by_k_places_gets_at_least_k_clones(k):
    """The split found one state per view (it stops at its state target): its budget gives view 0
    2 x 1 + 2 clones, too few for k > 4; the evidence budget gives at least k."""
    sym, u, places = ring_walk(400 * k, shared_view_ring(k))
    seq = SymbolSequence.build(sym, u, [sym.size], 2, k + 1)
    split = np.arange(k + 1)
    assert place_lower_bound(sym, u, [sym.size], k + 1)[0] == k
    assert evidence_budget(split, seq, 2, 2)[0] >= k
    assert split_budget(split, seq, 2, 2)[0] == 4
    fit = EMRefinement(growth={"budget": "evidence"}).fit(seq, split, 0)
    assert adjusted_rand_score(places, fit.labels_) == 1.0
    assert np.sum(fit.state_symbol_ == 0) == k


def test_the_lower_bound_never_exceeds_the_places_of_a_deterministic_world():
    sym, u, places = ring_walk(3000, [0, 1, 2, 3, 1, 4, 2, 5])
    lb = place_lower_bound(sym, u, [3000], 6, horizon=4)
    true = np.array([np.unique(places[sym == k]).size for k in range(6)])
    assert np.all(lb <= true) and np.all(lb >= 1)


def test_the_lower_bound_respects_episodes():
    """No outcome crosses an episode start: 0 -> 2 below is an episode boundary, not a move."""
    sym = np.array([0, 1, 0, 2])
    u = np.zeros(4, dtype=np.int64)
    assert place_lower_bound(sym, u, [3, 1], 3, min_count=1)[0] == 1
    assert place_lower_bound(sym, u, [4], 3, min_count=1)[0] == 2
    assert place_lower_bound(sym, u, [4], 3, min_count=2)[0] == 1   # each outcome seen once


def test_gds_ids_keep_one_clone_under_the_evidence_budget():
    sym, u, _ = ring_walk(2000, [0, 1, 0, 2, 3])
    seq = SymbolSequence.build(sym, u, [2000], 2, 3)    # id 3 is a GDS
    assert evidence_budget(np.array([0, 1, 2, -1]), seq, 2, 2)[3] == 1


def test_unknown_budget_is_refused():
    with pytest.raises(ValueError,
                       match="^growth.budget must be one of split, evidence, got 'nope'"):
        EMRefinement(growth={"budget": "nope"}).check_params()


@pytest.mark.parametrize("dims", [(3, 4, 5), (2**40, 2**40, 3)])
def test_distinct_rows_are_numpys_unique_rows(dims):
    """Numbered in mixed radix when the rows fit in int64 numbers, np.unique over rows when they
    do not (2**40 x 2**40 x 3): the same rows and counts either way."""
    rng = np.random.default_rng(0)
    rows = np.column_stack([rng.integers(min(d, 4), size=500) for d in dims])
    rows[:, 0] += dims[0] - 4 if dims[0] > 4 else 0
    want = np.unique(rows, axis=0, return_counts=True)
    got = distinct_rows(rows, dims)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
