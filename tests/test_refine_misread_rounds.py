"""The soft rounds on misread views made short: the first soft round on each step's own
evidence where the hard labelling pairs no two symbols (``reading.observed_in="early"``,
:func:`~topomap.core.refine.soft_states.successor_pairing`), that round stopped once its
readings settle (``reading.settle``), and the hard rounds on its corrections started from its
labelling (``growth.cycle_start="soft"``) -- on the misread ring walk, whose answer is known."""

import numpy as np
import pytest

from topomap.core.refine import rounds
from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.soft import SoftFit
from topomap.core.refine.sequence import SymbolSequence
from topomap.core.refine.soft_states import successor_pairing
from topomap.core.refine.structure import same_partition

from test_observed_evidence import _ring_loglik
from test_soft_refine import RING, _ring_walk, _seq

EARLY = {"temperature": 1.0, "observed_in": "early"}
OLD = {"reading": {"temperature": 1.0, "observed_in": "auto", "settle": 0.0},
       "growth": {"cycle_start": "random"}}


def test_successor_pairing_by_hand():
    # one state, one action: the next symbols 0, 0, 0, 1 -- the row of symbol 0 (its usual
    # next view) reads 1 once in 4
    seq = SymbolSequence.build([0, 0, 0, 0, 1], [0] * 5, [5], 1, 2)
    assert successor_pairing(seq, np.zeros(5, dtype=np.int64)) == pytest.approx(0.25)
    # two states, each always followed by one symbol: nothing paired
    seq = SymbolSequence.build([0, 1, 0, 1, 0, 1], [0] * 6, [6], 1, 2)
    assert successor_pairing(seq, np.array([0, 1, 0, 1, 0, 1])) == 0.0
    # state 0 followed by 0, 1, 0, 1 (a tie: counted under symbol 0), states 1 and 2 by 0
    # three times: all 7 moves under symbol 0, 2 of them reading 1
    seq = SymbolSequence.build([0, 0, 0, 1, 0, 0, 0, 1], [0] * 8, [8], 1, 2)
    labels = np.array([0, 1, 0, 2, 0, 1, 0, 2])
    assert successor_pairing(seq, labels) == pytest.approx(2 / 7)


def _fit(**groups):
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    fit = EMRefinement(evidence="soft", **groups).fit(
        seq, RING, 0, observed=_ring_loglik(sym, place, -np.log(0.6)))
    return fit, place


def test_early_reads_the_first_soft_round_on_the_per_step_evidence():
    """The ring's misreads are one view seen wrong at random: the hard labelling pairs no two
    symbols, so the first soft round already takes each step's evidence, and maps the ring."""
    fit, place = _fit(reading=EARLY)
    first = fit.info_["soft_rounds"][0]
    assert first["evidence"] == "observed" and first["hard_paired"] < rounds.PAIRED_READ
    assert same_partition(fit.labels_, place)
    old, _ = _fit(**OLD)
    assert "evidence" not in old.info_["soft_rounds"][0]  # "auto": the confusion matrix first


def test_early_keeps_the_confusion_matrix_where_the_moves_pair_two_symbols(monkeypatch):
    monkeypatch.setattr(rounds, "PAIRED_READ", 0.0)  # every pairing counts as a view cut in two
    fit, place = _fit(reading=EARLY)
    assert "evidence" not in fit.info_["soft_rounds"][0]


def test_read_settle_stops_the_first_soft_round_sooner_with_the_same_map():
    settled, place = _fit(reading={**EARLY, "settle": 0.002})
    full, _ = _fit(reading={**EARLY, "settle": 0.0})
    n = [f.info_["soft_rounds"][0]["em_iterations"] for f in (settled, full)]
    assert n[0] < n[1]
    assert same_partition(settled.labels_, place) and same_partition(full.labels_, place)


def test_cycle_start_soft_warm_starts_the_hard_round_after_an_observed_soft_round(monkeypatch):
    starts = _starts(monkeypatch)
    fit, place = _fit(reading=EARLY, growth={"cycle_start": "soft"})
    assert starts and all(starts) and same_partition(fit.labels_, place)
    starts.clear()
    fit, _ = _fit(reading=EARLY, growth={"cycle_start": "random"})
    assert not any(starts)


def test_warm_cycle_rounds_merge_leftovers_and_no_other_round_does(monkeypatch):
    from topomap.core.refine import methods
    calls = []
    merge = methods.merge_leftovers

    def recorded(*args):
        calls.append(1)
        return merge(*args)
    monkeypatch.setattr(methods, "merge_leftovers", recorded)
    fit, place = _fit(reading=EARLY, growth={"cycle_start": "soft"})
    assert calls and same_partition(fit.labels_, place)
    calls.clear()
    _fit(reading=EARLY, growth={"cycle_start": "random"})
    assert not calls


def _soft_fit(n_states: int, corrected: float) -> SoftFit:
    labels = np.zeros(4, dtype=np.int64)
    return SoftFit(labels, np.zeros(n_states, dtype=np.int64), np.eye(2), labels,
                   {"corrected": corrected})


def test_warm_cycle_by_hand():
    """At least WARM_VISITS steps per state of the soft round, at most WARM_CORRECTED of the
    steps corrected."""
    visits, most = rounds.WARM_VISITS, rounds.WARM_CORRECTED
    steps = int(10 * visits)  # 10 states: exactly WARM_VISITS steps each
    assert rounds.warm_cycle(_soft_fit(10, most), steps)
    assert rounds.warm_cycle(_soft_fit(10, 0.0), steps)
    assert not rounds.warm_cycle(_soft_fit(10, 0.0), steps - 1)  # a step short of the bar
    assert not rounds.warm_cycle(_soft_fit(11, 0.0), steps)  # one state more
    assert not rounds.warm_cycle(_soft_fit(10, most + 0.01), steps)  # too many corrected


def _starts(monkeypatch):
    """The hard rounds' starts (True: warm) recorded as they run."""
    starts = []
    hard_round = EMRefinement._hard_round

    def recorded(self, seq, split_state_symbol, random_state, init=None, split_labels=None,
                 **kw):
        starts.append(init is not None)
        return hard_round(self, seq, split_state_symbol, random_state, init, split_labels, **kw)
    monkeypatch.setattr(EMRefinement, "_hard_round", recorded)
    return starts


def test_cycle_start_auto_is_warm_where_the_places_are_visited_often(monkeypatch):
    """The ring: 6,000 steps on 10 places (600 a state) with 4 % misreads: "auto" starts the
    hard rounds on corrected symbols warm, as "soft" does, and maps the ring."""
    starts = _starts(monkeypatch)
    fit, place = _fit(reading=EARLY, growth={"cycle_start": "auto"})
    assert starts and all(starts) and same_partition(fit.labels_, place)


@pytest.mark.parametrize("bar", ["WARM_VISITS", "WARM_CORRECTED"])
def test_cycle_start_auto_is_cold_past_either_bar(monkeypatch, bar):
    """The same walk with a bar it misses (more steps per state than it has, or no corrected
    step allowed): every hard round on corrected symbols starts from random counts."""
    monkeypatch.setattr(rounds, bar, {"WARM_VISITS": 1e6, "WARM_CORRECTED": -1.0}[bar])
    starts = _starts(monkeypatch)
    fit, place = _fit(reading=EARLY, growth={"cycle_start": "auto"})
    assert any("hard_states" in r for r in fit.info_["soft_rounds"])  # a cycle ran
    assert not any(starts) and same_partition(fit.labels_, place)
