"""``EMRefinement(growth={"start": ...})``: the first EM stage started from the split's
labelling, on small worlds whose answer is known (the aliased ring and the 4 x 3 grid of
test_refine.py)."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from test_refine import RING, grid_walk, noisy, ring_walk
from topomap.core.checks import ParameterError
from topomap.core.learner import MapLearner
from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.sequence import SymbolSequence
from topomap.core.refine.structure import same_partition


def started(start: str) -> EMRefinement:
    """``refine=em`` whose stage 1 starts as ``start`` says (``growth.start``)."""
    return EMRefinement(growth={"start": start})


def ring(seed):
    sym, u, places = ring_walk(3000, RING, seed)
    return SymbolSequence.build(sym, u, [3000], 2, 6), places


@pytest.mark.parametrize("seed", range(3))
def test_a_right_split_is_kept_in_two_short_rounds(seed):
    """The split labels every place of the ring apart: EM started from it has nothing to move,
    so stage 1 stops at its first convergence check (11 E-steps: the stop is checked from the
    11th on) with the 8 places, and so does the one round on all steps; from random counts stage
    1 needs more."""
    seq, places = ring(seed)
    fit = started("split").fit(seq, np.asarray(RING), seed, split_labels=places)
    assert fit.n_states_ == 8 and same_partition(fit.labels_, places)
    assert fit.info_["stages"] == [(2000, 8, 11), (3000, 8, 11)]
    plain = EMRefinement().fit(seq, np.asarray(RING), seed)
    assert plain.info_["stages"][0][2] > 11


@pytest.mark.parametrize("seed", range(3))
def test_a_split_that_missed_the_aliased_places_is_repaired(seed):
    """One state per symbol (the split told no aliased place apart): the spare clones and the
    split test of the later rounds find all 8 places."""
    seq, places = ring(seed)
    fit = started("split").fit(seq, np.arange(6), seed, split_labels=seq.sym)
    assert fit.n_states_ == 8 and adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("seed", range(3))
def test_a_split_that_cut_places_in_two_is_merged_back(seed):
    """Every place's steps dealt at random to two states: the merging of bisimilar states joins
    each pair again."""
    seq, places = ring(seed)
    halves = places * 2 + np.random.default_rng(seed).integers(0, 2, places.size)
    fit = started("split").fit(seq, np.repeat(RING, 2), seed, split_labels=halves)
    assert fit.n_states_ == 8 and adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("seed", range(12))
def test_the_grid_is_found_from_one_state_per_symbol(seed):
    """The 4 x 3 grid from the wrongest split there is (each symbol one state): all 12 cells."""
    sym, u, places = grid_walk(4000, seed)
    seq = SymbolSequence.build(sym, u, [4000], 4, 3)
    fit = started("split").fit(seq, np.arange(3), seed, split_labels=sym)
    assert fit.n_states_ == 12 and adjusted_rand_score(places, fit.labels_) == 1.0


def test_the_learner_hands_its_split_to_the_refinement():
    """Through :class:`MapLearner` the refinement starts from ``labels_split_`` (the ring's
    split, 6 states for 8 places, is wrong); the map file's label names the start."""
    sym, u, places = ring_walk(3000, RING, 0)
    learner = MapLearner(n_clusters=6, n_states=6, refine=started("split"),
                         refined_size="free").fit(noisy(sym, 6), u)
    assert adjusted_rand_score(places, learner.labels_split_) < 0.9
    assert adjusted_rand_score(places, learner.labels_) == 1.0 and learner.map_.n_states == 8
    assert "start='split'" in learner.map_.info["refine"]


@pytest.mark.parametrize("split_labels, message", [
    (None, r"^split_labels: start='split' needs the split state of every step$"),
    (np.zeros(5, int), r"^split_labels: must be 8 integer states, one per step, got shape"),
    (np.full(8, -1), r"^split_labels: states must be >= 0$"),
    (np.zeros(8, int), r"^split_labels: a state does not emit the symbol of every step"),
])
def test_a_bad_split_start_is_refused_in_one_line(split_labels, message):
    seq = SymbolSequence.build([0, 1, 2, 0, 1, 2, 0, 1], np.zeros(8, int), [8], 1, 3)
    with pytest.raises(ValueError, match=message):
        started("split").fit(seq, np.arange(3), 0, split_labels=split_labels)


def test_an_unknown_start_is_refused_by_name():
    with pytest.raises(ParameterError, match=r"^growth.start must be one of random, split, "
                                             r"split_budget, auto, got 'warm'$"):
        EMRefinement(growth={"start": "warm"}).check_params()


def test_the_random_start_ignores_split_labels():
    """``start="random"`` (the default) gives the same fit with or without the split's
    labelling."""
    seq, places = ring(0)
    a = EMRefinement().fit(seq, np.asarray(RING), 0)
    b = EMRefinement().fit(seq, np.asarray(RING), 0, split_labels=places)
    assert np.array_equal(a.labels_, b.labels_) and a.info_ == b.info_


def test_auto_starts_from_a_split_that_predicts_the_next_view():
    """The right split predicts every next symbol (successor surprise 0): ``"auto"`` starts from
    it, as ``"split"`` does."""
    seq, places = ring(0)
    auto, split = (started(s).fit(seq, np.asarray(RING), 0, split_labels=places)
                   for s in ("auto", "split"))
    assert auto.info_ == split.info_ and np.array_equal(auto.labels_, split.labels_)


def test_auto_starts_from_random_counts_where_the_split_joined_places():
    """One state per symbol on the ring: from the state of symbol 1 (places 1 and 4) the move
    forward shows symbol 2 or 4, so the split is far from predicting the next view and
    ``"auto"`` starts as ``"random"`` does."""
    seq, _ = ring(0)
    auto = started("auto").fit(seq, np.arange(6), 0, split_labels=seq.sym)
    plain = EMRefinement().fit(seq, np.arange(6), 0)
    assert auto.info_ == plain.info_ and np.array_equal(auto.labels_, plain.labels_)
