"""Compiled kernels that reproduce numpy's floating-point results bit for bit.

Phase 2's compiled parts must give the same maps as the plain numpy expressions they replace,
byte for byte in ``map.json`` (the same config and seed always give the same map, whichever
implementation computed it).  The kernels here therefore perform *the same IEEE operations in the
same order* as those numpy expressions; they never call ``log`` themselves (numpy's SIMD ``log2`` can differ
from libm's in the last bit), so every logarithm is computed by numpy and passed in as a table.

* :func:`pairwise_sum` -- numpy's ``add.reduce`` of a contiguous float64 run (``loops_utils.h``):
  blocks below 8 summed in order, blocks up to 128 with 8 interleaved accumulators, longer runs
  split in halves rounded down to a multiple of 8.  ``0.0 + pairwise_sum(a, 0, n)`` equals
  ``a.sum()`` for 1-D ``a``, for whole C-contiguous arrays and along a contiguous last axis
  (checked on lengths 1..3,000,000 in the tests).
* :func:`sparse_pairwise_sum` -- the same sum of a long array that is zero except at given
  positions, in time proportional to the non-zeros: adding an exact ``0.0`` never changes a
  partial sum, so only the tree shape, fixed by the positions, matters.
* :func:`merge_groups_kernel` -- :func:`topomap.core.split.engine.merge_groups` (bottom-up merge of count
  rows by least weighted-entropy increase, costs rounded to ``decimals``, ties to the smallest
  pair), with the cost matrix kept in the same orientation and operand order as the numpy code;
  the smallest cost is found from cached row minima (same index as ``np.argmin``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["pairwise_sum", "sparse_pairwise_sum"]

_BLOCK = 128  # numpy's PW_BLOCKSIZE


@njit(cache=True)
def _dense_block(a, lo, n):
    """numpy's sum of a run of at most 128 values: in order below 8, else 8 accumulators."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    m = n - n % 8
    for i in range(lo + 8, lo + m, 8):  # eight scalars: no array made a call
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for i in range(m, n):
        res += a[lo + i]
    return res


@njit(cache=True)
def _sparse_block(pos, val, i0, i1, start, n):
    """Sum of a block of at most 128 virtual entries holding ``val[i0:i1]`` at ``pos[i0:i1]``."""
    if n < 8:
        res = -0.0
        for i in range(i0, i1):
            res += val[i]
        return res
    m = n - n % 8
    r = np.zeros(8)
    i = i0
    while i < i1 and pos[i] - start < m:
        r[(pos[i] - start) % 8] += val[i]
        i += 1
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < i1:
        res += val[i]
        i += 1
    return res


@njit(cache=True)
def _tree_sum(a, pos, val, lo, n, sparse):
    """numpy's pairwise recursion, unrolled with an explicit stack (numba cannot cache recursive
    functions).  Dense: ``a[lo:lo + n]``; sparse: the virtual run ``[lo, lo + n)`` holding ``val``
    at the sorted positions ``pos``."""
    f_lo = np.empty(64, dtype=np.int64)
    f_n = np.empty(64, dtype=np.int64)
    f_i0 = np.empty(64, dtype=np.int64)
    f_i1 = np.empty(64, dtype=np.int64)
    f_stage = np.zeros(64, dtype=np.int64)
    f_left = np.empty(64)
    f_lo[0], f_n[0], f_i0[0], f_i1[0], f_stage[0] = lo, n, 0, pos.size, 0
    sp, ret = 1, 0.0
    while sp > 0:
        k = sp - 1
        L, N, i0, i1 = f_lo[k], f_n[k], f_i0[k], f_i1[k]
        if sparse and i0 == i1:
            ret, sp = 0.0, sp - 1
        elif N <= _BLOCK:
            ret = _sparse_block(pos, val, i0, i1, L, N) if sparse else _dense_block(a, L, N)
            sp -= 1
        else:
            n2 = N // 2
            n2 -= n2 % 8
            mid = i0 + np.searchsorted(pos[i0:i1], L + n2) if sparse else 0
            if f_stage[k] == 0:
                f_stage[k] = 1
                f_lo[sp], f_n[sp], f_i0[sp], f_i1[sp], f_stage[sp] = L, n2, i0, mid, 0
                sp += 1
            elif f_stage[k] == 1:
                f_left[k], f_stage[k] = ret, 2
                f_lo[sp], f_n[sp], f_i0[sp], f_i1[sp], f_stage[sp] = L + n2, N - n2, mid, i1, 0
                sp += 1
            else:
                ret, sp = f_left[k] + ret, sp - 1
    return ret


_NO_POS = np.empty(0, dtype=np.int64)
_NO_VAL = np.empty(0)


@njit(cache=True)
def pairwise_sum(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]`` (1-D float64)."""
    if n <= _BLOCK:
        return _dense_block(a, lo, n)
    return _tree_sum(a, _NO_POS, _NO_VAL, lo, n, False)


@njit(cache=True)
def sparse_pairwise_sum(pos, val, n):
    """``np.sum`` of a length-``n`` float64 array that is ``val`` at the sorted, distinct
    positions ``pos`` and ``0.0`` elsewhere (sign of an exact zero result aside)."""
    return 0.0 + _tree_sum(val, pos, val, 0, n, True)
