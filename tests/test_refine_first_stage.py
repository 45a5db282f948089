"""``EMRefinement(growth={"first": "rough", "first_factor": ..., "first_iter": ...})``: a
rougher first EM stage where it runs on a prefix, on the small worlds of test_refine.py whose
answer is known (the aliased ring and the 4 x 3 grid)."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from test_refine import RING, ROOM, grid_walk, ring_walk
from topomap.core.checks import ParameterError
from topomap.core.refine import methods
from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.sequence import SymbolSequence

#: growth settings: a rough stage 1, and stage 1 as every round whatever ``first``
ROUGH = {"first": "rough", "first_factor": 1, "first_iter": 25}
PLAIN = {"first_factor": 0, "first_iter": 0}


def ring(seed, T=3200):
    sym, u, places = ring_walk(T, RING, seed)
    return SymbolSequence.build(sym, u, [T], 2, 6), places


def grid(seed, T=4000):
    sym, u, places = grid_walk(T, seed)
    return SymbolSequence.build(sym, u, [T], 4, 3), places


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("rough", [ROUGH, {"first": "rough", "first_factor": 1, "first_iter": 5}])
def test_a_rough_first_stage_still_finds_every_place_of_the_ring(seed, rough):
    """The split found nothing (one state per symbol): stage 1 is on the first 2,000 of 3,200
    steps (at most ``ROUGH`` of them), so it is cut to ``first_iter`` E-steps on one clone per split state (+ spare); the
    growth stage and the rounds on all steps still find the 8 places.  (Baum-Welch judges its
    own stop from the 11th E-step on: a stage of 5 E-steps was cut.)"""
    seq, places = ring(seed)
    fit = EMRefinement(growth=rough).fit(seq, np.arange(6), seed)
    n, _, iters = fit.info_["stages"][0]
    assert n == 2000 and iters <= rough["first_iter"] and (iters == 5) is (rough["first_iter"] == 5)
    assert fit.n_states_ == 8 and adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("seed", range(3))
def test_a_rough_first_stage_still_finds_every_cell_of_the_grid(seed):
    """The split's usual size (a state per cell): stage 1 on the first 2,000 of 4,000 steps."""
    seq, places = grid(seed)
    fit = EMRefinement(growth=ROUGH).fit(seq, ROOM.place_symbols, seed)
    assert fit.info_["stages"][0][0] == 2000 and fit.info_["stages"][0][2] <= 25
    assert fit.n_states_ == 12 and adjusted_rand_score(places, fit.labels_) == 1.0


@pytest.mark.parametrize("first, same_as", [("rough", "squarem"), ("plain", "none")])
def test_auto_acceleration_is_squarem_after_a_rough_first_stage_only(first, same_as):
    """``hard.accelerate="auto"`` (the default): after a rough stage 1 the warm-started rounds
    are SQUAREM's, after a plain one plain EM -- stage for stage the fit of ``"squarem"`` or of
    ``"none"``, which differ on this grid (stage 1 the same in all three)."""
    seq, _ = grid(0)
    fits = {acc: EMRefinement(growth={**ROUGH, "first": first}, hard={"accelerate": acc}).fit(
        seq, ROOM.place_symbols, 0).info_["stages"] for acc in ("auto", "none", "squarem")}
    assert fits["none"][0] == fits["squarem"][0] and fits["none"][1:] != fits["squarem"][1:]
    assert fits["auto"] == fits[same_as]


def factors_used(monkeypatch):
    """The clone factors the first stages size their budget with, in order."""
    used, evidence = [], methods.BUDGETS["evidence"]

    def spy(split_state_symbol, seq, factor, spare):
        used.append(factor)
        return evidence(split_state_symbol, seq, factor, spare)

    monkeypatch.setitem(methods.BUDGETS, "evidence", spy)
    return used


def test_the_first_factor_sizes_the_budget_of_a_stage_on_a_short_prefix_only(monkeypatch):
    """2,000 of 3,200 steps is at most ``ROUGH`` (2/3) of them, 2,400 or all 3,200 are more."""
    used = factors_used(monkeypatch)
    seq, _ = ring(0)
    for prefix in (2000, 2400, 3200):
        EMRefinement(growth={"first": "rough", "first_factor": 1, "prefix": prefix}).fit(
            seq, np.arange(6), 0)
    EMRefinement(growth={"clone_factor": 3, "first_factor": 0}).fit(seq, np.arange(6), 0)
    assert methods.ROUGH == 2 / 3 and used == [1, 2, 2, 3]


@pytest.mark.parametrize("prefix", [2400, 3200])
def test_a_first_stage_on_most_steps_keeps_its_iterations(prefix):
    """A prefix of more than ``ROUGH`` of the steps (3/4, all): stage 1 is not cut, and the fit
    is the plain one, stage for stage."""
    seq, _ = ring(0)
    plain = EMRefinement(growth={"prefix": prefix, **PLAIN}).fit(seq, np.arange(6), 0)
    rough = EMRefinement(growth={"prefix": prefix, "first": "rough", "first_iter": 5}).fit(
        seq, np.arange(6), 0)
    assert plain.info_["stages"][0][0] == prefix and plain.info_["stages"][0][2] > 5
    assert rough.info_["stages"] == plain.info_["stages"]


def test_first_rtol_lets_stage_one_go_on_while_it_gains():
    """``first_rtol`` 0: past ``first_iter`` Baum-Welch goes on while it gains anything (above
    ``tol``), the plain stop: stage 1 runs as long as without a cap; ``inf``: it stops there."""
    seq, _ = ring(1)
    def stage_one(**params):
        return EMRefinement(growth=params).fit(seq, np.arange(6), 1).info_["stages"][0]

    plain = stage_one(**PLAIN)
    on = stage_one(first="rough", first_factor=0, first_iter=12, first_rtol=0.0)
    cut = stage_one(first="rough", first_factor=0, first_iter=12)
    assert plain[2] > 13 and on == plain and cut[2] == 12


def test_the_first_stage_settings_are_named_in_the_provenance_only_when_set():
    assert "first" not in EMRefinement().provenance()
    assert "first_factor=0, first_iter=0, settings=" in EMRefinement(growth=PLAIN).provenance()
    assert ("start='split', first='rough', first_rtol=0.001, settings=" in EMRefinement(
        growth={"start": "split", "first_rtol": 1e-3, **ROUGH}).provenance())


@pytest.mark.parametrize("params, message", [
    (dict(first_factor=-1), "growth.first_factor must be a non-negative integer, got -1"),
    (dict(first_iter=2.5), "growth.first_iter must be a non-negative integer, got 2.5"),
    (dict(first_rtol=-0.1), "growth.first_rtol must be >= 0, got -0.1"),
    (dict(first="fast"), "growth.first must be one of auto, rough, plain, got 'fast'"),
])
def test_bad_first_stage_settings_are_refused_by_name(params, message):
    with pytest.raises(ParameterError, match=f"^{message}"):
        EMRefinement(growth=params).check_params()


def growth_prefixes(monkeypatch, changed: bool, **params):
    """The prefix of every stage up to stage 3 on a 64,000-step ring, every EM round faked to
    end with 8 states and the merges and splits after it to change something or nothing."""
    def em_round(self, seq, *args, **kwargs):
        return np.zeros(seq.T, dtype=np.int64), np.arange(8) % 6, 1

    def restructure(self, seq, labels, state_symbol):
        return (labels, state_symbol), (labels, state_symbol), changed

    monkeypatch.setattr(EMRefinement, "_first_round", em_round)
    monkeypatch.setattr(EMRefinement, "_warm_round", em_round)
    monkeypatch.setattr(EMRefinement, "_restructure", restructure)
    seq, _ = ring(0, T=64000)
    em = EMRefinement(evidence="hard", growth=params)
    em.settings_ = em.check_params()  # as fit sets it
    stages = em._stages(seq, np.arange(6), 0)
    return [n for n, _, _ in next(stages)[2]["stages"]]


def test_growth_settles_on_two_full_stages_after_a_rough_one(monkeypatch):
    """As many states at the end of two stages in a row: the next stage takes all steps.  After a
    plain stage 1 that is stage 2 (2,000 and 4,000 steps); after a rough one, whose count is no
    test, stages 2 and 3 (4,000 and 8,000), and only where merging and splitting the last one's
    states change nothing; else the prefix doubles on to all 64,000 steps."""
    assert growth_prefixes(monkeypatch, False, **PLAIN) == [2000, 4000, 64000]
    assert growth_prefixes(monkeypatch, True, **PLAIN) == [2000, 4000, 64000]
    assert growth_prefixes(monkeypatch, False, **ROUGH) == [2000, 4000, 8000, 64000]
    assert growth_prefixes(monkeypatch, True, **ROUGH) == [2000, 4000, 8000, 16000, 32000, 64000]
