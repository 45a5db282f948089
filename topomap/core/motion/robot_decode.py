"""The robot route's decoder: a Viterbi over (cell, heading bin) whose moves carry the walk's own
odometric displacement (:mod:`topomap.core.motion.robot`).

States are the map's ``N`` cells (centres ``cent`` (N, 2) [m], mean scans in the map frame) times
``B`` heading bins (one per beam, ``2 pi / B`` rad each).  A keyframe's move ``(forward, left,
turn)`` in the frame of the keyframe before takes cell ``c`` at heading bin ``h`` to
``cent[c] + R(2 pi h / B) (forward, left)``; each successor ``c'`` of ``c`` (cells walked from
``c`` to ``c'`` between two keyframes of the training walk, the cells near ``c`` and ``c``
itself: :func:`~topomap.core.motion.robot.successors`) is weighted by
``exp(-d^2 / 2 sd^2)`` of its distance ``d`` from there, normalised over the successors; the
heading bin turns by the move's turn rounded to bins, spread by the kernel ``log_turn`` over
``+-W`` bins.  The emission (:func:`emission`) is a Gaussian of the scan against the cell's mean
scan turned to ``h``.  A jump anywhere costs ``jump`` (log); paths 200 nats below the best are
not extended (they cannot win within one keyframe: an emission differs by at most tens of nats).

The recursion takes the best over a target's sources before the heading kernel and sums the
normalisers of a cell's headings side by side (:func:`_step`): the same floating-point sums as
one source, successor and turn at a time, ties going to the first source, so the same paths to
the bit -- measured on ``robot_alike@0.3333`` seed 0 (1,499 keyframes, 256 cells, 60 bins),
3.1x less CPU than one at a time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..split.threads import in_threads

__all__ = ["emission", "viterbi", "heading_kernel", "PRUNE"]

#: nats: a (cell, heading) more than this below the best is not extended
PRUNE = 200.0
#: keyframes whose emissions are computed at once, a block to a thread (memory: block x cells x
#: bins float32; the same numbers whatever the threads)
_BLOCK = 500


def heading_kernel(sd_bins: float, half_width: int = 3) -> np.ndarray:
    """(2 half_width + 1,) log-probabilities of a heading turning by ``-half_width ...
    half_width`` bins more than the move says: a Gaussian of sd ``sd_bins`` bins, normalised."""
    k = np.arange(-half_width, half_width + 1)
    log_k = -0.5 * (k / sd_bins) ** 2
    return log_k - np.log(np.exp(log_k).sum())


def emission(X, M, var: float) -> np.ndarray:
    """(T, N, B) ``log N(x_t; M_c turned to heading bin h, var I)`` up to a constant: scans ``X``
    (T, B) in the robot's frame against mean scans ``M`` (N, B) in the map frame, every rotation
    at once by the FFT (``sum_j X[t, j] M[c, j + h]``)."""
    X, M = np.asarray(X, dtype=np.float64), np.asarray(M, dtype=np.float64)
    T, B = X.shape
    FX, FM = np.fft.rfft(X, axis=1), np.fft.rfft(M, axis=1)
    x2, m2 = (X ** 2).sum(1), (M ** 2).sum(1)
    out = np.empty((T, len(M), B), dtype=np.float32)

    def block(a):  # numpy's FFT and arithmetic release the GIL: blocks run on threads
        b = min(T, a + _BLOCK)
        corr = np.fft.irfft(np.conj(FX[a:b, None, :]) * FM[None], n=B, axis=2)
        out[a:b] = -0.5 * (x2[a:b, None, None] + m2[None, :, None] - 2 * corr) / var

    in_threads(block, range(0, T, _BLOCK))
    return out


@njit(cache=True)
def _best(delta):
    best, arg = -1e300, 0
    N, B = delta.shape
    for c in range(N):
        for h in range(B):
            if delta[c, h] > best:
                best, arg = delta[c, h], c * B + h
    return best, arg


@njit(cache=True)
def _weights(c, px, py, graph, inv2, lp):
    """Each successor of cell ``c``: its log weight into ``lp`` (``-d^2 / 2 sd^2``, ``d`` [m]
    from the move's end ``(px, py)``); returns the log of their sum, summed in order."""
    cent, nb_ptr, nb_idx = graph[0], graph[1], graph[2]
    lo, hi = nb_ptr[c], nb_ptr[c + 1]
    tot = -1e300
    for q in range(lo, hi):
        c2 = nb_idx[q]
        lp[q - lo] = -((cent[c2, 0] - px) ** 2 + (cent[c2, 1] - py) ** 2) * inv2
        tot = max(tot, lp[q - lo]) + np.log1p(np.exp(-abs(tot - lp[q - lo])))
    return tot


@njit(cache=True)
def _into(delta, move, c2, h2, best_all, graph, kernel, work):
    """``(score, source)`` of the best move into state ``(c2, h2)``, every source and kernel
    turn tried one by one (``source`` -1 where none beats ``best_all + jump``; among equal
    scores the smallest source ``c B + h``): the few states :func:`_step` cannot settle from
    its per-heading maxima."""
    cent, nb_ptr, nb_idx, pred_ptr, pred_idx = graph
    sd, log_turn, jump = kernel
    cos_h, sin_h, lp = work[0], work[1], work[2]
    f, lft, s0 = move[0], move[1], int(move[2])
    B = delta.shape[1]
    W = (log_turn.size - 1) // 2
    inv2 = 1.0 / (2 * sd * sd)
    best, src = best_all + jump, -1
    for j in range(2 * W + 1):
        h = (h2 + W - j - s0) % B
        for r in range(pred_ptr[c2], pred_ptr[c2 + 1]):
            c = pred_idx[r]
            v0 = delta[c, h]
            if v0 < best_all - PRUNE:
                continue
            px = cent[c, 0] + cos_h[h] * f - sin_h[h] * lft
            py = cent[c, 1] + sin_h[h] * f + cos_h[h] * lft
            tot = _weights(c, px, py, graph, inv2, lp)
            for q in range(nb_ptr[c], nb_ptr[c + 1]):
                if nb_idx[q] == c2:
                    v = v0 + lp[q - nb_ptr[c]] - tot + log_turn[j]
                    if v > best or (v == best and src >= 0 and c * B + h < src):
                        best, src = v, c * B + h
    return best, src


@njit(cache=True)
def _wrap(x, B):
    """``x % B``, the division spared where ``0 <= x < B`` already."""
    return x if 0 <= x < B else x % B


@njit(cache=True)
def _step(delta, move, graph, kernel, out, work):
    """One keyframe of the recursion: ``out`` = ``(new, arg)``, (N, B) the best score into each
    state and the state it came from (among equal scores the first, the smallest ``c B + h``;
    the best state overall where the jump wins); ``move`` (forward [m], left [m], turn
    [bins]); ``graph`` = ``(cent, nb_ptr, nb_idx, pred_ptr, pred_idx)`` (each cell's successors
    and predecessors, CSR) and ``kernel`` = ``(sd, log_turn, jump)`` as :func:`viterbi`'s;
    ``work`` from :func:`_buffers`.

    A source ``(c, h)`` reaches heading bin ``hh = h + s0`` before the kernel turns it, so the
    kernel applies after the maximum over sources: ``top[c2, hh]`` the best ``delta[c, h] +
    log w(c -> c2) - log sum w`` (its cell ``top_c``, the first among equal scores; the best
    score below it ``below``), then ``new[c2, h2]`` the best of ``top[c2, h2 + W - j] +
    log_turn[j]`` -- the same sums, one kernel pass per state instead of one per (source,
    successor).  Where a score below the best rounds to the same sum once the turn's log is
    added (``below + log_turn`` equal to the best), :func:`_into` settles the state source by
    source.  A cell's normalisers (a log-sum-exp over its successors, summed in order) are
    summed for all its headings side by side: the same sums, independent of one another, so
    the processor overlaps them."""
    top, top_c, below = work[3], work[4], work[5]
    best_all, arg_all = _best(delta)
    top[:, :] = -np.inf
    top_c[:, :] = -1
    below[:, :] = -np.inf
    _from_sources(delta, move, best_all, graph, kernel[0], work)
    _into_targets(delta, move, (best_all, arg_all), graph, kernel, out, work)


@njit(cache=True)
def _from_sources(delta, move, best_all, graph, sd, work):
    """:func:`_step`'s first pass, cell by cell: each unpruned source heading's move end, its
    successors' log weights and normalisers (a cell's headings side by side), and the best
    score into each ``(c2, hh)`` it reaches before the kernel (``top``, ``top_c``, ``below``)."""
    cent, nb_ptr, nb_idx = graph[0], graph[1], graph[2]
    cos_h, sin_h, top, top_c, below, lps = work[0], work[1], work[3], work[4], work[5], work[6]
    px, py, tots, v0s, hs = work[7], work[8], work[9], work[10], work[11]
    N, B = delta.shape
    f, lft, s0 = move[0], move[1], int(move[2]) % B
    inv2 = 1.0 / (2 * sd * sd)
    for c in range(N):
        lo, hi = nb_ptr[c], nb_ptr[c + 1]
        m = 0
        for h in range(B):
            if delta[c, h] >= best_all - PRUNE:
                hs[m] = h
                m += 1
        if m == 0 or hi == lo:
            continue
        for i in range(m):  # each heading's move end
            h = hs[i]
            px[i] = cent[c, 0] + cos_h[h] * f - sin_h[h] * lft
            py[i] = cent[c, 1] + sin_h[h] * f + cos_h[h] * lft
        for q in range(lo, hi):
            x2, y2 = cent[nb_idx[q], 0], cent[nb_idx[q], 1]
            for i in range(m):
                lps[q - lo, i] = -((x2 - px[i]) ** 2 + (y2 - py[i]) ** 2) * inv2
        # _weights' first term: exp(-1e300) is 0, log1p(0) is 0
        for i in range(m):
            tots[i] = max(-1e300, lps[0, i]) + 0.0
        for q in range(1, hi - lo):
            for i in range(m):
                tot, l = tots[i], lps[q, i]
                tots[i] = max(tot, l) + np.log1p(np.exp(-abs(tot - l)))
        for i in range(m):  # hs: the source's heading bin -> the bin it reaches
            v0s[i] = delta[c, hs[i]]
            hs[i] = _wrap(hs[i] + s0, B)
        for q in range(lo, hi):  # each (q, i) reaches its own (c2, hh): any order in a cell
            c2 = nb_idx[q]
            for i in range(m):
                hh = hs[i]
                v1 = v0s[i] + lps[q - lo, i] - tots[i]
                t, b = top[c2, hh], below[c2, hh]
                up = v1 > t  # a tie keeps the smaller cell, the one already there
                below[c2, hh] = t if up else (max(b, v1) if v1 < t else b)
                top[c2, hh] = v1 if up else t
                top_c[c2, hh] = c if up else top_c[c2, hh]


@njit(cache=True)
def _into_targets(delta, move, best, graph, kernel, out, work):
    """:func:`_step`'s second pass, cell by cell: ``new[c2]`` the best of ``top`` turned by the
    kernel or the jump from ``best`` = ``(best_all, arg_all)``, ``arg[c2]`` its first source;
    a state whose runner-up rounds to the same sum settled by :func:`_into`."""
    _, log_turn, jump = kernel
    new, arg = out
    top, top_c, below, row, best_h = work[3], work[4], work[5], work[12], work[13]
    best_all, arg_all = best
    N, B = delta.shape
    s0 = int(move[2]) % B
    W = (log_turn.size - 1) // 2
    floor = best_all + jump
    for c2 in range(N):
        for x in range(B + 2 * W):  # row[h2 + 2 W - j] = top[c2, h2 + W - j]
            row[x] = top[c2, _wrap(x - W, B)]
        for h2 in range(B):
            best_h[h2] = floor
        for j in range(2 * W + 1):
            lt = log_turn[j]
            for h2 in range(B):
                v = row[h2 + 2 * W - j] + lt
                best_h[h2] = v if v > best_h[h2] else best_h[h2]
        for h2 in range(B):  # the first source among the turns that reach the best
            b = best_h[h2]
            new[c2, h2] = b
            src, tied = -1, False
            if b > floor:
                for j in range(2 * W + 1):
                    if row[h2 + 2 * W - j] + log_turn[j] == b:
                        hh = _wrap(h2 + W - j, B)
                        s = top_c[c2, hh] * B + _wrap(hh - s0, B)
                        src = s if src < 0 else min(src, s)
                        tied = tied or below[c2, hh] + log_turn[j] == b
            if tied:
                new[c2, h2], src = _into(delta, move, c2, h2, best_all, graph, kernel, work)
            arg[c2, h2] = src if src >= 0 else arg_all


@njit(cache=True)
def _first(idx, lo, q):
    """Whether ``idx[q]`` is not among ``idx[lo:q]``."""
    for r in range(lo, q):
        if idx[r] == idx[q]:
            return False
    return True


@njit(cache=True)
def _predecessors(nb_ptr, nb_idx, N):
    """CSR ``(ptr, idx)`` of each cell's predecessors (the cells it is a successor of), each
    once, in increasing order."""
    count = np.zeros(N + 1, dtype=np.int64)
    for c in range(N):
        for q in range(nb_ptr[c], nb_ptr[c + 1]):
            if _first(nb_idx, nb_ptr[c], q):
                count[nb_idx[q] + 1] += 1
    ptr = np.cumsum(count)
    idx = np.empty(ptr[N], dtype=np.int64)
    fill = ptr[:N].copy()
    for c in range(N):
        for q in range(nb_ptr[c], nb_ptr[c + 1]):
            if _first(nb_idx, nb_ptr[c], q):
                idx[fill[nb_idx[q]]] = c
                fill[nb_idx[q]] += 1
    return ptr, idx


@njit(cache=True)
def _buffers(N, B, most, turns):
    """:func:`_step`'s ``work`` for ``N`` cells, ``B`` heading bins, cells of at most ``most``
    successors and a heading kernel of ``turns`` bins: each bin's cosine and sine, a cell's
    successors' log weights (``lp``), ``top``, ``top_c`` and ``below`` (N, B), a cell's
    headings' log weights (``lps``, most x B), move ends (x, y), normalisers, scores and bins,
    a row of ``top`` padded by the kernel's reach, each target bin's best score."""
    cos_h, sin_h = np.empty(B), np.empty(B)
    for h in range(B):
        cos_h[h], sin_h[h] = np.cos(2 * np.pi * h / B), np.sin(2 * np.pi * h / B)
    most = max(1, most)
    return (cos_h, sin_h, np.empty(most), np.empty((N, B)), np.empty((N, B), dtype=np.int64),
            np.empty((N, B)), np.empty((most, B)), np.empty(B), np.empty(B), np.empty(B),
            np.empty(B), np.empty(B, dtype=np.int64), np.empty(B + turns), np.empty(B))


def viterbi(E, moves, cent, nb_ptr, nb_idx, sd, log_turn, log_init, jump):
    """``(cells, heading bins)`` (K,) each, the best path: ``E`` (K, N, B) emissions; ``moves``
    (K, 3) into keyframe ``k`` in the frame of keyframe ``k - 1`` (forward [m], left [m], turn
    [rad]); ``cent`` (N, 2) [m]; each cell's successors in CSR (``nb_ptr`` (N + 1,),
    ``nb_idx``); ``sd`` [m]; ``log_turn`` (:func:`heading_kernel`); ``log_init`` (N,) the first
    keyframe's cell prior (log; every heading alike); ``jump`` (log) a jump anywhere.  Memory:
    the path's way back, K x N x B of 2 bytes (4 where N B > 65,536)."""
    K, N, B = E.shape
    back = np.empty((K, N, B), dtype=np.uint16 if N * B <= 65536 else np.int32)
    return _viterbi(E, moves, cent, nb_ptr, nb_idx, sd, log_turn, log_init, jump, back)


@njit(cache=True)
def _viterbi(E, moves, cent, nb_ptr, nb_idx, sd, log_turn, log_init, jump, back):
    """:func:`viterbi` with its way back ``back`` (K, N, B) given."""
    K, N, B = E.shape
    delta = np.empty((N, B))
    for c in range(N):
        delta[c] = log_init[c] + E[0, c]
    new = np.empty((N, B))
    arg = np.empty((N, B), dtype=np.int32)
    pred_ptr, pred_idx = _predecessors(nb_ptr, nb_idx, N)
    work = _buffers(N, B, int(np.max(nb_ptr[1:] - nb_ptr[:-1])), log_turn.size)
    for k in range(1, K):
        move = np.array([moves[k, 0], moves[k, 1], np.floor(moves[k, 2] * B / (2 * np.pi) + 0.5)])
        _step(delta, move, (cent, nb_ptr, nb_idx, pred_ptr, pred_idx), (sd, log_turn, jump),
              (new, arg), work)
        for c in range(N):
            for h in range(B):
                delta[c, h] = new[c, h] + E[k, c, h]
                back[k, c, h] = arg[c, h]
        delta -= delta.max()
    cells = np.empty(K, dtype=np.int64)
    bins = np.empty(K, dtype=np.int64)
    i = np.argmax(delta)
    cells[K - 1], bins[K - 1] = i // B, i % B
    for k in range(K - 1, 0, -1):
        a = np.int64(back[k, cells[k], bins[k]])
        cells[k - 1], bins[k - 1] = a // B, a % B
    return cells, bins
