"""The E-step's backward pass on two threads gives the one-thread pass's counts and occupancies
bit for bit: on hand cases, and on random clone tables whose episode ends and piece bounds fall
anywhere (pieces of 1, 2, 3 and 7 steps, one and two threads, pruned clones or none)."""

import threading

import numpy as np
import pytest

from topomap.core.refine import backward, kernels
from topomap.core.refine.backward import backward_counts, backward_counts_threaded, pair_work
from topomap.core.refine.clones import make_layout, m_step
from topomap.core.refine.kernels import clone_backward_counts, clone_forward
from topomap.core.split import threads


@pytest.fixture(params=[1, 2])
def n_threads(request, monkeypatch):
    monkeypatch.setattr(threads, "n_threads", lambda: request.param)
    return request.param


def _bits(x):
    return np.ascontiguousarray(x).view(np.int64)


def _both(lay, vals, prune, chunk, counts=None, occ=None):
    """(counts, occupancy) of the fused pass and of the threaded one, added to the same
    starting values (zeros unless given)."""
    alpha, log_c = clone_forward(lay.tables, vals, prune)
    counts = np.zeros(vals.size) if counts is None else counts
    occ = np.zeros(lay.n_clones) if occ is None else occ
    fused = clone_backward_counts(lay.tables, vals, alpha, log_c, counts.copy(), occ.copy())
    threaded = backward_counts_threaded(lay.tables, vals, alpha, log_c, counts.copy(),
                                        occ.copy(), chunk)
    return fused, threaded


@pytest.mark.parametrize("chunk", [1, 2, 3, 7])
@pytest.mark.parametrize("swap", [False, True])
def test_two_clones_that_keep_or_swap_by_hand(chunk, swap, n_threads):
    """One symbol with two clones, one action: the clones keep (or swap) their place at every
    step, so from the uniform start each clone holds 1/2 at every step; episodes of 3, 1, 4 and
    2 steps make 2 + 0 + 3 + 1 = 6 transitions, 3 on each pair the model allows, and each clone
    is occupied 10 / 2 = 5 steps."""
    lay = make_layout(np.zeros(10, np.int64), np.zeros(10, np.int64), [3, 1, 4, 2], [2], 1)
    vals = np.array([0.0, 1.0, 1.0, 0.0]) if swap else np.array([1.0, 0.0, 0.0, 1.0])
    fused, (counts, occ) = _both(lay, vals, 0.0, chunk)
    np.testing.assert_array_equal(counts, vals * 3.0)
    np.testing.assert_array_equal(occ, [5.0, 5.0])
    np.testing.assert_array_equal(_bits(counts), _bits(fused[0]))
    np.testing.assert_array_equal(_bits(occ), _bits(fused[1]))


def test_a_clone_ruled_out_gets_no_counts_by_hand(n_threads):
    """Symbols 0 1 0 1 0 1 (symbol 0: clones a, b; symbol 1: clone c), one episode: the model
    sends a to c and c to a only, so b is ruled out after the uniform first step (its forward
    probability is 0 from step 2 on) and, given the whole walk, at step 0 too.  The walk is
    a c a c a c: a -> c three times, c -> a twice, a and c occupied three steps each."""
    sym = np.array([0, 1, 0, 1, 0, 1])
    lay = make_layout(sym, np.zeros(6, np.int64), [6], [2, 1], 1)
    # blocks: (0, 0, 1) from {a, b} to {c}: rows a, b; (0, 1, 0) from {c} to {a, b}
    vals = np.array([1.0, 0.0, 1.0, 0.0])
    for chunk in (1, 2, 3, 7):
        fused, (counts, occ) = _both(lay, vals, 0.0, chunk)
        np.testing.assert_array_equal(counts, [3.0, 0.0, 2.0, 0.0])
        np.testing.assert_array_equal(occ, [3.0, 0.0, 3.0])
        np.testing.assert_array_equal(_bits(counts), _bits(fused[0]))
        np.testing.assert_array_equal(_bits(occ), _bits(fused[1]))


def _random_case(seed, T=60, clones=(3, 4, 1, 6), n_actions=2):
    """A random walk of episodes of 1 to 12 steps and a random model with many small entries
    (so that pruning rules clones out)."""
    rng = np.random.default_rng(seed)
    lengths = []
    while sum(lengths) < T:
        lengths.append(int(min(rng.integers(1, 13), T - sum(lengths))))
    sym, u = rng.integers(0, len(clones), T), rng.integers(0, n_actions, T)
    lay = make_layout(sym, u, lengths, np.array(clones), n_actions)
    vals = m_step(lay, rng.random(int(lay.boff[-1])) ** 4, 1e-3, joint=False)
    return lay, vals, rng


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("chunk", [1, 2, 3, 7, 1000])
@pytest.mark.parametrize("prune", [0.0, 0.15])
def test_random_tables_give_the_fused_bits(seed, chunk, prune, n_threads):
    """Few steps on many blocks (the fused pass's row-major route), added to random counts."""
    lay, vals, rng = _random_case(seed)
    assert pair_work(lay.tables) < kernels.COLUMN_PASS_WORK * vals.size
    start = rng.random(vals.size), rng.random(lay.n_clones)
    fused, threaded = _both(lay, vals, prune, chunk, *start)
    np.testing.assert_array_equal(_bits(threaded[0]), _bits(fused[0]))
    np.testing.assert_array_equal(_bits(threaded[1]), _bits(fused[1]))
    assert not np.array_equal(threaded[0], start[0])


@pytest.mark.parametrize("prune", [0.0, 0.05])
def test_long_walk_on_few_blocks_gives_the_fused_bits(prune, n_threads):
    """Many steps on few blocks: the fused pass takes its column-major route here."""
    lay, vals, _ = _random_case(5, T=3000, clones=(5, 3, 6), n_actions=1)
    assert pair_work(lay.tables) >= kernels.COLUMN_PASS_WORK * vals.size
    alpha, _ = clone_forward(lay.tables, vals, prune)
    assert prune == 0.0 or (alpha == 0).any()
    for chunk in (7, 512):
        fused, threaded = _both(lay, vals, prune, chunk)
        np.testing.assert_array_equal(_bits(threaded[0]), _bits(fused[0]))
        np.testing.assert_array_equal(_bits(threaded[1]), _bits(fused[1]))


def test_pair_work_by_hand():
    """Symbols 0 1 1 | 0 with 2 and 3 clones: transitions 0->1 (2 x 3) and 1->1 (3 x 3)."""
    lay = make_layout(np.array([0, 1, 1, 0]), np.zeros(4, np.int64), [3, 1], [2, 3], 1)
    assert pair_work(lay.tables) == 6 + 9


@pytest.mark.parametrize("threads_allowed, work_bound, step_pairs, threaded", [
    (1, 0, 0, False), (2, 0, 0, True), (2, 1 << 40, 0, False), (2, 0, 1 << 20, False)])
def test_the_threads_run_where_allowed_and_worth_it(threads_allowed, work_bound, step_pairs,
                                                    threaded, monkeypatch):
    calls = []
    monkeypatch.setattr(threads, "n_threads", lambda: threads_allowed)
    monkeypatch.setattr(backward, "THREAD_WORK", work_bound)
    monkeypatch.setattr(backward, "THREAD_STEP_PAIRS", step_pairs)
    real = backward.backward_counts_threaded
    monkeypatch.setattr(backward, "backward_counts_threaded",
                        lambda *a: calls.append(1) or real(*a))
    lay, vals, _ = _random_case(1)
    alpha, log_c = clone_forward(lay.tables, vals, 0.0)
    got = backward_counts(lay.tables, vals, alpha, log_c, np.zeros(vals.size),
                          np.zeros(lay.n_clones))
    fused = clone_backward_counts(lay.tables, vals, alpha, log_c, np.zeros(vals.size),
                                  np.zeros(lay.n_clones))
    assert bool(calls) == threaded
    np.testing.assert_array_equal(_bits(got[0]), _bits(fused[0]))


@pytest.mark.parametrize("fail_from", [1, 2])
def test_a_failing_message_job_raises_and_no_count_is_added_after_it(fail_from, n_threads,
                                                                     monkeypatch):
    """The messages fail at their first or second piece: the call raises their error (it does
    not wait for messages that never come: run on a thread given 60 s) and no count is added
    from a piece whose messages were not done (the first piece's may have been added before the
    failure; with one thread the messages run first, so none is)."""
    real, real_tally, tallied, outcome = backward._messages, backward._tally, [], []

    def broken(tables, vals_t, alpha, log_c, betas, hi, lo):
        if hi <= tables.sym.size - 7 * (fail_from - 1):
            raise FloatingPointError("messages")
        return real(tables, vals_t, alpha, log_c, betas, hi, lo)

    monkeypatch.setattr(backward, "_messages", broken)
    monkeypatch.setattr(backward, "_tally", lambda *a: tallied.append(a[-2:]) or real_tally(*a))
    lay, vals, _ = _random_case(2)
    alpha, log_c = clone_forward(lay.tables, vals, 0.0)

    def call():
        try:
            backward_counts_threaded(lay.tables, vals, alpha, log_c, np.zeros(vals.size),
                                     np.zeros(lay.n_clones), 7)
        except FloatingPointError as error:
            outcome.append(error)

    caller = threading.Thread(target=call, daemon=True)
    caller.start()
    caller.join(60)
    assert not caller.is_alive() and len(outcome) == 1 and "messages" in str(outcome[0])
    T = lay.sym.size
    assert set(tallied) <= ({(T, T - 7)} if fail_from == 2 else set())
    assert n_threads == 2 or tallied == []
