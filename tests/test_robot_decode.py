"""The robot decoder's Viterbi (:mod:`topomap.core.motion.robot_decode`) against its recursion
written out one (source, successor, turn) at a time in plain Python: the same floating-point
sums in the same order, so the paths, scores and sources must agree bit for bit -- ties
included (the first source in ``c B + h`` order among equal scores)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from topomap.core.motion.robot_decode import (PRUNE, _buffers, _into, _predecessors, _step,
                                              heading_kernel, viterbi)


def _plain_step(delta, move, cent, ptr, idx, sd, log_turn, jump):
    """``(new, arg)`` of one keyframe: every source ``(c, h)`` within ``PRUNE`` of the best,
    each successor ``c2`` weighted by ``exp(-d^2 / 2 sd^2)`` normalised by a log-sum-exp summed
    in order, each turn of the kernel; a target keeps the first strictly better score."""
    N, B = delta.shape
    W = (len(log_turn) - 1) // 2
    f, lft, s0 = float(move[0]), float(move[1]), int(move[2])
    best_all, arg_all = -1e300, 0
    for c in range(N):
        for h in range(B):
            if delta[c, h] > best_all:
                best_all, arg_all = delta[c, h], c * B + h
    new = [[best_all + jump] * B for _ in range(N)]
    arg = [[arg_all] * B for _ in range(N)]
    inv2 = 1.0 / (2 * sd * sd)
    for c in range(N):
        succ = [int(x) for x in idx[ptr[c]:ptr[c + 1]]]
        for h in range(B):
            v0 = float(delta[c, h])
            if v0 < best_all - PRUNE:
                continue
            cos_h, sin_h = math.cos(2 * math.pi * h / B), math.sin(2 * math.pi * h / B)
            px = float(cent[c, 0]) + cos_h * f - sin_h * lft
            py = float(cent[c, 1]) + sin_h * f + cos_h * lft
            lp = [-((float(cent[c2, 0]) - px) ** 2 + (float(cent[c2, 1]) - py) ** 2) * inv2
                  for c2 in succ]
            tot = -1e300
            for w in lp:
                tot = max(tot, w) + math.log1p(math.exp(-abs(tot - w)))
            for c2, w in zip(succ, lp):
                for j in range(2 * W + 1):
                    h2 = (h + s0 - W + j) % B
                    v = v0 + w - tot + float(log_turn[j])
                    if v > new[c2][h2]:
                        new[c2][h2], arg[c2][h2] = v, c * B + h
    return np.array(new), np.array(arg)


def _plain_viterbi(E, moves, cent, ptr, idx, sd, log_turn, log_init, jump):
    K, N, B = E.shape
    delta = log_init[:, None] + E[0].astype(np.float64)
    back = np.zeros((K, N, B), dtype=np.int64)
    for k in range(1, K):
        move = (moves[k, 0], moves[k, 1], math.floor(moves[k, 2] * B / (2 * math.pi) + 0.5))
        new, back[k] = _plain_step(delta, move, cent, ptr, idx, sd, log_turn, jump)
        delta = new + E[k].astype(np.float64)
        delta -= delta.max()
    cells, bins = np.zeros(K, dtype=np.int64), np.zeros(K, dtype=np.int64)
    cells[-1], bins[-1] = divmod(int(np.argmax(delta)), B)
    for k in range(K - 1, 0, -1):
        cells[k - 1], bins[k - 1] = divmod(int(back[k, cells[k], bins[k]]), B)
    return cells, bins


@st.composite
def _models(draw):
    """A tiny map and walk: cells on a coarse grid (equal distances, so equal weights) or
    anywhere, successor lists in any order (empty ones too), emissions from a few values (equal
    scores everywhere) with a pruned one, starting scores one unit in the last place apart,
    1-9 heading bins (fewer than the kernel's turns too), turns of any size, a Gaussian
    heading kernel or round numbers, a cheap or a dear jump."""
    N = draw(st.integers(1, 5))
    B = draw(st.integers(1, 9))
    K = draw(st.integers(1, 6))
    coord = st.sampled_from([0.0, 0.5, 1.0]) if draw(st.booleans()) else st.floats(0, 1)
    cent = np.array([[draw(coord), draw(coord)] for _ in range(N)])
    lists = [draw(st.permutations(sorted(draw(st.sets(st.integers(0, N - 1), max_size=N)))))
             for _ in range(N)]
    ptr = np.r_[0, np.cumsum([len(s) for s in lists])].astype(np.int64)
    idx = np.array([c2 for s in lists for c2 in s], dtype=np.int64)
    score = st.sampled_from([0.0, 0.0, -0.5, -1.0, -2.25, -400.0]) if draw(st.booleans()) \
        else st.floats(-6, 0, width=32)
    E = np.array(draw(st.lists(score, min_size=K * N * B, max_size=K * N * B)),
                 dtype=np.float32).reshape(K, N, B)
    step = st.sampled_from([0.0, 0.5]) | st.floats(-0.7, 0.7)
    moves = np.array([[draw(step), draw(step), draw(st.floats(-7, 7))] for _ in range(K)])
    sd = draw(st.sampled_from([0.1, 0.5, 1.0]))
    W = draw(st.integers(0, 3))
    log_turn = heading_kernel(draw(st.sampled_from([0.3, 0.5, 2.0])), W) if draw(st.booleans()) \
        else np.array(draw(st.lists(st.sampled_from([0.0, -0.5, -1.0]), min_size=2 * W + 1,
                                    max_size=2 * W + 1)))
    log_init = np.array([draw(st.sampled_from([0.0, -1.5, -np.nextafter(1.5, 0.0), -2.5]))
                         for _ in range(N)])
    jump = draw(st.sampled_from([math.log(1e-300), -4.0, -0.5]))
    return E, moves, cent, ptr, idx, sd, log_turn, log_init, jump


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(_models())
def test_the_paths_are_the_plain_recursion_s(model):
    got, want = viterbi(*model), _plain_viterbi(*model)
    assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


def _one_step(delta, model):
    """``(new, arg)`` of :func:`_step` from ``delta`` with the model's second move."""
    E, moves, cent, ptr, idx, sd, log_turn, log_init, jump = model
    N, B = delta.shape
    move = np.array([moves[1, 0], moves[1, 1], math.floor(moves[1, 2] * B / (2 * math.pi) + 0.5)])
    graph = (cent, ptr, idx) + _predecessors(ptr, idx, N)
    work = _buffers(N, B, int(np.max(np.diff(ptr))), log_turn.size)
    new, arg = np.empty((N, B)), np.empty((N, B), dtype=np.int32)
    _step(delta, move, graph, (sd, log_turn, jump), (new, arg), work)
    return move, graph, work, new, arg


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(_models().filter(lambda m: len(m[0]) > 1 and m[3][-1] > 0))
def test_every_state_s_score_and_source_are_the_plain_step_s(model):
    """Not only the path: each state's best score (bit for bit) and the source it came from;
    the source-by-source settling of a state gives the same."""
    E, moves, cent, ptr, idx, sd, log_turn, log_init, jump = model
    delta = log_init[:, None] + E[0].astype(np.float64)
    move, graph, work, new, arg = _one_step(delta, model)
    want_new, want_arg = _plain_step(delta, move, cent, ptr, idx, sd, log_turn, jump)
    assert new.tolist() == want_new.tolist() and arg.tolist() == want_arg.tolist()
    best_all = delta.max()
    for c2 in range(delta.shape[0]):
        for h2 in range(delta.shape[1]):
            score, src = _into(delta, move, c2, h2, best_all, graph, (sd, log_turn, jump), work)
            assert score == want_new[c2, h2]
            assert src == (want_arg[c2, h2] if score > best_all + jump else -1)


def test_a_source_that_rounds_to_the_best_score_wins_by_its_order():
    """Cells 0 and 1 (0.5 m either side of cell 2, their one successor; weights exactly -0.5,
    normalised to 0) score -1.5 and -1.5 + 2^-52 into cell 2: cell 1 is better by one unit in
    the last place, but with the kernel's turn (-1) added both round to -2.5 (where the spacing
    is 2^-51, the tie to even), so one source at a time the first, cell 0, keeps the state."""
    x = 1.5
    assert -np.nextafter(x, 0.0) - 1.0 == -x - 1.0  # the two sums round together
    cent = np.array([[-0.5, 0.0], [0.5, 0.0], [0.0, 0.0]])
    ptr, idx = np.array([0, 1, 2, 2]), np.array([2, 2])
    delta = np.array([[-x], [-np.nextafter(x, 0.0)], [-50.0]])
    log_turn, jump = np.array([-1.0]), math.log(1e-300)
    model = (np.zeros((2, 3, 1), np.float32), np.zeros((2, 3)), cent, ptr, idx, 0.5, log_turn,
             np.zeros(3), jump)
    _, _, _, new, arg = _one_step(delta, model)
    want_new, want_arg = _plain_step(delta, (0.0, 0.0, 0), cent, ptr, idx, 0.5, log_turn, jump)
    assert want_new[2, 0] == -2.5 and want_arg[2, 0] == 0
    assert new[2, 0] == -2.5 and arg[2, 0] == 0
