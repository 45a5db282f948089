"""Soft symbol evidence (topomap.core.refine.soft, soft_kernels): kernels against enumeration of
every path on a tiny model, and the refinement on a hand-built aliased world with misreads."""

import itertools

import numpy as np
import pytest

from topomap.core.refine import methods, rounds
from topomap.core.refine.methods import CSCGRefinement, EMRefinement
from topomap.core.refine import soft_kernels
from topomap.core.refine.sequence import SymbolSequence
from topomap.core.refine.settings import Reading, SoftRounds
from topomap.core.refine.soft import (co_successors, initial_confusion, misread_share,
                                      soft_round, successor_surprise)
from topomap.core.refine.soft_states import twin_overlap
from topomap.core.refine.soft_kernels import (SoftData, SoftModel, SoftStats, soft_backward,
                                              soft_candidates, soft_forward, soft_offsets,
                                              soft_viterbi)
from topomap.core.refine.structure import same_partition


def _tiny(seed=0):
    """3 clones (symbols 0, 0, 1), 2 read symbols, 2 actions, episodes of 3 and 2 steps; clone 2
    never reads symbol 0 (a zero of the evidence: the sparse candidates skip it)."""
    rng = np.random.default_rng(seed)
    A, S = 2, 3
    trans = rng.random((A, S, S)) + 0.1
    trans /= trans.sum(axis=2, keepdims=True)
    emit = np.array([[0.8, 0.2], [0.7, 0.3], [0.0, 1.0]])
    init = np.array([0.5, 0.3, 0.2])
    read = np.array([0, 1, 0, 1, 1], dtype=np.int64)
    u = np.array([0, 1, 0, 1, 0], dtype=np.int64)
    has_next = np.array([True, True, False, True, False])
    cptr, cidx = soft_candidates(emit)
    return SoftData(read, u, has_next), SoftModel(trans, emit, init, cptr, cidx)


def _enumerate(data, model):
    """Every clone path: log-likelihood, expected counts and the best path (brute force)."""
    T, S = data.read.size, model.init.size
    starts = [0] + [t + 1 for t in range(T - 1) if not data.has_next[t]]
    total, tr = 0.0, np.zeros_like(model.trans)
    em, ini = np.zeros_like(model.emit), np.zeros(S)
    best_path, best_lp = [], 0.0
    bounds = list(zip(starts, starts[1:] + [T]))
    for t0, t1 in bounds:  # episodes are independent
        probs = {}
        for path in itertools.product(range(S), repeat=t1 - t0):
            p = model.init[path[0]]
            for k, c in enumerate(path):
                t = t0 + k
                p *= model.emit[c, data.read[t]]
                if k:
                    p *= model.trans[data.u[t - 1], path[k - 1], c]
            probs[path] = p
        z = sum(probs.values())
        total += np.log(z)
        for path, p in probs.items():
            w = p / z
            ini[path[0]] += w
            for k, c in enumerate(path):
                em[c, data.read[t0 + k]] += w
                if k:
                    tr[data.u[t0 + k - 1], path[k - 1], c] += w
        path = max(probs, key=probs.get)
        best_path += list(path)
        best_lp += np.log(probs[path])
    return total, tr, em, ini, np.array(best_path), best_lp


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kernels_match_enumeration(seed):
    data, model = _tiny(seed)
    ll, tr, em, ini, best, best_lp = _enumerate(data, model)
    pos = soft_offsets(data, model)
    alpha, log_c = soft_forward(data, model, pos, 0.0)
    assert log_c.sum() == pytest.approx(ll, rel=1e-10)
    stats = SoftStats(np.zeros_like(model.trans), np.zeros_like(model.emit), np.zeros(3))
    soft_backward(data, model, pos, alpha, log_c, stats)
    np.testing.assert_allclose(stats.trans, tr, atol=1e-12)
    np.testing.assert_allclose(stats.emit, em, atol=1e-12)
    np.testing.assert_allclose(stats.init, ini, atol=1e-12)
    with np.errstate(divide="ignore"):
        log_model = SoftModel(np.log(model.trans), np.log(model.emit), np.log(model.init),
                              model.cptr, model.cidx)
    path, lp = soft_viterbi(data, log_model, pos)
    np.testing.assert_array_equal(path, best)
    assert lp == pytest.approx(best_lp, rel=1e-10)


def _soft_forward_row_by_row(data, model, pos, prune):
    """The soft forward pass written out: each step's message sums the transition rows of the
    non-zero messages before it one by one, in order, weighs them by the evidence, then is
    scaled to sum 1 (summed in order) and pruned."""
    alpha, log_c = np.zeros(pos[-1]), np.zeros(data.read.size)
    for t, r in enumerate(data.read):
        cand = model.cidx[model.cptr[r]:model.cptr[r + 1]]
        if t == 0 or not data.has_next[t - 1]:
            acc = model.init[cand] * model.emit[cand, r]
        else:
            before = model.cidx[model.cptr[data.read[t - 1]]:model.cptr[data.read[t - 1] + 1]]
            acc = np.zeros(cand.size)
            for i, ci in enumerate(before):
                if alpha[pos[t - 1] + i] != 0.0:
                    acc = acc + alpha[pos[t - 1] + i] * model.trans[data.u[t - 1], ci, cand]
            acc = acc * model.emit[cand, r]
        c = 0.0
        for x in acc:
            c += x
        scaled = acc / c
        alpha[pos[t]:pos[t + 1]] = np.where(scaled >= prune, scaled, 0.0)
        log_c[t] = np.log(c)
    return alpha, log_c


@pytest.mark.parametrize("prune", [0.0, 0.05])
def test_soft_forward_sums_the_rows_in_order(prune):
    """The soft forward pass (rows of non-zero messages added two at a time where a step's
    candidates are a run of clones) gives the messages of the pass written out row by row, bit
    for bit, with pruned candidates leaving odd and even numbers of rows a step."""
    rng = np.random.default_rng(7)
    A, S, K, T = 2, 9, 3, 2000
    trans = rng.random((A, S, S)) ** 4 + 1e-3
    trans /= trans.sum(axis=2, keepdims=True)
    emit = rng.random((S, K)) + 0.05
    emit /= emit.sum(axis=1, keepdims=True)
    cptr, cidx = soft_candidates(emit)
    has_next = np.ones(T, dtype=bool)
    has_next[[700, T - 1]] = False
    data = SoftData(rng.integers(0, K, T), rng.integers(0, A, T), has_next)
    model = SoftModel(trans, emit, np.full(S, 1.0 / S), cptr, cidx)
    pos = soft_offsets(data, model)
    alpha, log_c = soft_forward(data, model, pos, prune)
    want, want_log_c = _soft_forward_row_by_row(data, model, pos, prune)
    np.testing.assert_array_equal(alpha, want)
    np.testing.assert_allclose(log_c, want_log_c, rtol=1e-15, atol=0)
    rows = np.add.reduceat(alpha != 0, pos[:-1])
    assert prune == 0.0 or (np.any(rows % 2 == 1) and np.any(rows % 2 == 0))


def test_soft_viterbi_ties_go_to_the_earliest_candidates():
    """A log model under which every path is as probable as every other (all zeros): the path
    takes the first candidate of every step, and its log-probability is 0."""
    data, model = _tiny()
    zeros = SoftModel(np.zeros_like(model.trans), np.zeros_like(model.emit), np.zeros(3),
                      model.cptr, model.cidx)
    path, lp = soft_viterbi(data, zeros, soft_offsets(data, model))
    np.testing.assert_array_equal(path, model.cidx[model.cptr[data.read]])
    assert lp == 0.0


def test_candidates_skip_zero_evidence():
    data, model = _tiny()
    # read symbol 0 allows clones 0 and 1 only; read symbol 1 all three
    assert model.cidx[model.cptr[0]:model.cptr[1]].tolist() == [0, 1]
    assert model.cidx[model.cptr[1]:model.cptr[2]].tolist() == [0, 1, 2]
    assert soft_offsets(data, model).tolist() == [0, 2, 5, 7, 10, 13]


# ----------------------------------------------------------------- an aliased ring with misreads
RING = np.array([0, 1, 0, 2, 1, 0, 0, 2, 1, 2])  # symbol of each of 10 places, aliased


def _ring_walk(T=6000, misread=0.04, seed=0, episodes=3):
    """A random walk on the ring (actions: 0 = forward, 1 = back, 2 = stay), the symbol of each
    step's place read wrong at a known set of steps."""
    rng = np.random.default_rng(seed)
    n = RING.size
    u = rng.integers(0, 3, T)
    place = np.empty(T, dtype=np.int64)
    x = 0
    for t in range(T):
        place[t] = x
        x = (x + (1, -1, 0)[u[t]]) % n
    sym = RING[place].copy()
    wrong = np.flatnonzero(rng.random(T) < misread)
    sym[wrong] = (sym[wrong] + rng.integers(1, 3, wrong.size)) % 3
    lengths = np.full(episodes, T // episodes)
    lengths[-1] += T - lengths.sum()
    return sym, u, lengths, place, wrong


def _seq(sym, u, lengths):
    return SymbolSequence.build(sym, u, lengths, 3, 3)


def _checked(est):
    """``est`` with its checked settings, as ``fit`` sets them (for its rounds called alone)."""
    est.settings_ = est.check_params()
    return est


def test_soft_refinement_recovers_ring_with_misreads():
    sym, u, lengths, place, wrong = _ring_walk()
    seq = _seq(sym, u, lengths)
    hard = EMRefinement(evidence="hard").fit(seq, RING, 0)
    assert hard.n_states_ > RING.size  # misreads multiply the hard refinement's states
    fit = EMRefinement(evidence="soft").fit(seq, RING, 0)
    assert fit.n_states_ == RING.size
    assert same_partition(fit.labels_, place)  # every step, misread ones too, in its place's state
    # the state of every misread step emits the place's true symbol
    np.testing.assert_array_equal(fit.state_symbol_[fit.labels_[wrong]], RING[place[wrong]])
    assert fit.info_["soft"] == "on"


def test_auto_keeps_hard_result_without_misreads():
    sym, u, lengths, place, _ = _ring_walk(misread=0.0)
    seq = _seq(sym, u, lengths)
    hard = EMRefinement(evidence="hard").fit(seq, RING, 0)
    auto = EMRefinement().fit(seq, RING, 0)
    np.testing.assert_array_equal(auto.labels_, hard.labels_)
    assert auto.info_["soft"] == "skipped"
    assert same_partition(auto.labels_, place)
    # the states predict every next symbol: no soft round runs at all
    assert auto.info_["surprise"] == 0.0 and auto.info_["soft_rounds"] == []



def test_a_hard_round_cut_short_finishes_as_the_whole_round():
    """Misreads show after stage 2 (many transitions go to a symbol their state does not
    predict), so the first hard round stops there; finishing it gives the whole round."""
    sym, u, lengths, _, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    est = _checked(EMRefinement())
    cut = est._first_hard_round(seq, RING, 0)
    assert cut.info["cut"] and cut.info["rounds_on_all_steps"] == 0
    assert successor_surprise(seq, cut.labels) >= methods.CUT_SURPRISE * Reading().detect
    whole = est._hard_round(seq, RING, 0)
    assert whole.info["rounds_on_all_steps"] >= 1
    resumed = cut.resume()
    np.testing.assert_array_equal(resumed.labels, whole.labels)
    np.testing.assert_array_equal(resumed.state_symbol, whole.state_symbol)
    assert resumed.info == whole.info


@pytest.mark.parametrize("soft_surprise", [None, 1.0])
def test_exact_readings_after_a_cut_give_the_uncut_fit(monkeypatch, soft_surprise):
    """Exact readings: a first hard round cut short (every cut forced) is finished, and the fit
    is the one without cuts -- whether the soft rounds stop at once (surprise below detect) or
    after the first soft round finds no misreads (the surprise forced high)."""
    sym, u, lengths, _, _ = _ring_walk(misread=0.0)
    seq = _seq(sym, u, lengths)
    if soft_surprise is not None:
        monkeypatch.setattr(rounds, "successor_surprise", lambda *a: soft_surprise)
    monkeypatch.setattr(methods, "CUT_SURPRISE", float("inf"))  # never cut
    uncut = EMRefinement().fit(seq, RING, 0)
    monkeypatch.setattr(methods, "CUT_SURPRISE", -1.0)  # always cut
    cut = EMRefinement().fit(seq, RING, 0)
    assert "cut" not in uncut.info_ and uncut.info_["soft"] == "skipped"
    np.testing.assert_array_equal(cut.labels_, uncut.labels_)
    assert cut.info_ == uncut.info_

@pytest.mark.parametrize("settle", [rounds.SETTLE_REREAD, 0.0])
def test_soft_rounds_stop_once_the_reread_symbols_settle(monkeypatch, settle):
    """On the ring with misreads, the first soft round reads every step as its place's symbol
    (each misread corrected, nothing else) and the second reads the same symbols again: the hard
    round on them would repeat the one before, so the rounds stop after one hard round.  With
    the rule off (``SETTLE_REREAD = 0``) a second hard round runs and finds the same map."""
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    reads, hard_rounds = [], []
    soft_round_of, hard_round_of = rounds.soft_round, EMRefinement._first_hard_round

    def recorded_soft(*args, **kwargs):
        fit = soft_round_of(*args, **kwargs)
        reads.append(fit.sym)
        return fit

    def counted_hard(self, *args, cycle=False):
        if cycle:
            hard_rounds.append(args[0].sym)
        return hard_round_of(self, *args, cycle=cycle)

    monkeypatch.setattr(rounds, "soft_round", recorded_soft)
    monkeypatch.setattr(EMRefinement, "_first_hard_round", counted_hard)
    monkeypatch.setattr(rounds, "SETTLE_REREAD", settle)
    fit = EMRefinement().fit(seq, RING, 0)
    np.testing.assert_array_equal(reads[0], RING[place])
    np.testing.assert_array_equal(reads[1], RING[place])
    assert [r["reread"] for r in fit.info_["soft_rounds"] if "reread" in r][0] == 0.0
    assert len(hard_rounds) == (1 if settle > 0 else 2)
    assert not any("hard_cut" in r for r in fit.info_["soft_rounds"])
    np.testing.assert_array_equal(hard_rounds[0], RING[place])
    assert fit.n_states_ == RING.size and same_partition(fit.labels_, place)


def _refit_with_nothing_corrected(monkeypatch, corrected=None):
    """The ring refined with one soft round whose symbols are forced back to the ones read (its
    record's ``corrected`` set to ``corrected`` unless None): ``(fit, the records of the hard
    rounds on its symbols that were asked for as cut-short rounds)``."""
    sym, u, lengths, _, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    soft_round_of, cycle_rounds = rounds.soft_round, []
    hard_round_of = EMRefinement._first_hard_round

    def nothing_corrected(*args, **kwargs):
        fit = soft_round_of(*args, **kwargs)
        fit.sym = seq.sym.copy()
        if corrected is not None:
            fit.info["corrected"] = corrected
        return fit

    def recorded_hard(self, *args, cycle=False):
        fit = hard_round_of(self, *args, cycle=cycle)
        if cycle:
            cycle_rounds.append(fit.info)
        return fit

    monkeypatch.setattr(rounds, "soft_round", nothing_corrected)
    monkeypatch.setattr(EMRefinement, "_first_hard_round", recorded_hard)
    return EMRefinement(soft={"rounds": 1}).fit(seq, RING, 0), cycle_rounds


@pytest.mark.parametrize("cut", [True, False])
def test_a_hard_round_on_symbols_still_misread_is_cut_short(monkeypatch, cut):
    """A soft round that corrects nothing (its symbols forced back to the ones read) leaves
    the ring's misreads: the hard round on its symbols is the first hard round again, whose
    stage-2 labelling shows them (``test_a_hard_round_cut_short_finishes_as_the_whole_round``),
    so it stops there too (``hard_cut``); with the cut off (``CUT_SURPRISE`` infinite) it runs
    its rounds on all steps.  Exact corrected symbols never cut it (``hard_cut`` absent in
    ``test_soft_rounds_stop_once_the_reread_symbols_settle``'s fit)."""
    if not cut:
        monkeypatch.setattr(methods, "CUT_SURPRISE", float("inf"))
    fit, cycle_rounds = _refit_with_nothing_corrected(monkeypatch)
    assert len(cycle_rounds) == 1
    assert cycle_rounds[0].get("cut", False) is cut
    assert (cycle_rounds[0]["rounds_on_all_steps"] == 0) is cut
    assert fit.info_["soft_rounds"][0].get("hard_cut", False) is cut


@pytest.mark.parametrize("corrected", [0.0, 0.5])
def test_a_soft_round_that_corrected_hardly_any_step_leaves_its_hard_round_whole(monkeypatch,
                                                                                corrected):
    """As above (the soft round's symbols forced back to the ones read, so the hard round on
    them would be cut), but the soft round's record says it corrected ``corrected`` of the
    steps: 0 is below ``CUT_CORRECTED`` x ``reading.detect`` (5 x 0.002 = 0.01), so the surprise
    left is not taken for misreads and the hard round runs whole (no cut round asked for, no
    ``hard_cut``); 0.5 is above, and the round is cut as before."""
    fit, cycle_rounds = _refit_with_nothing_corrected(monkeypatch, corrected)
    cut = corrected >= rounds.CUT_CORRECTED * 0.002
    assert len(cycle_rounds) == int(cut)
    assert fit.info_["soft_rounds"][0].get("hard_cut", False) is cut


@pytest.mark.parametrize("explained", [True, False])
def test_the_map_is_tried_first_after_a_hard_round_that_explains_its_symbols(monkeypatch,
                                                                             explained):
    """On the ring with misreads the first soft round corrects every misread, so the hard round
    on its symbols maps the ring's places and predicts every next symbol: the last soft round
    (no spare clones: one clone per place) is tried at once, re-reads every symbol as it is and
    gives the map -- one soft round with spare clones in all.  Without that (the hard round
    said not to explain its symbols) a second soft round with spare clones runs first."""
    sym, u, lengths, place, _ = _ring_walk()
    seq = _seq(sym, u, lengths)
    spare_rounds, spare_of = [], rounds._spare_soft_round
    cycle_of = EMRefinement._cycle_hard_round

    def counted_spare(*args):
        spare_rounds.append(args[0])
        return spare_of(*args)

    monkeypatch.setattr(rounds, "_spare_soft_round", counted_spare)
    if not explained:
        monkeypatch.setattr(EMRefinement, "_cycle_hard_round",
                            lambda self, *args: (cycle_of(self, *args)[0], False))
    fit = EMRefinement().fit(seq, RING, 0)
    last = fit.info_["soft_rounds"][-1]
    assert len(spare_rounds) == (1 if explained else 2)
    assert last["clones"] == RING.size and "hard_states" not in last
    assert ("reread" in last) is explained and last.get("reread", 0.0) == 0.0
    assert fit.n_states_ == RING.size and same_partition(fit.labels_, place)


def test_reread_share_counts_the_changed_symbols():
    assert rounds.reread_share([0, 1, 2, 2], [0, 1, 1, 0]) == 0.5
    assert rounds.reread_share([3], [3]) == 0.0


# a hand-made walk: labels 0 1 0 | 1 0 1 (two episodes), action 0 throughout, symbols 0 1 0 | 0 0 2
# transitions inside the episodes: (state 0 -> 1), (1 -> 0), (1 -> 0), (0 -> 2)
_HAND = dict(sym=[0, 1, 0, 0, 0, 2], labels=np.array([0, 1, 0, 1, 0, 1]), lengths=[3, 3])


def test_successor_surprise_counts_the_unpredicted_next_symbols():
    seq = SymbolSequence.build(_HAND["sym"], np.zeros(6), _HAND["lengths"], 1, 3)
    # state 0 is followed by 1 and 2 (one of its two transitions unpredicted), state 1 by 0, 0
    assert successor_surprise(seq, _HAND["labels"]) == pytest.approx(1 / 4)
    # one episode: the step 2 -> 3 (state 0 -> symbol 0) joins state 0's successors 1, 0, 2
    one = SymbolSequence.build(_HAND["sym"], np.zeros(6), [6], 1, 3)
    assert successor_surprise(one, _HAND["labels"]) == pytest.approx(2 / 5)


def test_co_successors_pair_the_symbols_one_state_action_leads_to():
    seq = SymbolSequence.build(_HAND["sym"], np.zeros(6), _HAND["lengths"], 1, 3)
    allowed = co_successors(seq, _HAND["labels"])
    off = allowed & ~np.eye(3, dtype=bool)
    assert {tuple(p) for p in np.argwhere(off)} == {(1, 2), (2, 1)}


def test_initial_confusion_spreads_the_error_over_the_allowed_pairs_only():
    allowed = np.zeros((3, 3), dtype=bool)
    allowed[1, 2] = allowed[2, 1] = True
    C = initial_confusion(4, 3, 0.2, allowed)  # 3 symbols and one GDS id
    np.testing.assert_allclose(C, [[1, 0, 0, 0], [0, 0.9, 0.1, 0], [0, 0.1, 0.9, 0],
                                   [0, 0, 0, 1]])
    np.testing.assert_allclose(initial_confusion(3, 3, 0.2)[0], [0.8, 0.1, 0.1])


def test_misread_share_is_the_off_diagonal_share_of_the_symbol_counts():
    N = np.array([[8.0, 2.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0, 50.0]])  # id 2: a GDS
    assert misread_share(N, 2) == pytest.approx(2 / 20)
    assert misread_share(np.zeros((2, 2)), 2) == 0.0


def test_exact_readings_stop_a_soft_round_early():
    sym, u, lengths, place, _ = _ring_walk(misread=0.0)
    r = Reading()
    fit = soft_round(_seq(sym, u, lengths), place, RING, reading=r, exact_below=r.detect)
    assert fit.info["stopped"] == "exact" and fit.info["em_iterations"] <= r.detect_iter
    np.testing.assert_array_equal(fit.labels, place)
    np.testing.assert_array_equal(fit.sym, sym)
    sym, u, lengths, place, _ = _ring_walk(misread=0.06, seed=1)
    noisy = soft_round(_seq(sym, u, lengths), place, RING, reading=r, exact_below=r.detect)
    assert "stopped" not in noisy.info and noisy.info["misread"] > 0.03


@pytest.mark.parametrize("misread", [0.06, 0.12])
def test_squarem_soft_round_corrects_as_plain_em_in_fewer_e_steps(misread):
    """``soft.accelerate="squarem"``: from the hard refinement of the misread ring, the soft
    round corrects the readings at least as well as plain soft EM run to the same ``tol``,
    in fewer E-steps (``max_iter`` high enough that neither stops by it)."""
    sym, u, lengths, place, _ = _ring_walk(misread=misread, seed=1)
    seq = _seq(sym, u, lengths)
    hard = _checked(EMRefinement(evidence="hard"))._hard_round(seq, RING, 0)
    fits = [soft_round(seq, hard.labels, hard.state_symbol,
                       soft=SoftRounds(accelerate=acc, max_iter=200))
            for acc in ("none", "squarem")]
    plain, fast = (np.mean(f.sym != RING[place]) for f in fits)
    assert fast <= plain + 0.002
    assert fits[1].info["em_iterations"] < fits[0].info["em_iterations"] < 200
    assert fits[1].info["em_loglik"] >= fits[0].info["em_loglik"] - 1e-3 * seq.T


def test_squarem_soft_round_still_stops_early_on_exact_readings():
    """The first ``detect_iter`` iterations stay plain EM, so exact readings stop the
    accelerated round as they stop the plain one: 6 misreads in 6,000 steps, fewer than
    ``detect`` (``tol`` 0: EM, which still gains on them, has no other stop before
    ``max_iter``)."""
    sym, u, lengths, place, _ = _ring_walk(misread=0.001)
    r = Reading()
    fit = soft_round(_seq(sym, u, lengths), place, RING, soft=SoftRounds(accelerate="squarem",
                                                                         tol=0.0),
                     reading=r, exact_below=r.detect)
    assert fit.info["stopped"] == "exact" and fit.info["em_iterations"] == r.detect_iter


def test_bad_soft_acceleration_rejected():
    with pytest.raises(ValueError, match="soft.accelerate must be one of none, squarem"):
        EMRefinement(soft={"accelerate": "fast"}).fit(_seq(*_ring_walk(T=30)[:3]), RING, 0)


def test_soft_round_learns_confusion():
    sym, u, lengths, place, wrong = _ring_walk(misread=0.06, seed=1)
    seq = _seq(sym, u, lengths)
    # the true map as a warm start: one state per place
    fit = soft_round(seq, place, RING)
    # 6 % of steps misread, each to one of the two other symbols: off-diagonal mass ~0.06
    assert 0.03 < fit.info["conf_offdiag"] < 0.09
    assert np.mean(fit.sym != RING[place]) < 0.01  # the readings are corrected


def test_cscg_soft_evidence_runs():
    sym, u, lengths, place, _ = _ring_walk(T=3000, misread=0.04)
    fit = CSCGRefinement(hard={"clones_per_symbol": 8, "max_iter": 100}, evidence="soft").fit(
        _seq(sym, u, lengths), RING, 0)
    assert fit.info_["soft"] == "on" and fit.labels_.size == sym.size


def test_gds_never_confused():
    C = initial_confusion(5, 3, 0.2)
    assert np.all(C[3:, :3] == 0) and np.all(C[:3, 3:] == 0)
    np.testing.assert_array_equal(C[3:, 3:], np.eye(2))


def test_gds_stay_exact_after_the_confusion_matrix_is_learned():
    """Places 0 and 4 are GDS 0 and 1 (ids 3 and 4 past the 3 K-means symbols), every other
    step misread 6 % of the time: after EM has learned the confusion matrix, the GDS rows and
    columns are still exactly the identity (no K-means symbol is read as a GDS, no GDS as
    anything else), while the K-means rows have learned their misreads; every GDS step is
    decoded to its own id and no other step to a GDS id."""
    sym, u, lengths, place, _ = _ring_walk(misread=0.06, seed=2)
    gds_place = {0: 3, 4: 4}
    sym = sym.copy()
    for p, g in gds_place.items():
        sym[place == p] = g
    seq = SymbolSequence.build(sym, u, lengths, 3, 3)
    state_symbol = np.array([gds_place.get(p, RING[p]) for p in range(RING.size)])
    fit = soft_round(seq, place, state_symbol)
    C = fit.conf
    np.testing.assert_array_equal(C[3:, :], np.eye(5)[3:])
    np.testing.assert_array_equal(C[:, 3:], np.eye(5)[:, 3:])
    assert 0.02 < fit.info["conf_offdiag"] < 0.1  # the K-means rows did learn
    is_gds = sym >= 3
    np.testing.assert_array_equal(fit.sym[is_gds], sym[is_gds])
    assert not np.any(fit.sym[~is_gds] >= 3)


def test_bad_evidence_rejected():
    with pytest.raises(ValueError, match="evidence"):
        EMRefinement(evidence="fuzzy").check_params()


def test_gds_steps_stay_in_their_state():
    """A GDS place (symbol id 3 past the 3 K-means symbols) is never confused: its steps, and only
    they, form one state."""
    sym, u, lengths, place, wrong = _ring_walk(misread=0.04, seed=3)
    sym = sym.copy()
    sym[place == 0] = 3  # place 0 is recognised as GDS 0 every time
    seq = SymbolSequence.build(sym, u, lengths, 3, 3)
    split_symbol = np.where(np.arange(RING.size) == 0, -1, RING)
    fit = EMRefinement(evidence="soft").fit(seq, split_symbol, 0)
    gds_states = np.flatnonzero(fit.state_symbol_ == 3)
    assert gds_states.size == 1
    np.testing.assert_array_equal(fit.labels_ == gds_states[0], place == 0)
    assert fit.n_states_ == RING.size
    # every step in its place's state but the last two, both misread (nothing follows them)
    assert same_partition(fit.labels_[:-2], place[:-2])


def _dense_twin_overlap(labels, state_symbol, u, has_next, n_actions, n_symbols):
    """twin_overlap by its definition: the dense (state x predecessor key) shares of every
    state, compared with every state of another symbol."""
    S = state_symbol.size
    t = np.flatnonzero(has_next)
    P = np.zeros((S, S * n_actions))
    np.add.at(P, (labels[t + 1], labels[t] * n_actions + u[t]), 1.0)
    P /= np.maximum(P.sum(axis=1, keepdims=True), 1.0)
    out, twin = np.zeros(S), np.full(S, -1, dtype=np.int64)
    plain = np.flatnonzero(state_symbol < n_symbols)
    for x in plain:
        others = plain[state_symbol[plain] != state_symbol[x]]
        if others.size:
            ov = np.minimum(P[x], P[others]).sum(axis=1)
            out[x], twin[x] = ov.max(), others[np.argmax(ov)]
    return out, twin


@pytest.mark.parametrize("seed", range(40))
def test_twin_overlap_matches_the_dense_definition(seed):
    """Comparing only the states that share a predecessor key gives the dense overlaps bit for
    bit, and the same twin (the lowest of equals; the first state of another symbol when none
    shares a key)."""
    rng = np.random.default_rng(seed)
    S, A, K, T = int(rng.integers(2, 30)), int(rng.integers(1, 4)), int(rng.integers(1, 4)), 300
    state_symbol = rng.integers(0, K + 2, S)  # ids from K on are GDS
    u = rng.integers(0, A, T)
    succ = rng.integers(0, S, (S, A))
    labels = np.zeros(T, dtype=np.int64)
    for t in range(1, T):  # mostly deterministic moves, some noise
        labels[t] = succ[labels[t - 1], u[t - 1]] if rng.random() < 0.8 else rng.integers(S)
    has_next = rng.random(T) < 0.95
    has_next[-1] = False
    got = twin_overlap(labels, state_symbol, u, has_next, A, K)
    expect = _dense_twin_overlap(labels, state_symbol, u, has_next, A, K)
    np.testing.assert_array_equal(got[0], expect[0])
    np.testing.assert_array_equal(got[1], expect[1])


def _gapped(seed):
    """Like :func:`_tiny` with 4 clones, where read symbol 0 allows clones 0 and 2 only (not a run
    of clones: the backward pass goes candidate by candidate)."""
    rng = np.random.default_rng(seed)
    A, S = 2, 4
    trans = rng.random((A, S, S)) + 0.1
    trans /= trans.sum(axis=2, keepdims=True)
    emit = np.array([[0.8, 0.2], [0.0, 1.0], [0.7, 0.3], [0.0, 1.0]])
    read = np.array([0, 1, 1, 0, 1, 0], dtype=np.int64)
    u = np.array([0, 1, 0, 1, 0, 1], dtype=np.int64)
    has_next = np.array([True, True, False, True, True, False])
    cptr, cidx = soft_candidates(emit)
    return SoftData(read, u, has_next), SoftModel(trans, emit, np.full(S, 0.25), cptr, cidx)


@pytest.mark.parametrize("make", [_tiny, _gapped])
@pytest.mark.parametrize("prune", [0.0, 0.3])
def test_soft_backward_passes_agree_bit_for_bit(make, prune):
    """The backward pass on runs of clones (column by column) and the candidate-by-candidate one
    give the same bits; where the candidates are not a run, the latter is the one taken."""
    data, model = make(1)
    pos = soft_offsets(data, model)
    alpha, log_c = soft_forward(data, model, pos, prune)
    S, K = model.emit.shape
    got = [SoftStats(np.zeros_like(model.trans), np.zeros((S, K)), np.zeros(S)) for _ in range(2)]
    soft_backward(data, model, pos, alpha, log_c, got[0])
    soft_kernels._soft_backward_rows(data, model, pos, alpha, log_c, got[1])
    for a, b in zip(*got):
        np.testing.assert_array_equal(a, b)
    assert got[0].trans.sum() > 0
    runs = soft_kernels._runs_of_clones(model.cptr, model.cidx)
    assert runs == (make is _tiny)


def test_gapped_candidates_match_enumeration():
    data, model = _gapped(2)
    ll, tr, em, ini, _, _ = _enumerate(data, model)
    pos = soft_offsets(data, model)
    alpha, log_c = soft_forward(data, model, pos, 0.0)
    assert log_c.sum() == pytest.approx(ll, rel=1e-10)
    stats = SoftStats(np.zeros_like(model.trans), np.zeros_like(model.emit), np.zeros(4))
    soft_backward(data, model, pos, alpha, log_c, stats)
    np.testing.assert_allclose(stats.trans, tr, atol=1e-12)
    np.testing.assert_allclose(stats.emit, em, atol=1e-12)
    np.testing.assert_allclose(stats.init, ini, atol=1e-12)


# ------------------------------------------- growth stages cut short where the prefix misreads
def _ring_layout(misread=0.04, seed=0):
    """The ring walk with misreads, 4 clones per symbol, random counts."""
    from topomap.core.refine.clones import clone_budget, random_counts
    sym, u, lengths, _, _ = _ring_walk(misread=misread)
    lay = _seq(sym, u, lengths).layout(clone_budget(3, 0, 4))
    return lay, random_counts(lay, np.random.default_rng(seed))


def test_capped_baum_welch_with_no_tolerance_is_baum_welch_itself():
    """``rtol=0``: the stop after the cap is Baum-Welch's own (``tol``), and the run goes on from
    the counts it stopped at -- the same iterations, log-likelihoods and counts as one run."""
    from topomap.core.refine.clones import baum_welch
    lay, init = _ring_layout()
    counts, _, history = baum_welch(lay, init.copy(), 0.01, False, max_iter=30, tol=1e-9)
    capped, capped_history = methods.capped_baum_welch(lay, init.copy(), 0.01, max_iter=30,
                                                       tol=1e-9, cap=12, rtol=0.0)
    assert len(history) == 30  # it never settles by tol: the cap and the rest both run
    assert capped_history == history
    np.testing.assert_array_equal(capped, counts)


def test_capped_baum_welch_goes_on_only_while_it_gains_the_share_asked():
    """After ``cap`` iterations Baum-Welch stops unless its last gain exceeds ``rtol`` x |its
    log-likelihood|; then it stops at the first later iteration gaining less than that."""
    from topomap.core.refine.clones import baum_welch
    lay, init = _ring_layout()
    _, _, full = baum_welch(lay, init.copy(), 0.01, False, max_iter=40, tol=0.0)
    cap = 12
    gain = np.diff(full)
    # a share the gain at the cap exceeds (twice over), but a later gain falls below
    rtol = 0.5 * gain[cap - 2] / abs(full[cap - 1])
    bar = rtol * abs(full[cap - 1])
    later = [j for j in range(cap + 1, 40) if full[j] - full[j - 1] < bar]
    assert later, "the ring's Baum-Welch keeps gaining: pick another rtol"
    _, history = methods.capped_baum_welch(lay, init.copy(), 0.01, max_iter=40, tol=0.0,
                                           cap=cap, rtol=rtol)
    assert len(history) == later[0] + 1
    _, history = methods.capped_baum_welch(lay, init.copy(), 0.01, max_iter=40, tol=0.0,
                                           cap=cap, rtol=4 * rtol)  # the gain at the cap is less
    assert len(history) == cap


@pytest.mark.parametrize("misread, evidence, stage_cap, capped", [
    (0.12, "auto", 15, True), (0.12, "soft", 15, True), (0.0, "auto", 15, False),
    (0.04, "auto", 15, False), (0.12, "hard", 15, False), (0.12, "auto", 0, False),
    (0.12, "auto", 50, False)])
def test_the_growth_stages_are_capped_only_where_the_prefix_shows_misreads(
        misread, evidence, stage_cap, capped):
    """The cap comes with many misreads on the first stage's prefix (12 % of the steps: its
    successor surprise at least ``CAP_SURPRISE`` x ``reading.detect``), never with exact
    symbols, few misreads (4 %), ``evidence="hard"``, ``growth.stage_cap`` 0 or a cap at
    ``hard.max_iter`` or above."""
    sym, u, lengths, _, _ = _ring_walk(misread=misread)
    seq = _seq(sym, u, lengths)
    est = _checked(EMRefinement(evidence=evidence,
                                growth={"stage_cap": stage_cap, "stage_rtol": 0.01}))
    rng = np.random.default_rng(0)
    prefix = seq.head(2000)
    labels, _, _ = est._first_round(prefix, RING, rng)
    surprise = successor_surprise(prefix, labels) / Reading().detect
    assert (surprise >= methods.CAP_SURPRISE) is (misread > 0.1)
    assert (est._stage_cap(prefix, labels) == (stage_cap, 0.01)) is capped


def test_capped_growth_stages_on_the_ring():
    """With 12 % misreads, every growth stage stops at the cap (a relative gain of 1 is never
    reached) where some ran longer without it; on exact symbols the fit is the same with or
    without the cap (the map of a clean walk never changes)."""
    sym, u, lengths, _, _ = _ring_walk(misread=0.12)
    seq = _seq(sym, u, lengths)
    growth = {"stage_cap": 3, "stage_rtol": 1.0}
    free = _checked(EMRefinement(growth={"stage_cap": 0}))._first_hard_round(seq, RING, 0)
    capped = _checked(EMRefinement(growth=growth))._first_hard_round(seq, RING, 0)
    assert max(iters for _, _, iters in free.info["stages"][1:]) > 3
    assert [iters for _, _, iters in capped.info["stages"][1:]] == [3] * (
        len(capped.info["stages"]) - 1)
    sym, u, lengths, _, _ = _ring_walk(misread=0.0)
    seq = _seq(sym, u, lengths)
    exact = EMRefinement().fit(seq, RING, 0)
    exact_capped = EMRefinement(growth=growth).fit(seq, RING, 0)
    np.testing.assert_array_equal(exact_capped.labels_, exact.labels_)
    assert exact_capped.info_ == exact.info_


def test_a_soft_round_stops_by_its_relative_tolerance(monkeypatch):
    """``soft.rtol``: Baum-Welch with soft evidence stops at the first iteration (from the third)
    gaining at most that share of the log-likelihood before it -- read off a run without it."""
    from topomap.core.refine import soft as soft_module
    sym, u, lengths, _, _ = _ring_walk(misread=0.12)
    seq = _seq(sym, u, lengths)
    hard = _checked(EMRefinement(evidence="hard"))._hard_round(seq, RING, 0)
    monitors = []

    class Recorded(soft_module.ConvergenceMonitor):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            monitors.append(self)

    monkeypatch.setattr(soft_module, "ConvergenceMonitor", Recorded)
    soft_round(seq, hard.labels, hard.state_symbol,
               soft=SoftRounds(tol=0.0, max_iter=20, rtol=0.0))
    h = np.array(monitors[-1].history)
    share = np.diff(h) / np.abs(h[:-1])  # share[j - 1]: the gain of iteration j + 1
    rtol = float(np.median(share[2:]))
    stop = next(j for j in range(2, h.size) if h[j] <= h[j - 1] + rtol * abs(h[j - 1]))
    fit = soft_round(seq, hard.labels, hard.state_symbol,
                     soft=SoftRounds(tol=0.0, max_iter=20, rtol=rtol))
    assert fit.info["em_iterations"] == stop + 1 < 20


@pytest.mark.parametrize("misread", [0.04, 0.12])
def test_the_soft_rounds_stop_by_rtol_only_where_misreads_are_many(misread):
    """``soft.rtol`` applies where the hard round's labelling shows many misreads (surprise at
    least ``CAP_SURPRISE`` x ``reading.detect``: 12 % of the ring's steps misread); with 4 % the
    fit is the one without it."""
    sym, u, lengths, _, _ = _ring_walk(misread=misread)
    seq = _seq(sym, u, lengths)
    plain = EMRefinement(soft={"rtol": 0.0}).fit(seq, RING, 0)
    loose = EMRefinement(soft={"rtol": 0.5}).fit(seq, RING, 0)
    first = [fit.info_["soft_rounds"][0]["em_iterations"] for fit in (plain, loose)]
    if misread < 0.1:
        assert plain.info_["surprise"] < rounds.CAP_SURPRISE * Reading().detect
        np.testing.assert_array_equal(loose.labels_, plain.labels_)
        assert loose.info_ == plain.info_
    else:
        assert plain.info_["surprise"] >= rounds.CAP_SURPRISE * Reading().detect
        assert first[1] == 3 < first[0]  # stopped at the first iteration it judges


def _prunes_of_the_soft_rounds(monkeypatch, seq, soft):
    """The fit of the ring with ``soft`` and the ``prune`` every soft round of it ran with."""
    prunes, soft_round_of = [], rounds.soft_round

    def recorded_soft(*args, soft, **kwargs):
        prunes.append(soft.prune)
        return soft_round_of(*args, soft=soft, **kwargs)

    monkeypatch.setattr(rounds, "soft_round", recorded_soft)
    return EMRefinement(soft=soft).fit(seq, RING, 0), prunes


def test_the_soft_rounds_prune_loosely_only_below_the_surprise_bar(monkeypatch):
    """``soft.prune_loose`` replaces ``soft.prune`` in every soft round when the labelling of the
    hard round they start from shows a successor surprise below ``soft.loose_below``, in none
    when the bar is that surprise itself; below it, or with ``prune_loose`` 0, the fit is the
    one without the setting."""
    sym, u, lengths, _, _ = _ring_walk(misread=0.04)
    seq = _seq(sym, u, lengths)
    plain, prunes = _prunes_of_the_soft_rounds(monkeypatch, seq, {})
    surprise = plain.info_["surprise"]
    assert 0 < surprise < 1 and len(prunes) >= 2 and set(prunes) == {1e-6}
    _, prunes = _prunes_of_the_soft_rounds(
        monkeypatch, seq, {"prune_loose": 1e-3, "loose_below": surprise + 1e-9})
    assert len(prunes) >= 2 and set(prunes) == {1e-3}
    for soft in ({"prune_loose": 1e-3, "loose_below": surprise}, {"loose_below": 1.0}):
        fit, prunes = _prunes_of_the_soft_rounds(monkeypatch, seq, soft)
        assert set(prunes) == {1e-6}
        np.testing.assert_array_equal(fit.labels_, plain.labels_)
        assert fit.info_ == plain.info_


def test_bad_loose_pruning_rejected():
    with pytest.raises(ValueError, match="soft.prune_loose"):
        EMRefinement(soft={"prune_loose": 1.5}).fit(_seq(*_ring_walk(T=30)[:3]), RING, 0)
    with pytest.raises(ValueError, match="soft.loose_below"):
        EMRefinement(soft={"loose_below": -0.1}).fit(_seq(*_ring_walk(T=30)[:3]), RING, 0)
