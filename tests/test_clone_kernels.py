"""The clone-model kernels against brute-force enumeration of every clone path on tiny models."""

import itertools

import numpy as np
import pytest

from topomap.core.refine import backward
from topomap.core.refine.backward import clone_backward_counts as backward_counts
from topomap.core.refine.clones import EStepWork, _e_step, make_layout, m_step
from topomap.core.refine.kernels import clone_forward as forward
from topomap.core.refine.kernels import clone_normalize_blocks as normalize_blocks
from topomap.core.refine.kernels import clone_normalize_into as normalize_into
from topomap.core.refine.kernels import clone_path_counts as path_counts
from topomap.core.refine.kernels import clone_step_offsets as step_offsets
from topomap.core.refine.kernels import clone_viterbi as viterbi


def tiny_case(seed, lengths=(4, 3), clones=(2, 3, 1), n_actions=2):
    """A random sequence over 3 symbols and a random block model for it."""
    rng = np.random.default_rng(seed)
    T = sum(lengths)
    sym = rng.integers(0, len(clones), T)
    u = rng.integers(0, n_actions, T)
    lay = make_layout(sym, u, np.array(lengths), np.array(clones), n_actions)
    vals = rng.random(int(lay.boff[-1])) + 0.05
    return lay, vals


def block_entry(lay, vals, t, i, j):
    """The factor of moving from global clone i at step t to global clone j at step t + 1."""
    s, s2 = lay.sym[t], lay.sym[t + 1]
    nn = lay.start[s2 + 1] - lay.start[s2]
    return vals[lay.boff[lay.blk[t]] + (i - lay.start[s]) * nn + (j - lay.start[s2])]


def enumerate_paths(lay, vals):
    """Yield (path, probability) for every clone path consistent with the symbols."""
    choices = [range(lay.start[s], lay.start[s + 1]) for s in lay.sym]
    for path in itertools.product(*choices):
        p = 1.0
        for t in range(lay.sym.size):
            if t == 0 or lay.blk[t - 1] < 0:
                p /= lay.start[lay.sym[t] + 1] - lay.start[lay.sym[t]]
            else:
                p *= block_entry(lay, vals, t - 1, path[t - 1], path[t])
        yield np.array(path), p


def brute_force(lay, vals):
    """Likelihood, expected counts (block layout), occupancy and the best path by enumeration."""
    total, best, best_p = 0.0, None, -1.0
    counts = np.zeros(vals.size)
    occ = np.zeros(lay.n_clones)
    for path, p in enumerate_paths(lay, vals):
        total += p
        if p > best_p:
            best, best_p = path, p
        path_counts(path, lay.tables, counts_p := np.zeros(vals.size))
        counts += p * counts_p
        np.add.at(occ, path, p)
    return total, counts / total, occ / total, best, best_p


def assert_forward_backward_match(lay, vals, total, counts, occ):
    """The compiled forward pass gives the enumerated likelihood, and the backward pass the
    enumerated expected transition counts and clone occupancies."""
    alpha, log_c = forward(lay.tables, vals, 0.0)
    assert log_c.sum() == pytest.approx(np.log(total), rel=1e-10)
    got, got_occ = np.zeros(vals.size), np.zeros(lay.n_clones)
    backward_counts(lay.tables, vals, alpha, log_c, got, got_occ)
    np.testing.assert_allclose(got, counts, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(got_occ, occ, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("seed", range(6))
def test_forward_backward_match_enumeration(seed):
    lay, vals = tiny_case(seed)
    total, counts, occ, _, _ = brute_force(lay, vals)
    assert_forward_backward_match(lay, vals, total, counts, occ)


@pytest.mark.parametrize("seed", range(6))
def test_viterbi_matches_enumeration(seed):
    lay, vals = tiny_case(seed)
    _, _, _, best, best_p = brute_force(lay, vals)
    path, log_p = viterbi(lay.tables, np.log(vals))
    assert log_p == pytest.approx(np.log(best_p), rel=1e-10)
    np.testing.assert_array_equal(path, best)


def test_viterbi_ties_go_to_the_lowest_clones():
    """A model under which every path is as probable as every other: the path takes the first
    clone of every step's symbol, and its log-probability is each episode's uniform start."""
    lay, vals = tiny_case(0, lengths=(5, 4), clones=(2, 3, 4))
    path, log_p = viterbi(lay.tables, np.zeros(vals.size))
    np.testing.assert_array_equal(path, lay.start[lay.sym])
    clones = np.diff(lay.start)
    assert log_p == pytest.approx(-np.log(clones[lay.sym[0]]) - np.log(clones[lay.sym[5]]))


@pytest.mark.parametrize("seed", range(4))
def test_zero_transitions_are_skipped_exactly(seed):
    """Exact zeros in the model give zero forward messages; skipping them changes nothing."""
    lay, vals = tiny_case(seed, lengths=(7,), clones=(3, 3, 2))
    vals[np.random.default_rng(seed).random(vals.size) < 0.4] = 0.0
    total, counts, occ, _, _ = brute_force(lay, vals)
    if total == 0.0:
        pytest.skip("this random sparsity pattern makes the sequence impossible")
    assert_forward_backward_match(lay, vals, total, counts, occ)


def deterministic_walk(T, clones, n_actions, seed):
    """A walk through a random deterministic clone graph; returns its symbols, actions, path."""
    rng = np.random.default_rng(seed)
    symbol = np.repeat(np.arange(len(clones)), clones)
    nxt = rng.integers(0, symbol.size, (symbol.size, n_actions))
    path, u = np.empty(T, dtype=np.int64), rng.integers(0, n_actions, T)
    path[0] = 0
    for t in range(1, T):
        path[t] = nxt[path[t - 1], u[t - 1]]
    return symbol[path], u, path


def test_pruning_approximates_exact_statistics():
    """On data a peaked model explains, dropping filtered probabilities below 1e-6 skips most
    clones and leaves likelihood and counts as they were."""
    T = 3000
    sym, u, path = deterministic_walk(T, [4, 4, 4], 2, seed=1)
    lay = make_layout(sym, u, np.array([T]), np.array([4, 4, 4]), 2)
    counts = path_counts(path, lay.tables, np.zeros(int(lay.boff[-1])))
    vals = m_step(lay, counts, 1e-9, joint=False)
    stats = []
    for prune in (0.0, 1e-6):
        alpha, log_c = forward(lay.tables, vals, prune)
        got, occ = np.zeros(vals.size), np.zeros(lay.n_clones)
        backward_counts(lay.tables, vals, alpha, log_c, got, occ)
        stats.append((log_c.sum(), got, occ, (alpha == 0).mean()))
    (ll0, c0, o0, _), (ll1, c1, o1, zero_share) = stats
    assert zero_share > 0.5
    assert ll1 == pytest.approx(ll0, abs=1e-3)
    np.testing.assert_allclose(c1, c0, atol=1e-3)
    np.testing.assert_allclose(o1, o0, atol=1e-3)


def test_single_episode_and_single_clone_symbols():
    lay, vals = tiny_case(7, lengths=(6,), clones=(1, 2, 2))
    total, counts, _, best, _ = brute_force(lay, vals)
    alpha, log_c = forward(lay.tables, vals, 0.0)
    assert log_c.sum() == pytest.approx(np.log(total), rel=1e-10)
    path, _ = viterbi(lay.tables, np.log(vals))
    np.testing.assert_array_equal(path, best)


def test_no_transition_crosses_an_episode_start():
    lay, _ = tiny_case(1, lengths=(2, 2, 3))
    assert (lay.blk[[1, 3, 6]] == -1).all() and (lay.blk[[0, 2, 4, 5]] >= 0).all()


def test_long_sequence_does_not_underflow():
    rng = np.random.default_rng(0)
    T = 100_000
    sym, u = rng.integers(0, 3, T), rng.integers(0, 2, T)
    lay = make_layout(sym, u, np.array([T]), np.array([4, 4, 4]), 2)
    vals = m_step(lay, rng.random(int(lay.boff[-1])), 1e-3, joint=False)
    alpha, log_c = forward(lay.tables, vals, 0.0)
    assert np.isfinite(log_c.sum()) and log_c.sum() < -1e4
    path, log_p = viterbi(lay.tables, np.log(vals))
    assert np.isfinite(log_p) and log_p <= log_c.sum()


def dense_counts(lay, counts):
    """The dense (A, S, S) table a count array in the block layout stands for."""
    A, S = lay.n_actions, lay.n_clones
    C = np.zeros((A, S, S))
    for b, (a, s, s2) in enumerate(lay.triples):
        block = counts[lay.boff[b]:lay.boff[b + 1]].reshape(lay.start[s + 1] - lay.start[s], -1)
        C[a, lay.start[s]:lay.start[s + 1], lay.start[s2]:lay.start[s2 + 1]] = block
    return C


def dense_transitions(lay, counts, pseudocount, joint):
    """The dense (A, S, S) model a count array stands for, normalised by brute force."""
    C = dense_counts(lay, counts) + pseudocount
    if joint:
        return C / C.sum(axis=(0, 2), keepdims=True)
    return C / C.sum(axis=2, keepdims=True)


@pytest.mark.parametrize("joint", [False, True])
def test_normalize_matches_dense_model(joint):
    lay, counts = tiny_case(3)
    vals = m_step(lay, counts, 0.01, joint)
    P = dense_transitions(lay, counts, 0.01, joint)
    for b, (a, s, s2) in enumerate(lay.triples):
        expect = P[a, lay.start[s]:lay.start[s + 1], lay.start[s2]:lay.start[s2 + 1]]
        np.testing.assert_allclose(vals[lay.boff[b]:lay.boff[b + 1]], expect.ravel(), rtol=1e-12)


def test_normalize_zero_rows_stay_zero():
    lay, counts = tiny_case(4)
    counts[:] = 0.0
    vals, Z = normalize_blocks(lay.tables, counts, lay.triples[:, 1].copy(),
                               lay.triples[:, 2].copy(), lay.triples[:, 0].copy(), lay.n_actions,
                               0.0, 0.0)
    assert (vals == 0).all() and (Z == 0).all()
    out = np.full(counts.size, np.nan)  # an M-step into kept arrays writes every entry
    normalize_into(lay.tables, counts, lay.triples[:, 1].copy(), lay.triples[:, 2].copy(),
                   lay.triples[:, 0].copy(), lay.n_actions, 0.0, 0.0, out)
    assert (out == 0).all()


@pytest.mark.parametrize("seed", range(3))
def test_path_counts_match_a_dense_count(seed):
    """A hard path's transitions, counted in the block layout, are its dense (u, x, x') counts;
    none crosses an episode start."""
    lengths = (4, 3, 5)
    lay, vals = tiny_case(seed, lengths=lengths)
    rng = np.random.default_rng(seed)
    path = np.array([rng.integers(lay.start[s], lay.start[s + 1]) for s in lay.sym])
    ends = set(np.cumsum(lengths) - 1)
    expect = np.zeros((lay.n_actions, lay.n_clones, lay.n_clones))
    for t in range(lay.sym.size - 1):
        if t not in ends:
            expect[lay.u[t], path[t], path[t + 1]] += 1
    got = path_counts(path, lay.tables, np.zeros(vals.size))
    np.testing.assert_array_equal(dense_counts(lay, got), expect)


def test_step_offsets_give_every_step_the_clones_of_its_symbol():
    lay, _ = tiny_case(2, clones=(2, 3, 1))
    sizes = [lay.start[s + 1] - lay.start[s] for s in lay.sym]
    np.testing.assert_array_equal(lay.pos, np.concatenate([[0], np.cumsum(sizes)]))
    np.testing.assert_array_equal(step_offsets(lay.sym, lay.start), lay.pos)


@pytest.mark.parametrize("prune", [0.0, 0.2])
def test_column_pass_gives_the_row_pass_bits(prune):
    """Where the blocks are small next to the steps' work the backward pass runs on column-major
    copies; its counts and occupancies (added to nonzero starting values) are the row pass's bit
    for bit, also with pruned clones and several episodes."""
    rng = np.random.default_rng(3)
    T, clones = 4000, np.array([5, 3, 6])
    sym, u = rng.integers(0, 3, T), rng.integers(0, 2, T)
    lay = make_layout(sym, u, np.array([1500, 1, 2499]), clones, 2)
    steps = np.flatnonzero(lay.blk >= 0)
    work = (clones[sym[steps]] * clones[sym[steps + 1]]).sum()
    assert work >= backward.COLUMN_PASS_WORK * lay.boff[-1]  # the column pass is the one taken
    vals = m_step(lay, rng.random(int(lay.boff[-1])) ** 4, 1e-3, joint=False)
    alpha, log_c = forward(lay.tables, vals, prune)
    assert prune == 0.0 or (alpha == 0).any()
    start_counts, start_occ = rng.random(vals.size), rng.random(lay.n_clones)
    rows = (start_counts.copy(), start_occ.copy())
    backward._backward_rows(lay.tables, vals, alpha, log_c, *rows)
    cols = (start_counts.copy(), start_occ.copy())
    backward_counts(lay.tables, vals, alpha, log_c, *cols)
    np.testing.assert_array_equal(cols[0], rows[0])
    np.testing.assert_array_equal(cols[1], rows[1])
    assert not np.array_equal(rows[0], start_counts)


def forward_row_by_row(lay, vals, prune):
    """The forward pass written out: each step's message sums the rows of the non-zero messages
    before it one by one, in order, then is scaled to sum 1 (summed in order) and pruned."""
    sym, blk, start, boff, pos = lay.tables
    alpha, log_c = np.empty(pos[-1]), np.empty(sym.size)
    for t in range(sym.size):
        a0, n = pos[t], pos[t + 1] - pos[t]
        if t == 0 or blk[t - 1] < 0:
            alpha[a0:a0 + n], log_c[t] = 1.0 / n, 0.0
            continue
        p0, o = pos[t - 1], boff[blk[t - 1]]
        acc = np.zeros(n)
        for i in range(a0 - p0):
            if alpha[p0 + i] != 0.0:
                acc = acc + alpha[p0 + i] * vals[o + i * n:o + (i + 1) * n]
        c = 0.0
        for x in acc:
            c += x
        scaled = acc / c
        alpha[a0:a0 + n] = np.where(scaled >= prune, scaled, 0.0)
        log_c[t] = np.log(c)
    return alpha, log_c


@pytest.mark.parametrize("prune", [0.0, 0.02])
def test_forward_pass_sums_the_rows_in_order(prune):
    """The forward pass (rows of non-zero messages added two at a time) gives the messages of
    the pass written out row by row, bit for bit, with pruned clones leaving odd and even
    numbers of rows a step, and the same log scaling factors."""
    rng = np.random.default_rng(5)
    T, clones = 3000, np.array([7, 4, 6])
    sym, u = rng.integers(0, 3, T), rng.integers(0, 2, T)
    lay = make_layout(sym, u, np.array([1000, 2000]), clones, 2)
    vals = m_step(lay, rng.random(int(lay.boff[-1])) ** 6, 1e-3, joint=False)
    alpha, log_c = forward(lay.tables, vals, prune)
    want, want_log_c = forward_row_by_row(lay, vals, prune)
    np.testing.assert_array_equal(alpha, want)
    np.testing.assert_allclose(log_c, want_log_c, rtol=1e-15, atol=0)
    rows = np.add.reduceat(alpha != 0, lay.pos[:-1])  # non-zero messages a step
    assert prune == 0.0 or (np.any(rows % 2 == 1) and np.any(rows % 2 == 0) and (rows < clones[
        lay.sym]).any())


@pytest.mark.parametrize("T, column", [(4000, True), (40, False)])
def test_e_steps_on_kept_arrays_give_the_bits_of_new_ones(T, column):
    """E-steps written into one :class:`EStepWork` (arrays holding garbage, then the last
    E-step's results) give the bits of the passes on new zeroed arrays, three E-steps in a row,
    in the column pass and in the row pass."""
    rng = np.random.default_rng(5)
    clones = np.array([5, 3, 6])
    sym, u = rng.integers(0, 3, T), rng.integers(0, 2, T)
    lay = make_layout(sym, u, np.array([T // 2, T - T // 2]), clones, 2)
    steps = np.flatnonzero(lay.blk >= 0)
    work_done = (clones[sym[steps]] * clones[sym[steps + 1]]).sum()
    assert (work_done >= backward.COLUMN_PASS_WORK * lay.boff[-1]) == column
    work = EStepWork.of(lay)
    for array in vars(work).values():
        array[:] = np.nan
    counts = new_counts = rng.random(int(lay.boff[-1])) ** 4
    for _ in range(3):
        vals = m_step(lay, counts, 1e-3, joint=False)
        alpha, log_c = forward(lay.tables, vals, 1e-3)
        expect, expect_occ = np.zeros(vals.size), np.zeros(lay.n_clones)
        backward_counts(lay.tables, vals, alpha, log_c, expect, expect_occ)
        new_counts, occ, ll, got_alpha = _e_step(
            lay, m_step(lay, new_counts, 1e-3, False, work.vals), 1e-3, work)
        for got, want in [(work.vals, vals), (got_alpha, alpha), (new_counts, expect),
                          (occ, expect_occ)]:
            np.testing.assert_array_equal(got, want)
        assert ll == log_c.sum() and new_counts is work.counts
        counts = expect


def test_the_decoded_path_is_every_steps_most_probable_clone_and_settles_when_it_stops_moving():
    """Three steps of two clones each; the path has settled once it changed on fewer than the
    share of steps at SETTLE_ITER (3) E-steps in a row."""
    from topomap.core.refine.clones import SETTLE_ITER, SettledPath, step_argmax

    pos = np.array([0, 2, 4, 6])
    a = np.array([0.9, 0.1, 0.2, 0.8, 0.5, 0.5])  # ties go to the first clone
    b = np.array([0.1, 0.9, 0.2, 0.8, 0.5, 0.5])  # step 0 moved
    assert step_argmax(a, pos).tolist() == [0, 1, 0]
    path = SettledPath(pos, share=0.5)  # settled: fewer than 1.5 of the 3 steps changed
    for alpha, changed, settled in [(a, [], False), (b, [1], False), (b, [1, 0], False),
                                    (b, [1, 0, 0], True), (a, [1, 0, 0, 1], True)]:
        path.report(alpha)
        assert path.changed == changed and path.settled is settled
    assert SETTLE_ITER == 3
    strict = SettledPath(pos, share=1 / 3)  # 1 change of 3 steps is not fewer than 1
    for alpha in (a, b, a, b):
        strict.report(alpha)
    assert not strict.settled


def test_a_settled_path_stops_baum_welch_after_its_first_judged_iteration():
    """With ``settle=1`` an E-step is calm unless the path changed on all 200 steps at once, so
    EM stops at the first iteration it judges, ``min_iter`` + 1; without it, at ``max_iter``
    (``tol=-inf``: the gain never stops it)."""
    from topomap.core.refine.clones import baum_welch

    lay, _ = tiny_case(0, lengths=(200,), clones=(3, 2, 2))
    init = np.random.default_rng(1).random(int(lay.boff[-1]))
    for settle, iters in [(0.0, 30), (1.0, 6)]:
        *_, history = baum_welch(lay, init, 1e-3, False, max_iter=30, tol=-np.inf, min_iter=5,
                                 settle=settle)
        assert len(history) == iters
