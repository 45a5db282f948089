"""Compiled kernels of the clone EM: the forward pass, Viterbi and counts over clone blocks (the
backward pass and its expected counts: :mod:`topomap.core.refine.backward`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = ["CloneTables", "clone_step_offsets", "clone_forward", "clone_forward_into",
           "clone_viterbi", "clone_path_counts", "clone_normalize_blocks", "clone_normalize_into",
           "normalise_block", "viterbi_buffers"]

# ======================================================================================
# Clone-structured, action-conditioned HMMs (the refinement phase, topomap.core.refine.clones)
# ======================================================================================
# Model
# -----
# Every hidden state (a *clone*) emits exactly one discrete symbol.  Clones are numbered so that the
# clones of symbol ``k`` are ``start[k] .. start[k + 1] - 1``.  At step ``t`` the symbol ``sym[t]``
# is observed, so only its clones can be occupied, and the transition ``t -> t + 1`` under action
# ``u[t]`` only involves the clones of ``sym[t]`` (rows) and of ``sym[t + 1]`` (columns).
#
# Sparse transition storage
# -------------------------
# Transitions are stored as dense *blocks*, one per ``(action, symbol, next symbol)`` triple that
# occurs in the data: block ``b`` is an ``n(src) x n(dst)`` row-major matrix at
# ``vals[boff[b] : boff[b + 1]]``, where ``n(k) = start[k + 1] - start[k]``.  ``blk[t]`` is the block
# of the transition ``t -> t + 1``, or ``-1`` when step ``t`` ends its episode (no transition crosses
# an episode boundary).  Memory is ``sum_b n(src_b) n(dst_b)``, a small fraction of the dense
# ``S x A x S`` tensor when clones are many and each symbol is followed by few symbols.
#
# What a block entry means (``P(x'|x,u)`` or the joint ``P(u,x'|x)``) is up to the caller: the
# kernels only need ``vals[b][i, j]`` to be the factor of moving from clone ``i`` of ``src_b`` to
# clone ``j`` of ``dst_b`` at a step with that block.
#
# Conventions
# -----------
# * The first step of every episode has a uniform distribution over the clones of its symbol; all
#   likelihoods are conditional on the first symbol of each episode.
# * Forward messages are normalised at every step (scaling factors ``c_t``), so
#   ``log P = sum_t log c_t`` never underflows however long the sequence is.
# * Per-step vectors are stored back to back in one flat array: the vector of step ``t`` starts at
#   ``pos[t]`` (see :func:`clone_step_offsets`).
#
# All arrays are contiguous ``int64`` / ``float64``; no Python objects are used inside the kernels.
# The tables that place a sequence on its clones (``sym``, ``blk``, ``start``, ``boff``, ``pos``)
# travel together as one :class:`CloneTables`.


class CloneTables(NamedTuple):
    """The clone layout of a sequence, as the kernels read it (all ``int64``).

    ``sym`` (T,) the symbol of every step; ``blk`` (T,) the block of the transition ``t -> t + 1``
    (-1 at an episode's last step); ``start`` (K + 1,) the clones of symbol ``k`` are
    ``start[k] .. start[k + 1] - 1``; ``boff`` (B + 1,) block ``b`` occupies
    ``boff[b] .. boff[b + 1] - 1`` of a count or probability array; ``pos`` (T + 1,) the offsets of
    the per-step clone vectors (:func:`clone_step_offsets`).
    """

    sym: np.ndarray
    blk: np.ndarray
    start: np.ndarray
    boff: np.ndarray
    pos: np.ndarray


@njit(cache=True)
def clone_step_offsets(sym, start):
    """Offsets ``pos`` (T + 1,) of the per-step clone vectors: step ``t`` owns
    ``pos[t] .. pos[t + 1] - 1``, one entry per clone of ``sym[t]``."""
    T = sym.size
    pos = np.empty(T + 1, dtype=np.int64)
    pos[0] = 0
    for t in range(T):
        k = sym[t]
        pos[t + 1] = pos[t] + start[k + 1] - start[k]
    return pos


@njit(cache=True)
def clone_forward(tables, vals, prune):
    """Scaled forward pass over the clone layout ``tables`` (:class:`CloneTables`), into new
    arrays (:func:`clone_forward_into`).

    Returns ``(alpha, log_c)``: ``alpha`` (pos[-1],) holds the filtered distribution
    ``P(x_t | s_1..s_t, u_1..u_{t-1})`` of every step over the clones of ``sym[t]``; ``log_c`` (T,)
    the log scaling factors, whose sum is the log-likelihood (0 at episode starts).  Filtered
    probabilities below ``prune`` are set to exactly 0 (0: exact inference), which lets both passes
    skip the clones a confident model has ruled out.  A step the model gives probability zero
    yields ``log_c = -inf`` and a zero message.  A step's message is summed in a buffer of its own
    (the compiler cannot vectorise a sum into the array it reads from).
    """
    T = tables.sym.size
    return clone_forward_into(tables, vals, prune, np.empty(tables.pos[T]), np.empty(T))


@njit(cache=True)
def clone_forward_into(tables, vals, prune, alpha, log_c):
    """:func:`clone_forward` written into ``alpha`` (pos[-1],) and ``log_c`` (T,) (every entry
    overwritten; arrays kept from one E-step to the next spare the page faults of new ones)."""
    sym, blk, start, boff, pos = tables
    T = sym.size
    buf = np.zeros(_widest(start))
    for t in range(T):
        a0 = pos[t]
        n = pos[t + 1] - a0
        if t == 0 or blk[t - 1] < 0:
            for j in range(n):
                alpha[a0 + j] = 1.0 / n
            log_c[t] = 0.0
            continue
        p0 = pos[t - 1]
        o = boff[blk[t - 1]]
        acc = buf[:n]
        acc[:] = 0.0
        # the rows of the non-zero messages, two a pass: (acc + a1 r1) + a2 r2 is the sum of
        # the rows one by one, bit for bit, and reads and writes acc once for both (0.84x the
        # pass's CPU on the 74 E-steps of the 12x12 room, seed 0: rows of about 20 clones;
        # four a pass took 1.8x, the compiler no longer vectorising the loop)
        m = a0 - p0
        i = 0
        while i < m:
            a1 = alpha[p0 + i]
            if a1 == 0.0:
                i += 1
                continue
            k = i + 1
            while k < m and alpha[p0 + k] == 0.0:
                k += 1
            r1 = vals[o + i * n:o + (i + 1) * n]
            if k == m:
                for j in range(n):
                    acc[j] += a1 * r1[j]
                break
            a2 = alpha[p0 + k]
            r2 = vals[o + k * n:o + (k + 1) * n]
            for j in range(n):
                acc[j] = (acc[j] + a1 * r1[j]) + a2 * r2[j]
            i = k + 1
        alpha[a0:a0 + n] = acc
        log_c[t] = np.log(normalise_block(alpha, a0, n, prune))
    return alpha, log_c


@njit(cache=True)
def _widest(start):
    """The most clones any symbol has."""
    width = 0
    for k in range(start.size - 1):
        width = max(width, start[k + 1] - start[k])
    return width


@njit(cache=True)
def normalise_block(alpha, a0, n, prune):
    """Scale ``alpha[a0:a0 + n]`` to sum 1, zeroing entries below ``prune``; returns the sum
    before scaling (the step's scaling factor)."""
    c = 0.0
    for j in range(n):
        c += alpha[a0 + j]
    if c > 0.0:
        for j in range(n):
            a = alpha[a0 + j] / c
            alpha[a0 + j] = a if a >= prune else 0.0
    return c


@njit(cache=True)
def _clone_active(alpha, a0, n, out):
    """Write the local indices ``j < n`` with ``alpha[a0 + j] > 0`` into ``out``; return how many."""
    k = 0
    for j in range(n):
        if alpha[a0 + j] > 0.0:
            out[k] = j
            k += 1
    return k


@njit(cache=True)
def _clone_backtrace(tables, psi, t0, t1, last, path):
    """Write the best path of steps ``t0 .. t1`` (inclusive) ending in local clone ``last``."""
    sym, _, start, _, pos = tables
    k = last
    for t in range(t1, t0 - 1, -1):
        path[t] = start[sym[t]] + k
        if t > t0:
            k = psi[pos[t] + k]


@njit(cache=True)
def viterbi_buffers(offsets, pos, T):
    """``(psi, delta, delta_next, path)`` of a Viterbi pass over ``T`` steps whose step ``t`` has
    ``pos[t + 1] - pos[t]`` candidates, at most the widest run of ``offsets``."""
    width = _widest(offsets)
    return (np.zeros(pos[T], dtype=np.int64), np.empty(width), np.empty(width),
            np.empty(T, dtype=np.int64))


@njit(cache=True)
def clone_viterbi(tables, log_vals):
    """Most probable clone sequence (max-product in log space; ties go to the lowest clone).

    ``log_vals`` is ``log(vals)`` (``-inf`` for zeros).  Returns ``(path, log_p)``: ``path`` (T,)
    global clone ids and ``log_p`` the summed log-probability of the best path of every episode,
    including the uniform start ``-log n(sym[t0])``.
    """
    sym, blk, start, boff, pos = tables
    T = sym.size
    psi, delta, delta_next, path = viterbi_buffers(start, pos, T)
    log_p = 0.0
    t0 = 0
    for t in range(T):
        n = pos[t + 1] - pos[t]
        if t == t0:
            for j in range(n):
                delta[j] = -np.log(n)
        else:
            m = pos[t] - pos[t - 1]
            o = boff[blk[t - 1]]
            # rows, the step's best scores and their arguments as slices: the compiler
            # vectorises the loop over j (0.55x the pass's CPU on the 12x12 room's 13 Viterbi
            # passes, seed 0; the same comparisons, so the same paths)
            best_next, arg = delta_next[:n], psi[pos[t]:pos[t] + n]
            best_next[:] = -np.inf
            arg[:] = 0
            for i in range(m):
                di = delta[i]
                if di == -np.inf:
                    continue
                row = log_vals[o + i * n:o + (i + 1) * n]
                for j in range(n):
                    v = di + row[j]
                    if v > best_next[j]:
                        best_next[j] = v
                        arg[j] = i
            delta, delta_next = delta_next, delta
        if blk[t] < 0:
            best = 0
            for j in range(1, n):
                if delta[j] > delta[best]:
                    best = j
            log_p += delta[best]
            _clone_backtrace(tables, psi, t0, t, best, path)
            t0 = t + 1
    return path, log_p


@njit(cache=True)
def clone_path_counts(path, tables, counts):
    """Add the transitions of a hard clone path to ``counts`` (layout of ``vals``), in place."""
    sym, blk, start, boff, _ = tables
    for t in range(sym.size):
        b = blk[t]
        if b < 0:
            continue
        s, s2 = sym[t], sym[t + 1]
        nn = start[s2 + 1] - start[s2]
        counts[boff[b] + (path[t] - start[s]) * nn + (path[t + 1] - start[s2])] += 1.0
    return counts


@njit(cache=True)
def clone_normalize_blocks(tables, counts, bsrc, bdst, bkey, n_keys, pseudocount, smooth):
    """M-step: turn counts into block probabilities (blocks ``b`` from clones of ``bsrc[b]`` to
    clones of ``bdst[b]``, laid out by ``tables.start`` and ``tables.boff``).

    Rows are grouped by a *row key*: row ``i`` of block ``b`` belongs to group
    ``(bkey[b], start[bsrc[b]] + i)`` -- for ``P(x'|x,u)`` the key is the action, for the joint
    ``P(u,x'|x)`` it is 0 for all blocks.  Every stored entry becomes
    ``(count + pseudocount) / Z`` with ``Z = (group's count total) + smooth``; ``smooth`` stands for
    the pseudocount mass of all entries that are not stored (``pseudocount`` times the number of
    columns of a dense row).  Rows with ``Z = 0`` become 0.  Returns ``(vals, Z)``, ``Z`` of shape
    ``(n_keys, S)``.
    """
    return clone_normalize_into(tables, counts, bsrc, bdst, bkey, n_keys, pseudocount, smooth,
                                np.empty(counts.size))


@njit(cache=True)
def clone_normalize_into(tables, counts, bsrc, bdst, bkey, n_keys, pseudocount, smooth, vals):
    """:func:`clone_normalize_blocks` written into ``vals`` (every entry overwritten)."""
    start, boff = tables.start, tables.boff
    S = start[start.size - 1]
    Z = np.zeros((n_keys, S))
    B = bsrc.size
    for b in range(B):
        c0 = start[bsrc[b]]
        n = start[bsrc[b] + 1] - c0
        nn = start[bdst[b] + 1] - start[bdst[b]]
        for i in range(n):
            src = counts[boff[b] + i * nn:boff[b] + (i + 1) * nn]
            acc = 0.0
            for j in range(nn):
                acc += src[j]
            Z[bkey[b], c0 + i] += acc
    for key in range(n_keys):
        for x in range(S):
            Z[key, x] += smooth
    for b in range(B):
        c0 = start[bsrc[b]]
        n = start[bsrc[b] + 1] - c0
        nn = start[bdst[b] + 1] - start[bdst[b]]
        for i in range(n):
            z = Z[bkey[b], c0 + i]
            row = boff[b] + i * nn
            out = vals[row:row + nn]
            if z <= 0.0:
                out[:] = 0.0
                continue
            # rows as slices: the compiler vectorises the division (the same quotients; 0.43x
            # the M-step's CPU on 13 E-steps of the 12x12 room, seed 0)
            src = counts[row:row + nn]
            for j in range(nn):
                out[j] = (src[j] + pseudocount) / z
    return vals, Z
