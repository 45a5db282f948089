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
def _step(delta, move, graph, kernel, out, work):
    """One keyframe of the recursion: ``out`` = ``(new, arg)``, (N, B) the best score into each
    state and the state it came from; ``move`` (forward [m], left [m], turn [bins]); ``graph``
    = ``(cent, nb_ptr, nb_idx)`` and ``kernel`` = ``(sd, log_turn, jump)`` as :func:`viterbi`'s;
    ``work`` = ``(cos_h, sin_h, lp)``: (B,) the cosine and sine of each heading bin's angle, a
    buffer of a cell's most successors (each successor's log weight, computed once for the
    normaliser and the moves: the same numbers as computed twice)."""
    cent, nb_ptr, nb_idx = graph
    sd, log_turn, jump = kernel
    new, arg = out
    cos_h, sin_h, lp = work
    f, lft, s0 = move[0], move[1], int(move[2])
    N, B = delta.shape
    W = (log_turn.size - 1) // 2
    best_all, arg_all = _best(delta)
    new[:, :] = best_all + jump
    arg[:, :] = arg_all
    inv2 = 1.0 / (2 * sd * sd)
    for c in range(N):
        lo, hi = nb_ptr[c], nb_ptr[c + 1]
        for h in range(B):
            v0 = delta[c, h]
            if v0 < best_all - PRUNE:
                continue
            px = cent[c, 0] + cos_h[h] * f - sin_h[h] * lft
            py = cent[c, 1] + sin_h[h] * f + cos_h[h] * lft
            tot = -1e300  # log of the normaliser over the successors
            for q in range(lo, hi):
                c2 = nb_idx[q]
                lp[q - lo] = -((cent[c2, 0] - px) ** 2 + (cent[c2, 1] - py) ** 2) * inv2
                tot = max(tot, lp[q - lo]) + np.log1p(np.exp(-abs(tot - lp[q - lo])))
            first = (h + s0 - W) % B  # the heading bin of the kernel's first turn
            for q in range(lo, hi):
                c2 = nb_idx[q]
                v1 = v0 + lp[q - lo] - tot
                h2 = first
                for j in range(2 * W + 1):
                    v = v1 + log_turn[j]
                    if v > new[c2, h2]:
                        new[c2, h2], arg[c2, h2] = v, c * B + h
                    h2 = h2 + 1 if h2 + 1 < B else 0


@njit(cache=True)
def viterbi(E, moves, cent, nb_ptr, nb_idx, sd, log_turn, log_init, jump):
    """``(cells, heading bins)`` (K,) each, the best path: ``E`` (K, N, B) emissions; ``moves``
    (K, 3) into keyframe ``k`` in the frame of keyframe ``k - 1`` (forward [m], left [m], turn
    [rad]); ``cent`` (N, 2) [m]; each cell's successors in CSR (``nb_ptr`` (N + 1,),
    ``nb_idx``); ``sd`` [m]; ``log_turn`` (:func:`heading_kernel`); ``log_init`` (N,) the first
    keyframe's cell prior (log; every heading alike); ``jump`` (log) a jump anywhere."""
    K, N, B = E.shape
    delta = np.empty((N, B))
    for c in range(N):
        delta[c] = log_init[c] + E[0, c]
    back = np.empty((K, N, B), dtype=np.int32)
    new = np.empty((N, B))
    arg = np.empty((N, B), dtype=np.int32)
    cos_h, sin_h = np.empty(B), np.empty(B)
    for h in range(B):
        cos_h[h], sin_h[h] = np.cos(2 * np.pi * h / B), np.sin(2 * np.pi * h / B)
    lp = np.empty(max(1, int(np.max(nb_ptr[1:] - nb_ptr[:-1]))))
    for k in range(1, K):
        move = np.array([moves[k, 0], moves[k, 1], np.floor(moves[k, 2] * B / (2 * np.pi) + 0.5)])
        _step(delta, move, (cent, nb_ptr, nb_idx), (sd, log_turn, jump), (new, arg),
              (cos_h, sin_h, lp))
        delta[:, :] = new + E[k]
        back[k] = arg
        delta -= delta.max()
    cells = np.empty(K, dtype=np.int64)
    bins = np.empty(K, dtype=np.int64)
    i = np.argmax(delta)
    cells[K - 1], bins[K - 1] = i // B, i % B
    for k in range(K - 1, 0, -1):
        a = back[k, cells[k], bins[k]]
        cells[k - 1], bins[k - 1] = a // B, a % B
    return cells, bins
