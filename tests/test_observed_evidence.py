"""Soft evidence from each step's own observation (topomap.core.refine.observed,
``refine.reading.temperature``): the evidence on hand-made log-densities, the refinement on the
misread ring walk with evidence that holds the true symbol or leaves it out, and the learner
handing phase 1's log-densities on."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.refine import observed, rounds
from topomap.core.refine.methods import EMRefinement
from topomap.core.refine.observed import SHARE, observed_evidence, step_evidence
from topomap.core.refine.sequence import SymbolSequence
from topomap.core.refine.structure import same_partition

from test_soft_refine import RING, _ring_walk, _seq


def test_step_evidence_is_the_tempered_likelihood_relative_to_the_best_symbol():
    loglik = np.array([[0.0, -1.0], [-2.0, 0.0], [5.0, -100.0], [0.0, 0.0]])
    sym = np.array([0, 1, 0, 2])  # the last step reads GDS id 2: its row is ignored
    ev = step_evidence(loglik, sym, 2, 3, 2.0)
    np.testing.assert_allclose(ev[0], [1.0, np.exp(-0.5), 0.0])
    np.testing.assert_allclose(ev[1], [np.exp(-1.0), 1.0, 0.0])
    # symbol 1 at step 2: -105 / 2 = -52.5, far below log(SHARE): not a candidate
    assert -105 / 2 < np.log(SHARE)
    np.testing.assert_allclose(ev[2], [1.0, 0.0, 0.0])
    # the share bounds the tempered evidence: -20 nats is out at temperature 1, in at 2 (-10)
    ll = np.array([[0.0, -20.0]])
    np.testing.assert_array_equal(step_evidence(ll, [0], 2, 2, 1.0), [[1, 0]])
    np.testing.assert_allclose(step_evidence(ll, [0], 2, 2, 2.0), [[1, np.exp(-10)]])
    np.testing.assert_array_equal(ev[3], [0.0, 0.0, 1.0])  # a GDS step keeps its id
    # a step no model gives a finite density keeps its symbol as read
    lost = step_evidence(np.array([[-np.inf, -np.inf]]), [1], 2, 2, 6.0)
    np.testing.assert_array_equal(lost, [[0.0, 1.0]])
    # a higher temperature flattens the evidence
    assert step_evidence(loglik, sym, 2, 3, 4.0)[0, 1] == pytest.approx(np.exp(-0.25))


def _ring_loglik(sym, place, true_gap):
    """Log-densities of the ring walk's steps: 0 for the symbol read, ``-true_gap`` for the
    place's true symbol where it was misread, -30 for every other symbol."""
    loglik = np.full((sym.size, 3), -30.0)
    loglik[np.arange(sym.size), RING[place]] = -true_gap
    loglik[np.arange(sym.size), sym] = 0.0
    return loglik


ALL = {"temperature": 1.0, "observed_in": "all"}  # every soft round on the per-step evidence


def test_evidence_that_holds_the_true_symbol_recovers_the_ring():
    """Every misread step's evidence gives its place's true symbol 0.6 of the read one's weight
    (temperature 1): the soft rounds put every step, misread ones too, in its place's state."""
    sym, u, lengths, place, wrong = _ring_walk()
    seq = _seq(sym, u, lengths)
    loglik = _ring_loglik(sym, place, -np.log(0.6))
    fit = EMRefinement(evidence="soft", reading=ALL).fit(seq, RING, 0, observed=loglik)
    assert fit.n_states_ == RING.size and same_partition(fit.labels_, place)
    np.testing.assert_array_equal(fit.state_symbol_[fit.labels_[wrong]], RING[place[wrong]])
    assert all(r["evidence"] == "observed" for r in fit.info_["soft_rounds"])


def test_evidence_without_the_true_symbol_cannot_correct_a_misread():
    """The same walk, but each misread step's evidence leaves its true symbol out (its
    likelihood 30 nats below the read one's, under SHARE): no clone of the true symbol may
    explain it, so every misread step stays in a state of the symbol read."""
    sym, u, lengths, place, wrong = _ring_walk()
    seq = _seq(sym, u, lengths)
    for reading in (ALL, {"temperature": 1.0, "observed_in": "last"}):  # every round, or the last
        fit = EMRefinement(evidence="soft", reading=reading).fit(
            seq, RING, 0, observed=_ring_loglik(sym, place, 30.0))
        np.testing.assert_array_equal(fit.state_symbol_[fit.labels_[wrong]], sym[wrong])


def test_last_takes_the_per_step_evidence_in_the_last_soft_round_only():
    """``observed_in="last"``: the cycles run on the confusion matrix (their records as without
    the evidence), the map's round on the per-step evidence."""
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    loglik = _ring_loglik(sym, place, -np.log(0.6))
    fit = EMRefinement(evidence="soft", reading={"observed_in": "last"}).fit(seq, RING, 0,
                                                                              observed=loglik)
    plain = EMRefinement(evidence="soft", reading={"temperature": 0.0}).fit(seq, RING, 0)
    records, before = fit.info_["soft_rounds"], plain.info_["soft_rounds"]
    assert [r.get("evidence") for r in records] == [None] * (len(records) - 1) + ["observed"]
    assert records[:-1] == before[:-1]
    assert same_partition(fit.labels_, place)


def test_the_evidence_is_asked_for_only_when_a_soft_round_runs():
    """The log-densities come as a function; the exact ring walk runs no soft round, so it is
    never called, and the fit is the one without it."""
    sym, u, lengths, _, _ = _ring_walk(misread=0.0)
    seq = _seq(sym, u, lengths)
    calls = []

    def loglik():
        calls.append(1)
        return np.zeros((seq.T, 3))
    fit = EMRefinement(reading={"temperature": 6.0}).fit(seq, RING, 0, observed=loglik)
    plain = EMRefinement().fit(seq, RING, 0)
    assert calls == [] and fit.info_["soft"] == "skipped"
    np.testing.assert_array_equal(fit.labels_, plain.labels_)


def test_observed_off_or_not_given_is_the_confusion_matrix():
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    off = EMRefinement(reading={"temperature": 0.0})
    with_ll = off.fit(seq, RING, 0, observed=_ring_loglik(sym, place, 30.0))
    labels, info = with_ll.labels_.copy(), with_ll.info_
    without = EMRefinement().fit(seq, RING, 0)  # on, but no log-densities given
    np.testing.assert_array_equal(labels, without.labels_)
    assert info == without.info_


def test_bad_observed_input_is_refused_with_its_name():
    seq = SymbolSequence.build([0, 1, 0, 1], [0, 0, 0, 0], [4], 1, 2)
    assert observed_evidence(seq, 6.0, None) is None
    with pytest.raises(ValueError, match=r"observed: must be \(4, 2\)"):
        observed_evidence(seq, 6.0, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="observed: the log-densities must be finite"):
        observed_evidence(seq, 6.0, np.full((4, 2), np.nan))
    assert observed_evidence(seq, 0.0, None) is None
    with pytest.raises(ParameterError, match="^reading.temperature must be >= 0 and finite"):
        EMRefinement(reading={"temperature": -1.0}).check_params()
    with pytest.raises(ParameterError,
                       match="^reading.observed_in must be one of last, auto, early, all"):
        EMRefinement(reading={"observed_in": "first"}).check_params()


def test_a_round_past_the_memory_bound_is_the_confusion_matrix_round(monkeypatch):
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    monkeypatch.setattr(observed, "MAX_BYTES", 1000)
    fit = EMRefinement(evidence="soft", reading=ALL).fit(seq, RING, 0,
                                                         observed=_ring_loglik(sym, place, 1.0))
    plain = EMRefinement(evidence="soft", reading={"temperature": 0.0}).fit(seq, RING, 0)
    np.testing.assert_array_equal(fit.labels_, plain.labels_)
    assert all(r["observed"] == "over MAX_BYTES" for r in fit.info_["soft_rounds"])


def test_the_learner_hands_phase_1_log_densities_to_the_soft_rounds():
    """A ring of 10 places with 3 aliased views in 2-D, read with noise that carries some views
    across their cluster's boundary: the learner's soft rounds take the per-step evidence."""
    sym, u, _, place, _ = _ring_walk(T=3000, misread=0.0, episodes=1)
    centres = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    X = centres[sym] + np.random.default_rng(1).normal(0.0, 0.3, (sym.size, 2))
    learner = MapLearner(n_clusters=3, n_states=10, refine=EMRefinement(
        evidence="soft", reading={"temperature": 6.0}), motion="discrete",
        random_state=0).fit(X, u)
    records = learner.refine_info_["soft_rounds"]
    assert records and records[-1]["evidence"] == "observed"
    assert learner.labels_.shape == place.shape


def test_pair_read_is_the_largest_confusion_between_two_k_means_symbols():
    conf = np.array([[0.8, 0.15, 0.05], [0.4, 0.6, 0.0], [0.0, 0.0, 1.0]])
    assert rounds.pair_read(conf, 2) == pytest.approx(0.4)  # the GDS row and column left out
    assert rounds.pair_read(np.eye(3), 3) == 0.0


def _auto_records(sym, u, lengths, split_symbol, n_symbols):
    seq = SymbolSequence.build(sym, u, lengths, 3, n_symbols)
    loglik = np.full((sym.size, n_symbols), -30.0)
    loglik[np.arange(sym.size), sym] = 0.0
    fit = EMRefinement(evidence="soft", reading={"observed_in": "auto"}).fit(
        seq, split_symbol, 0, observed=loglik)
    return fit.info_["soft_rounds"]


def test_auto_takes_the_per_step_evidence_after_a_first_round_of_plain_misreads():
    """The ring's misreads are spread over the other symbols (4 %): the first round's confusion
    matrix reads no symbol as another often, so the rounds after it take the evidence."""
    sym, u, lengths, place, _ = _ring_walk()
    records = _auto_records(sym, u, lengths, RING, 3)
    assert records[0]["paired"] < rounds.PAIRED_READ and "evidence" not in records[0]
    assert len(records) > 1 and all(r["evidence"] == "observed" for r in records[1:])


def test_auto_keeps_the_confusion_matrix_where_the_first_round_pairs_two_symbols(monkeypatch):
    """The same walk with the first round's confusion matrix taken to pair two symbols (as on
    the office, where phase 1 cuts some places' views in two: 0.20-0.50): only the last round
    takes the per-step evidence."""
    sym, u, lengths, place, _ = _ring_walk()
    monkeypatch.setattr(rounds, "pair_read", lambda conf, n: rounds.PAIRED_READ)
    records = _auto_records(sym, u, lengths, RING, 3)
    assert records[0]["paired"] == rounds.PAIRED_READ
    assert [r.get("evidence") for r in records[1:]] == [None] * (len(records) - 2) + ["observed"]


def test_read_moved_sums_the_clones_of_each_symbol_by_hand():
    # clones 0 and 2 read symbol 0, clone 1 symbol 1; symbol 2 (a GDS id) has no clone
    occupancy = np.array([[0.3, 0.1, 0.0, 0.25],
                          [0.4, 0.8, 0.5, 0.5],
                          [0.3, 0.1, 0.5, 0.25]])
    read, moved = observed._read_moved(occupancy, np.array([0, 1, 0]), 3, None)
    # symbol 0 holds 0.6 / 0.2 / 0.5 / 0.5 against symbol 1's 0.4 / 0.8 / 0.5 / 0.5: ties go to
    # the lower symbol
    np.testing.assert_array_equal(read, [0, 1, 0, 0])
    assert moved == 1.0  # nothing to compare with
    _, moved = observed._read_moved(occupancy, np.array([0, 1, 0]), 3, np.array([0, 1, 1, 1]))
    assert moved == 0.5
