"""The split's passes cut into pieces on threads give what one pass over everything gives: on
hand cases, and on random walks with many episodes whose runs of steps cross the pieces'
bounds (pieces of 1, 2, 3 and 7 steps, one to three threads)."""

import numpy as np
import pytest

from topomap.core.split import threads
from topomap.core.split.engine import members_of
from topomap.core.split.kernels import (_tally, centre_pairs, follow_keys, instance_table,
                                        tally_pairs, touched_codes)
from topomap.core.stats import episode_masks

WHOLE = 1 << 40  # one piece: the pass over everything


@pytest.fixture(params=[1, 2, 3])
def n_threads(request, monkeypatch):
    monkeypatch.setattr(threads, "n_threads", lambda: request.param)
    monkeypatch.setattr(threads, "THREAD_STEPS", 0)  # threads however few the steps
    return request.param


def _walk(seed, T=400, S=5, A=3):
    """Random labels and actions, episodes of 1 to 30 steps, and the steps of state 0 that
    follow a key, in runs (consecutive steps) so that pieces end inside them."""
    rng = np.random.default_rng(seed)
    x, u = rng.integers(0, S, T), rng.integers(0, A, T)
    x[100:160] = 0  # a long run of state 0
    lengths = []
    while sum(lengths) < T:
        lengths.append(int(min(rng.integers(1, 31), T - sum(lengths))))
    has_prev, has_next = episode_masks(T, lengths)
    return x, u, S, A, has_prev, has_next


def test_in_threads_keeps_the_call_order(n_threads):
    assert threads.in_threads(lambda i: i * i, range(50)) == [i * i for i in range(50)]
    assert threads.in_threads(len, []) == []


def test_in_threads_keeps_few_steps_on_the_calling_thread(n_threads, monkeypatch):
    import threading

    monkeypatch.setattr(threads, "THREAD_STEPS", 100)
    caller = threading.get_ident()
    ran_on = threads.in_threads(lambda _: threading.get_ident(), range(4), steps=99)
    assert ran_on == [caller] * 4
    ran_on = threads.in_threads(lambda _: threading.get_ident(), range(4), steps=100)
    assert (caller in ran_on) == (n_threads == 1)


def test_pieces_cover_the_range_in_order():
    assert threads.pieces(7, 3) == [slice(0, 3), slice(3, 6), slice(6, 7)]
    assert threads.pieces(6, 3) == [slice(0, 3), slice(3, 6)] and threads.pieces(0, 3) == []


def test_follow_keys_in_pieces_by_hand(n_threads):
    # one episode 0..3, one of 4..5: steps 0 and 4 start episodes; A = 2, key of step t is
    # x[t-1] * 2 + u[t-1]
    x, u = np.array([0, 1, 0, 1, 1, 0]), np.array([1, 0, 1, 1, 0, 0])
    has_prev, has_next = episode_masks(6, [4, 2])
    chosen = np.zeros(4, dtype=bool)
    chosen[1] = True  # the key (state 0, action 1): the steps after steps 0 and 2
    steps = np.arange(6)
    for chunk in (1, 2, 4, WHOLE):
        goes, starts = follow_keys(x, u, steps, has_prev, has_next, 2, chosen, chunk)
        assert goes.tolist() == [False, True, False, True, False, False]
        assert starts.tolist() == [0, 4]  # positions in ``steps``


@pytest.mark.parametrize("seed", range(4))
def test_follow_keys_in_pieces_equals_one_pass(seed, n_threads):
    x, u, S, A, has_prev, has_next = _walk(seed)
    steps = np.flatnonzero(x == 0).astype(np.int32)
    chosen = np.random.default_rng(seed).random(S * A) < 0.5
    whole = follow_keys(x, u, steps, has_prev, has_next, A, chosen, WHOLE)
    assert whole[1].size > 1  # several first steps of episodes
    for chunk in (1, 2, 3, 7):
        goes, starts = follow_keys(x, u, steps, has_prev, has_next, A, chosen, chunk)
        assert np.array_equal(goes, whole[0]) and np.array_equal(starts, whole[1])


def test_touched_codes_in_pieces_by_hand(n_threads):
    # the first case of test_count_kernels: state 1 split, steps 2 and 3 moved to state 3;
    # pieces of one step each cut between every neighbour
    x, u, A = np.array([0, 1, 3, 3, 2]), np.array([1, 0, 1, 0, 1]), 2
    has_prev, has_next = np.arange(5) > 0, np.arange(5) < 4
    out, ins, starts, near = touched_codes(np.array([2, 3]), has_prev, has_next, has_prev & has_next,
                                           x, u, A, np.int64(32), 1, 3, chunk=1)
    assert out.shape == (4, 0)
    assert ins.tolist() == [[(1 << 32) | 2, (2 << 32) | 3, (3 << 32) | 4],
                            [(1 << 32) | 6, (2 << 32) | 7, (7 << 32) | 4], [0, 1, 1]]
    assert starts.tolist() == [[(2 << 32) | 1, (3 << 32) | 1, (2 << 32) | 2],
                               [(2 << 32) | 3, (7 << 32) | 3, (6 << 32) | 2]]
    assert near.tolist() == [False, True, True, True]


@pytest.mark.parametrize("seed", range(4))
def test_touched_codes_in_pieces_equals_one_pass(seed, n_threads):
    x, u, S, A, has_prev, has_next = _walk(seed)
    rng = np.random.default_rng(seed)
    steps = np.flatnonzero(x == 0)
    moved = np.sort(np.concatenate([steps[(steps >= 100) & (steps < 130)],  # a run
                                    rng.choice(steps, 15, replace=False)]))
    moved = np.unique(moved).astype(np.int32)
    x = x.copy()
    x[moved] = S  # the new state
    args = (moved, has_prev, has_next, has_prev & has_next, x, u, A, np.int64(32), 0, S)
    whole = touched_codes(*args, chunk=WHOLE)
    assert whole[0].shape[1] > 0 and whole[1].shape[1] > 0 and whole[2].shape[1] > 0
    for chunk in (1, 2, 3, 7):
        for a, b in zip(touched_codes(*args, chunk=chunk), whole):
            assert np.array_equal(a, b)


def test_tally_counts_codes_like_numpy():
    rng = np.random.default_rng(0)
    for n, size in ((0, 5), (3, 1000), (50, 6), (2000, 40), (2000, 3000)):
        keys, cols = rng.integers(0, size, n), rng.integers(0, size, n)
        codes = (keys << 32) | cols
        want = np.unique(codes, return_counts=True)
        got = _tally(codes, size)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


@pytest.mark.parametrize("seed", range(3))
def test_centre_pairs_give_every_states_instance_table(seed):
    x, u, S, A, has_prev, has_next = _walk(seed)
    centre = has_prev & has_next
    size = (S + 1) * A
    bits = size.bit_length()
    for dtype in (np.int32, np.int64):
        pairs = np.empty(int(centre.sum()), dtype=dtype)
        bounds = centre_pairs(x, u, centre, S, A, bits, pairs)
        for s, steps in enumerate(members_of(x, S, np.empty(0, dtype=np.int32))):
            want = instance_table(x, u, steps, centre, A, size)
            got = tally_pairs(pairs[bounds[s]:bounds[s + 1]], bits, size)
            assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def test_centre_pairs_by_hand():
    # A = 2 (size 6, 3 bits); centres t = 1, 2, 4 in states 1, 0, 0 (as in test_count_kernels)
    x, u = np.array([0, 1, 0, 1, 0, 1]), np.array([1, 0, 1, 0, 1, 1])
    centre = np.array([False, True, True, False, True, False])
    pairs = np.empty(3, dtype=np.int64)
    bounds = centre_pairs(x, u, centre, 2, 2, 3, pairs)
    # state 0: t = 2 (key 2, column 3) and t = 4 (key 2, column 3); state 1: t = 1 (key 1, 0)
    assert bounds.tolist() == [0, 2, 3] and pairs.tolist() == [2 << 3 | 3, 2 << 3 | 3, 1 << 3]


def test_concurrent_proposals_split_as_proposals_in_turn(n_threads):
    # a criterion marked ``concurrent`` proposes the dirty states' splits on threads: the
    # proposals, scores and labels are those of proposals made one after the other
    import threading

    from topomap.core.split.criteria import EntropyCriterion
    from topomap.core.split.engine import Splitter

    class InTurn(EntropyCriterion):
        concurrent = False

    class Seen(EntropyCriterion):
        threads: set = set()

        def propose(self, counts):
            self.threads.add(threading.get_ident())
            return super().propose(counts)

    rng = np.random.default_rng(5)
    S, A, T = 6, 3, 3000
    succ = rng.integers(0, 2 * S, (2 * S, A))
    u, p, x = rng.integers(0, A, T), 0, np.empty(T, dtype=np.int64)
    for t in range(T):
        x[t], p = p % S, succ[p, u[t]]  # 12 places seen as 6: aliased states to split
    masks = episode_masks(T, [T])
    runs = []
    for criterion in (InTurn(), Seen()):
        s = Splitter(x, u, A, *masks, symbol=list(range(S)), gds=[-1] * S,
                     obs_entropy=np.zeros(S), criterion=criterion)
        history = []
        while (best := s.best()) is not None and s.n_states < 12:
            history.append((best.state, best.score))
            s.apply(best)
        runs.append((history, s.labels.copy()))
    assert len(runs[0][0]) == 6 and runs[0][0] == runs[1][0]
    assert np.array_equal(runs[0][1], runs[1][1])
    assert (threading.get_ident() in Seen.threads) == (n_threads == 1)


def test_rows_in_threads_gives_one_call_s_rows_in_order(n_threads):
    """Rows cut into a piece a thread and joined again: each row's result where one call over
    every row puts it, with the shared arguments handed to every piece (7 rows over 1-3
    threads: pieces of 7, 4 + 3 and 3 + 2 + 2 rows)."""
    def fn(scale, offset, a, b):  # each row apart: a row of each result per row
        return a * scale + offset, a.sum(axis=1) - b

    a, b = np.arange(21.0).reshape(7, 3), np.arange(7.0)
    got = threads.rows_in_threads(fn, (2.0, 1.0), a, b)
    want = (2 * a + 1, np.array([3 + 0, 12 - 1, 21 - 2, 30 - 3, 39 - 4, 48 - 5, 57 - 6.0]))
    assert len(got) == 2
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
