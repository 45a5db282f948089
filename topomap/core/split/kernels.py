"""Compiled bookkeeping of the split: the instance and transition tables, tallies of their
updates, the steps a split moves or touches (the merge and the gain: :mod:`.merge_kernels`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .threads import CHUNK, in_threads, pieces

__all__ = ["transition_table", "action_table", "merge_tallies", "tally_codes",
           "instance_table", "centre_pairs", "tally_pairs", "sorted_union", "follow_keys",
           "touched_codes", "split_table"]

@njit(cache=True, nogil=True)
def transition_table(x, u, has_next, S, A):
    """Sorted codes ``(x[t] * A + u[t]) << 32 | x[t + 1]`` of the distinct transitions (steps
    with ``has_next``) and their counts, in two passes over the steps and no (T,) temporaries:
    the same table :func:`instance_table` makes of instances."""
    key_seen, col_seen = np.zeros(S * A, dtype=np.bool_), np.zeros(S, dtype=np.bool_)
    for t in range(x.size):
        if has_next[t]:
            key_seen[x[t] * A + u[t]] = True
            col_seen[x[t + 1]] = True
    keys, cols = np.flatnonzero(key_seen), np.flatnonzero(col_seen)
    key_rank, col_rank = np.full(S * A, -1), np.full(S, -1)
    key_rank[keys] = np.arange(keys.size)
    col_rank[cols] = np.arange(cols.size)
    n = np.zeros((keys.size, cols.size), dtype=np.int64)
    for t in range(x.size):
        if has_next[t]:
            n[key_rank[x[t] * A + u[t]], col_rank[x[t + 1]]] += 1
    nz = np.flatnonzero(n)
    codes = np.empty(nz.size, dtype=np.int64)
    for i in range(nz.size):
        codes[i] = (keys[nz[i] // cols.size] << 32) | cols[nz[i] % cols.size]
    return codes, n.ravel()[nz]


@njit(cache=True, nogil=True)
def action_table(x, u, S, A):
    """(S, A) how often each state takes each action: ``np.bincount(x * A + u)`` in one pass."""
    out = np.zeros((S, A), dtype=np.int64)
    for t in range(x.size):
        out[x[t], u[t]] += 1
    return out


@njit(cache=True, nogil=True)
def merge_tallies(codes, counts, minus, minus_n, plus, plus_n):
    """The sorted sparse table (``codes``, ``counts``) with ``minus_n[j]`` taken off at code
    ``minus[j]`` and ``plus_n[k]`` added at code ``plus[k]`` (both tallies sorted and distinct;
    every code of ``minus`` is in the table), entries that reach zero dropped: one merge."""
    out_codes = np.empty(codes.size + plus.size, dtype=np.int64)
    out_counts = np.empty(codes.size + plus.size, dtype=np.int64)
    i = j = k = n = 0
    while i < codes.size or k < plus.size:
        if k >= plus.size or (i < codes.size and codes[i] <= plus[k]):
            c, v = codes[i], counts[i]
            i += 1
        else:
            c, v = plus[k], 0
        if k < plus.size and plus[k] == c:
            v += plus_n[k]
            k += 1
        if j < minus.size and minus[j] < c:
            raise ValueError("a code taken off is not in the table")
        if j < minus.size and minus[j] == c:
            v -= minus_n[j]
            j += 1
        if v < 0:
            raise ValueError("more taken off a code than the table holds")
        if v != 0:
            out_codes[n], out_counts[n] = c, v
            n += 1
    if j < minus.size:
        raise ValueError("a code taken off is not in the table")
    return out_codes[:n], out_counts[:n]


@njit(cache=True, nogil=True)
def _tally_sorted(codes):
    """Sorted distinct ``codes`` and their counts, by sorting them."""
    codes = np.sort(codes)
    out, counts = np.empty(codes.size, dtype=np.int64), np.empty(codes.size, dtype=np.int64)
    m = 0
    for i in range(codes.size):
        if m > 0 and out[m - 1] == codes[i]:
            counts[m - 1] += 1
        else:
            out[m], counts[m] = codes[i], 1
            m += 1
    return out[:m], counts[:m]


@njit(cache=True, nogil=True)
def _stable_by(codes, shift, size, out):
    """``codes`` into ``out`` in the order of ``(code >> shift) & 0xFFFFFFFF`` (below ``size``),
    ties in their order: a counting sort."""
    start = np.zeros(size + 1, dtype=np.int64)
    for c in codes:
        start[((c >> shift) & 0xFFFFFFFF) + 1] += 1
    for k in range(size):
        start[k + 1] += start[k]
    for c in codes:
        d = (c >> shift) & 0xFFFFFFFF
        out[start[d]] = c
        start[d] += 1


@njit(cache=True, nogil=True)
def _tally(codes, size):
    """Sorted distinct ``codes`` (``key << 32 | col``, keys and columns below ``size``) and
    their counts: counting sorts by column then by key, then one pass over the sorted codes, in
    O(codes + size); by a sort, O(codes log codes), when the codes are few next to ``size``."""
    n = codes.size
    if 16 * n < size:
        return _tally_sorted(codes)
    by_col, ordered = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    _stable_by(codes, 0, size, by_col)
    _stable_by(by_col, 32, size, ordered)
    counts = by_col  # reused: its codes are no longer needed
    m = 0
    for i in range(n):
        if m > 0 and ordered[m - 1] == ordered[i]:
            counts[m - 1] += 1
        else:
            ordered[m], counts[m] = ordered[i], 1
            m += 1
    return ordered[:m].copy(), counts[:m].copy()


@njit(cache=True, nogil=True)
def tally_codes(codes, size):
    """Sorted distinct values of ``codes`` (``key << 32 | col``, keys and columns below
    ``size``) and how often each occurs."""
    return _tally(codes, size)


@njit(cache=True)
def instance_table(x, u, steps, centre, A, size):
    """The instance table of ``steps``: sorted codes ``key << 32 | column`` (key ``x[t-1] * A +
    u[t-1]``, column ``x[t+1] * A + u[t]``) of the distinct pairs of the steps that are centres,
    and their counts (keys and columns below ``size``): one pass gathers the pairs, then
    :func:`_tally`; no (keys x columns) array."""
    codes = np.empty(steps.size, dtype=np.int64)
    n = 0
    for t in steps:
        if centre[t]:
            codes[n] = ((x[t - 1] * A + u[t - 1]) << 32) | (x[t + 1] * A + u[t])
            n += 1
    return _tally(codes[:n], size)


@njit(cache=True, nogil=True)
def centre_pairs(x, u, centre, S, A, bits, pairs):
    """Every centre's pair ``key << bits | column`` (see :func:`instance_table`; keys and
    columns below ``2 ** bits``), in one pass in step order, put in its state's stretch of
    ``pairs`` (as long as the centres; a dtype that holds ``2 ** (2 * bits)``): the stretches'
    bounds, (S + 1,)."""
    bounds = np.zeros(S + 1, dtype=np.int64)
    for t in range(x.size):
        if centre[t]:
            bounds[x[t] + 1] += 1
    for s in range(S):
        bounds[s + 1] += bounds[s]
    fill = bounds[:-1].copy()
    for t in range(x.size):
        if centre[t]:
            s = x[t]
            pairs[fill[s]] = ((x[t - 1] * A + u[t - 1]) << bits) | (x[t + 1] * A + u[t])
            fill[s] += 1
    return bounds


@njit(cache=True, nogil=True)
def tally_pairs(pairs, bits, size):
    """The instance table of the pairs ``key << bits | column`` (:func:`centre_pairs`; keys and
    columns below ``size``)."""
    codes = np.empty(pairs.size, dtype=np.int64)
    mask = (np.int64(1) << bits) - 1
    for i in range(pairs.size):
        p = np.int64(pairs[i])
        codes[i] = ((p >> bits) << 32) | (p & mask)
    return _tally(codes, size)


@njit(cache=True, nogil=True)
def sorted_union(a, b):
    """The distinct values of two sorted int arrays, sorted (a merge: no sort)."""
    out = np.empty(a.size + b.size, dtype=np.int64)
    i = j = n = 0
    while i < a.size or j < b.size:
        if j >= b.size or (i < a.size and a[i] <= b[j]):
            v = a[i]
            i += 1
        else:
            v = b[j]
            j += 1
        if n == 0 or out[n - 1] != v:
            out[n] = v
            n += 1
    return out[:n]


@njit(cache=True, nogil=True)
def _follow_keys(x, u, steps, has_prev, has_next, A, chosen):
    goes = np.zeros(steps.size, dtype=np.bool_)
    starts = np.empty(steps.size, dtype=np.int64)
    n = 0
    for i in range(steps.size):
        t = steps[i]
        if has_prev[t]:
            goes[i] = chosen[x[t - 1] * A + u[t - 1]]
        elif has_next[t]:
            starts[n] = i
            n += 1
    return goes, starts[:n]


def follow_keys(x, u, steps, has_prev, has_next, A, chosen, chunk=CHUNK):
    """``(goes, starts)``: a mask over ``steps``, those with a predecessor whose key ``x[t-1] *
    A + u[t-1]`` is ``chosen`` (a mask over the keys), and the positions in ``steps`` of the
    first steps of episodes that have a next step (pieces of ``chunk`` steps on threads)."""
    cut = pieces(steps.size, chunk)
    done = in_threads(lambda p: _follow_keys(x, u, steps[p], has_prev, has_next, A, chosen), cut,
                      steps=steps.size)
    if len(done) == 1:
        return done[0]
    return (np.concatenate([g for g, _ in done]),
            np.concatenate([s + p.start for (_, s), p in zip(done, cut)]))


@njit(cache=True, nogil=True)
def _shifted(moved, has, shift):
    out = np.empty(moved.size, dtype=np.int64)
    n = 0
    for t in moved:
        if has[t]:
            out[n] = t + shift
            n += 1
    return out[:n]


@njit(cache=True, nogil=True)
def _code_pair(x, u, t, A, shift, centred, q, new):
    """The instance (``centred``) or transition code at step ``t`` before a split of ``q`` (the
    label ``new`` read as ``q``) and after it (labels ``x`` as they are)."""
    if centred:
        a, b, ua, ub = x[t - 1], x[t + 1], u[t - 1], u[t]
        after = ((a * A + ua) << shift) | (b * A + ub)
        a, b = q if a == new else a, q if b == new else b
        return ((a * A + ua) << shift) | (b * A + ub), after
    a, b = x[t], x[t + 1]
    after = ((a * A + u[t]) << shift) | b
    a, b = q if a == new else a, q if b == new else b
    return ((a * A + u[t]) << shift) | b, after


@njit(cache=True, nogil=True)
def _centre_codes(c, centre, x, u, A, shift, q, new, rows, near):
    """The centre rows of :func:`touched_codes` for the sorted steps ``c``, written into
    ``rows`` (7, c.size): those outside ``q`` and ``new`` into rows 0-3, those inside into rows
    4-6, each from column 0 on; ``near`` marked.  Returns how many of each."""
    n_out = n_in = 0
    for t in c:
        s = x[t]
        near[s] = True
        if not centre[t]:
            continue
        b, a = _code_pair(x, u, t, A, shift, True, q, new)
        if s == q or s == new:
            rows[4, n_in], rows[5, n_in], rows[6, n_in] = b, a, s == new
            n_in += 1
        else:
            rows[0, n_out], rows[1, n_out], rows[2, n_out], rows[3, n_out] = t, s, b, a
            n_out += 1
    return n_out, n_in


@njit(cache=True, nogil=True)
def _start_codes(starts, has_next, x, u, A, shift, q, new, trans):
    """The transition rows of :func:`touched_codes` for the sorted steps ``starts``, written
    into ``trans`` (2, starts.size) from column 0 on; how many."""
    n = 0
    for t in starts:
        if has_next[t]:
            trans[0, n], trans[1, n] = _code_pair(x, u, t, A, shift, False, q, new)
            n += 1
    return n


@njit(cache=True)
def _close_up(rows, first, kept):
    """Move the ``kept[k]`` columns of ``rows`` written from column ``first[k]`` on next to
    those before them, in order; a copy of the columns kept."""
    n = 0
    for k in range(first.size):
        if n != first[k]:
            rows[:, n:n + kept[k]] = rows[:, first[k]:first[k] + kept[k]].copy()
        n += kept[k]
    return rows[:, :n].copy()


@njit(cache=True, nogil=True)
def _around(moved, has_prev, has_next):
    """The sorted steps next to a moved step, and the sorted starts of the transitions next to
    or at one."""
    before = _shifted(moved, has_prev, -1)
    return (sorted_union(before, _shifted(moved, has_next, 1)),
            sorted_union(_shifted(moved, has_next, 0), before))


@njit(cache=True, nogil=True)
def _piece_codes(moved, lo, hi, masks, walk, split, out):
    """The rows of :func:`touched_codes` for the steps of ``[moved[lo], moved[hi])`` (from the
    first step for the first piece, to the last for the last) next to a moved step -- the moved
    steps ``lo - 1 .. hi`` are the only ones next to them --, written into ``rows`` and ``trans``
    from column 0 on, ``near`` marked.  ``masks`` = ``(has_prev, has_next, centre)``, ``walk`` =
    ``(x, u, A, shift)``, ``split`` = ``(q, new)``, ``out`` = ``(rows, trans, near)``.  Returns
    how many of each: outside, inside, transitions."""
    has_prev, has_next, centre = masks
    x, u, A, shift = walk
    q, new = split
    rows, trans, near = out
    c, starts = _around(moved[max(lo - 1, 0):min(hi + 1, moved.size)], has_prev, has_next)
    low = moved[lo] if lo > 0 else -1
    top = moved[hi] if hi < moved.size else x.size + 1
    i0, i1 = np.searchsorted(c, low), np.searchsorted(c, top)
    j0, j1 = np.searchsorted(starts, low), np.searchsorted(starts, top)
    n_out, n_in = _centre_codes(c[i0:i1], centre, x, u, A, shift, q, new, rows, near)
    return n_out, n_in, _start_codes(starts[j0:j1], has_next, x, u, A, shift, q, new, trans)


def touched_codes(moved, has_prev, has_next, centre, x, u, A, shift, q, new, *, chunk=CHUNK):
    """What a split of ``q`` changed around the sorted steps ``moved`` (labels ``x`` already
    moved to ``new``), in passes over their neighbours (pieces of ``chunk // 2`` moved steps,
    about ``chunk`` neighbours, on threads).

    Returns ``(outside, inside, starts, near)``: ``outside`` rows the instance centres next to a
    moved step that lie outside ``q`` and ``new``, their states, codes before and after;
    ``inside`` rows the codes before and after of those inside, and 1 where the centre is in
    ``new``; ``starts`` rows the codes before and after of the transitions starting next to or at
    a moved step (all in step order); ``near`` a mask over the states holding a step next to a
    moved one (``q`` and ``new`` may be missing).
    """
    cut = pieces(moved.size, max(chunk // 2, 1))
    # every piece writes into its own columns of arrays made here (no large arrays made on the
    # threads, whose memory the allocator would keep apart): at most two neighbours and two
    # transitions a moved step, its piece's and the one on each side
    caps = np.array([2 * (min(p.stop + 1, moved.size) - max(p.start - 1, 0)) for p in cut],
                    dtype=np.int64)
    first = np.cumsum(caps) - caps
    rows = np.empty((7, int(caps.sum())), dtype=np.int64)
    trans = np.empty((2, int(caps.sum())), dtype=np.int64)
    near = np.zeros((len(cut), new + 1), dtype=bool)

    def run(k):
        p, cols = cut[k], slice(first[k], first[k] + caps[k])
        return _piece_codes(moved, p.start, p.stop, (has_prev, has_next, centre),
                            (x, u, A, shift), (q, new), (rows[:, cols], trans[:, cols], near[k]))

    kept = np.array(in_threads(run, range(len(cut)), steps=4 * moved.size),
                    dtype=np.int64).reshape(-1, 3)
    return (_close_up(rows[:4], first, kept[:, 0]), _close_up(rows[4:], first, kept[:, 1]),
            _close_up(trans, first, kept[:, 2]), near.any(axis=0))


@njit(cache=True)
def split_table(codes, counts, chosen, shift):
    """A sorted table ``(codes, counts)`` cut in two by its keys (``code >> shift``): the
    entries whose key is not ``chosen`` (a mask over the keys), then those whose key is."""
    n_in = 0
    for i in range(codes.size):
        if chosen[codes[i] >> shift]:
            n_in += 1
    kept_codes, kept_counts = np.empty(codes.size - n_in, dtype=np.int64), np.empty(
        codes.size - n_in, dtype=np.int64)
    went_codes, went_counts = np.empty(n_in, dtype=np.int64), np.empty(n_in, dtype=np.int64)
    i_kept = i_went = 0
    for i in range(codes.size):
        if chosen[codes[i] >> shift]:
            went_codes[i_went], went_counts[i_went] = codes[i], counts[i]
            i_went += 1
        else:
            kept_codes[i_kept], kept_counts[i_kept] = codes[i], counts[i]
            i_kept += 1
    return (kept_codes, kept_counts), (went_codes, went_counts)
