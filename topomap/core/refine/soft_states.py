"""The states the soft rounds work on (:mod:`topomap.core.refine.soft`): twin states -- one
place read as two symbols -- found (:func:`twin_overlap`) and merged (:func:`merge_twins`), and
the states a round keeps (:func:`keep_states`, :func:`min_steps_of`): small states that are only
the residue of misreads go, rarely visited places stay; and how far a labelling's states predict
the next view (:func:`successor_surprise`) and whether its moves show two symbols for one view
(:func:`successor_pairing`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..sums import sparse_pairwise_sum
from .clones import compact_labels

__all__ = ["twin_overlap", "merge_twins", "min_steps_of", "keep_states", "successor_surprise",
           "successor_pairing"]


def twin_overlap(labels, state_symbol, u, has_next, n_actions: int, n_symbols: int):
    """For every state, the largest overlap ``sum_k min(p_X(k), p_Y(k))`` of its predecessor
    distribution (``k`` = previous state and action) with that of a state ``Y`` of another
    K-means symbol.  Misreads of a place's view make a state reached exactly like the place's own
    state (overlap near 1); in a world with deterministic moves two places never share a
    predecessor key (overlap near 0).  GDS states get 0.  Returns ``(overlap, twin)``, ``twin``
    the state ``Y`` (the lowest of equals; the first state of another symbol when none shares
    a key, -1 for GDS states and where no state of another symbol exists).  Only states that
    share a key are compared (:func:`twin_pairs`)."""
    S, A = state_symbol.size, n_actions
    t = np.flatnonzero(has_next)
    code, count = np.unique(labels[t + 1] * (S * A) + labels[t] * A + u[t], return_counts=True)
    dest, key = code // (S * A), code % (S * A)
    share = count / np.maximum(np.bincount(dest, weights=count, minlength=S), 1.0)[dest]
    order = np.lexsort((dest, key))
    kptr = np.searchsorted(key[order], np.arange(S * A + 1))
    symbol = np.where(state_symbol < n_symbols, state_symbol, -1).astype(np.int64)
    out, twin = twin_pairs(kptr, dest[order], share[order], symbol, S * A)
    plain = np.flatnonzero(symbol >= 0)
    if plain.size:
        other = plain[state_symbol[plain] != state_symbol[plain[0]]]
        first = np.where(state_symbol[plain] != state_symbol[plain[0]], plain[0],
                         other[0] if other.size else -1)
        twin[plain] = np.where(twin[plain] < 0, first, twin[plain])
    return out, twin


def merge_twins(seq, labels, state_symbol, twin: float):
    """Merge every state into its twin of another symbol (:func:`twin_overlap` at least
    ``twin``), the smaller state into the larger: the steps of a place read as two symbols (its
    view lies between two K-means clusters, or misreads started a chain) become one state, which
    keeps the larger state's symbol.  Returns ``(labels, state_symbol, n_merged)``; unused
    states are removed and states renumbered by first use."""
    if twin >= 1.0:
        return labels, state_symbol, 0
    overlap, partner = twin_overlap(labels, state_symbol, seq.u, seq.masks()[1], seq.n_actions,
                                    seq.n_symbols)
    sizes = np.bincount(labels, minlength=state_symbol.size)
    target = np.arange(state_symbol.size)
    for x in np.argsort(sizes, kind="stable"):
        y = partner[x]
        if overlap[x] >= twin and y >= 0 and sizes[y] >= sizes[x] and target[y] != x:
            target[x] = y
    for _ in range(state_symbol.size):  # follow chains x -> y -> z
        nxt = target[target]
        if np.array_equal(nxt, target):
            break
        target = nxt
    n_merged = int(np.sum(target != np.arange(state_symbol.size)))
    labels, state_symbol, _ = compact_labels(target[labels], state_symbol)
    return labels, state_symbol, n_merged


def min_steps_of(settings, n_steps: int, n_reference: int) -> float:
    """The steps a state needs to be kept (``settings`` a
    :class:`~topomap.core.refine.settings.SoftRounds`): ``settings.min_steps`` itself from 1 on,
    else that fraction of the mean steps per state of ``n_reference`` states."""
    m = settings.min_steps
    return m if m >= 1 else int(np.ceil(m * n_steps / n_reference))


def keep_states(seq, labels, state_symbol, min_steps: int, twin: float) -> np.ndarray:
    """States to keep: GDS states, those with at least ``min_steps`` steps, and small ones that
    look like a rarely visited place rather than the residue of misreads: no twin of another
    symbol (:func:`twin_overlap` below ``twin``), reached mostly from kept-size states, and
    the usual outcome of those arrivals (from its predecessor keys, at least half the
    transitions lead to it: a misread is the unusual outcome of a move).  States below
    ``min_steps / 5`` steps always go."""
    sizes = np.bincount(labels, minlength=state_symbol.size)
    big = sizes >= min_steps
    keep = big | (state_symbol >= seq.n_symbols)
    if twin < 1.0 and not keep.all():
        has_next = seq.masks()[1]
        overlap, _ = twin_overlap(labels, state_symbol, seq.u, has_next, seq.n_actions,
                                  seq.n_symbols)
        t = np.flatnonzero(has_next)
        key = labels[t] * seq.n_actions + seq.u[t]
        key_total = np.bincount(key, minlength=state_symbol.size * seq.n_actions)
        S = state_symbol.size
        into = np.bincount(labels[t + 1], minlength=S)
        from_big = np.bincount(labels[t + 1], weights=big[labels[t]], minlength=S)
        pairs = np.unique(labels[t + 1] * (S * seq.n_actions) + key)
        reach = np.bincount(pairs // (S * seq.n_actions),
                            weights=key_total[pairs % (S * seq.n_actions)], minlength=S)
        share = into / np.maximum(reach, 1.0)
        rare_place = ((overlap < twin) & (from_big >= 0.5 * into) & (share >= 0.5)
                      & (sizes >= min_steps / 5))
        keep |= rare_place
    return keep


def successor_surprise(seq, labels) -> float:
    """The share of a labelling's transitions whose next symbol is not the one its (state,
    action) is most often followed by: 0 when the states predict every next view, as in a
    deterministic world mapped right; every misread raises it (a move from a well-known state
    that once shows another view): a labelling at 0 leaves a soft round nothing to correct."""
    t = np.flatnonzero(seq.masks()[1])
    if t.size == 0:
        return 0.0
    key = labels[t] * seq.n_actions + seq.u[t]
    pairs, count = np.unique(key * seq.n_ids + seq.sym[t + 1], return_counts=True)
    top = np.zeros(int(key.max()) + 1)
    np.maximum.at(top, pairs // seq.n_ids, count)
    return float(1.0 - top.sum() / t.size)


def successor_pairing(seq, labels) -> float:
    """How often a labelling's moves show one K-means symbol where another is their usual next
    view, for the pair of symbols it happens to most: every transition counted under the
    symbol most often seen after its (state, action) and the symbol seen, the largest
    off-diagonal share of a row.  Misreads give a few per cent (gridroom 8x6 at 18 % misreads
    0.06-0.10); a view phase 1 cut into two symbols, seen after the same moves in turn, 0.2-0.5
    (the office at 10.8-25.6 %): what the first soft round's confusion matrix learns as
    ``paired`` (:func:`~topomap.core.refine.rounds.pair_read`), read off the hard labelling."""
    ns = seq.n_symbols
    t = np.flatnonzero(seq.masks()[1])
    t = t[seq.sym[t + 1] < ns]
    if t.size == 0 or ns < 2:
        return 0.0
    key = np.unique(labels[t] * seq.n_actions + seq.u[t], return_inverse=True)[1].ravel()
    seen = np.zeros((int(key.max()) + 1, ns))
    np.add.at(seen, (key, seq.sym[t + 1]), 1.0)
    rows = np.zeros((ns, ns))
    np.add.at(rows, seen.argmax(axis=1), seen)
    rows /= np.maximum(rows.sum(axis=1, keepdims=True), 1.0)
    np.fill_diagonal(rows, 0.0)
    return float(rows.max())


@njit(cache=True)
def twin_pairs(kptr, dest, share, symbol, n_keys):
    """The largest predecessor overlap of every state with a state of another symbol, from the
    states every predecessor key leads to (see :func:`twin_overlap`).

    ``dest[kptr[k]:kptr[k + 1]]`` are the states key ``k`` leads to, in increasing order, and
    ``share`` the part of each state's arrivals that key brings; ``symbol`` (S,) the symbol of
    every state, -1 for those left out (GDS).  Returns ``(overlap, twin)``: for every state ``x``
    the largest ``sum_k min(share_x(k), share_y(k))`` over the states ``y`` of another symbol it
    shares a key with (the lowest ``y`` of equals) -- each sum taken as numpy sums the dense row
    of ``n_keys`` entries (:func:`topomap.core.sums.sparse_pairwise_sum`), so the values are those
    of the dense computation bit for bit -- and 0.0 with ``twin`` -1 where it shares none.
    """
    S = symbol.size
    n_pairs = 0
    for k in range(kptr.size - 1):
        m = kptr[k + 1] - kptr[k]
        n_pairs += m * (m - 1)
    px = np.empty(n_pairs, dtype=np.int64)
    py = np.empty(n_pairs, dtype=np.int64)
    pk = np.empty(n_pairs, dtype=np.int64)
    pv = np.empty(n_pairs)
    n = 0
    for k in range(kptr.size - 1):
        for a in range(kptr[k], kptr[k + 1]):
            x = dest[a]
            for b in range(kptr[k], kptr[k + 1]):
                y = dest[b]
                if a != b and symbol[x] >= 0 and symbol[y] >= 0 and symbol[x] != symbol[y]:
                    px[n], py[n], pk[n] = x, y, k
                    pv[n] = min(share[a], share[b])
                    n += 1
    order = np.argsort((px[:n] * S + py[:n]) * n_keys + pk[:n])
    overlap = np.zeros(S)
    twin = np.full(S, -1, dtype=np.int64)
    i = 0
    while i < n:
        j = i
        x, y = px[order[i]], py[order[i]]
        while j < n and px[order[j]] == x and py[order[j]] == y:
            j += 1
        ov = sparse_pairwise_sum(pk[order[i:j]], pv[order[i:j]], n_keys)
        if ov > overlap[x]:
            overlap[x], twin[x] = ov, y
        i = j
    return overlap, twin
