"""Clone budgets sized by the data: how many places must share a view, at least.

The refinement's first EM stage gives a K-means symbol ``clone_factor`` x (its split states) +
spare clones (:func:`split_budget`).  The split undercounts places on
views seen from many places (an open floor, a wall face): it stops at the total state count, and
its tests need many visits per place.  The data bound that count from below without any model:

*In a deterministic world a place has one outcome per action sequence.*  So if, from view
``k``, the same action sequence ``w`` was followed by ``m`` different symbol sequences (each seen
at least ``min_count`` times, which discounts misreads), at least ``m`` places show view ``k``.
:func:`place_lower_bound` takes the largest such ``m`` over the action sequences of length 1 to
``horizon``; :func:`evidence_budget` gives every symbol at least that many clones (plus spare).

The bound only uses symbol ids and action ids; in a stochastic world it overcounts (a place with
two outcomes of one action looks like two places), which costs clones, not correctness: EM and
the merging of bisimilar states join clones the data do not separate.
"""

from __future__ import annotations

import numpy as np

from .clones import clone_budget

__all__ = ["place_lower_bound", "distinct_rows", "split_budget", "evidence_budget", "BUDGETS"]


def place_lower_bound(sym, u, lengths, n_ids: int, horizon: int = 2, min_count: int = 2):
    """(n_ids,) the least number of places that show each symbol id.

    For every step ``t`` and every ``h = 1..horizon`` (within the episode), the outcome of the
    action sequence ``u[t..t+h-1]`` from ``sym[t]`` is ``sym[t+1..t+h]``.  The bound of symbol
    ``k`` is the largest number of distinct outcomes, each seen ``min_count`` times or more, of one
    action sequence from ``k``; 1 for a symbol seen but never followed (0 for one never seen).
    The ``(symbol, actions, outcome)`` rows are counted exactly (:func:`distinct_rows`).
    """
    sym = np.asarray(sym, dtype=np.int64)
    u = np.asarray(u, dtype=np.int64)
    T = sym.size
    end = np.repeat(np.cumsum(lengths) - 1, lengths)  # the last step of every step's episode
    bound = (np.bincount(sym, minlength=n_ids) > 0).astype(np.int64)
    for h in range(1, horizon + 1):
        t = np.flatnonzero(np.arange(T) + h <= end)
        if t.size == 0:
            break
        ahead = t[:, None] + np.arange(h)
        # one row per step: its symbol, the h actions taken, the h symbols that followed
        rows = np.column_stack([sym[t], u[ahead], sym[ahead + 1]])
        uniq, cnt = distinct_rows(rows, (n_ids,) + (int(u.max()) + 1,) * h + (n_ids,) * h)
        uniq = uniq[cnt >= min_count]
        if uniq.size == 0:
            continue
        # outcomes per (symbol, action sequence), then the largest per symbol
        pairs, per = np.unique(uniq[:, :1 + h], axis=0, return_counts=True)
        np.maximum.at(bound, pairs[:, 0], per)
    return bound


def distinct_rows(rows, dims):
    """The distinct rows of the int array ``rows`` (N, len(dims)), column ``i`` in
    ``[0, dims[i])``, in ascending order, and how often each occurs: as ``np.unique(rows, axis=0,
    return_counts=True)``, exactly.  Each row is numbered in mixed radix
    (``np.ravel_multi_index``), which is 20 times faster on 10^6 rows, unless there are more
    possible rows than int64 numbers."""
    try:
        keys = np.ravel_multi_index(tuple(rows.T), dims)
    except ValueError:  # more possible rows than int64 numbers
        return np.unique(rows, axis=0, return_counts=True)
    uniq, counts = np.unique(keys, return_counts=True)
    return np.column_stack(np.unravel_index(uniq, dims)), counts


def split_budget(split_state_symbol, seq, factor: int, spare: int):
    """Clones per symbol id sized by the split: ``factor`` x the symbol's split states + ``spare``
    for every K-means symbol, one per GDS id."""
    split_state_symbol = np.asarray(split_state_symbol)
    per = np.bincount(split_state_symbol[split_state_symbol >= 0], minlength=seq.n_symbols)
    return clone_budget(seq.n_symbols, seq.n_gds, factor * per[:seq.n_symbols] + spare)


def evidence_budget(split_state_symbol, seq, factor: int, spare: int, horizon: int = 2,
                    min_count: int = 2, cap: int | None = None):
    """Clones per symbol id: the larger of the split's budget (``factor`` x split states + ``spare``)
    and the data's lower bound on the places showing the symbol (:func:`place_lower_bound`) +
    ``spare``, at most ``cap`` (None: no cap) for K-means symbols; one per GDS id."""
    split_state_symbol = np.asarray(split_state_symbol)
    per = np.bincount(split_state_symbol[split_state_symbol >= 0], minlength=seq.n_symbols)
    lb = place_lower_bound(seq.sym, seq.u, seq.lengths, seq.n_ids, horizon, min_count)
    clones = np.maximum(factor * per[:seq.n_symbols], lb[:seq.n_symbols]) + spare
    if cap is not None:
        clones = np.minimum(clones, max(int(cap), 1))
    return clone_budget(seq.n_symbols, seq.n_ids - seq.n_symbols, clones)


#: budget rules of the refinement's first stage: name -> f(split_state_symbol, seq, factor, spare)
BUDGETS = {"split": split_budget, "evidence": evidence_budget}
