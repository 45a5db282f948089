"""Bringing a refined labelling to the number of states the user asked for.

A refinement chooses its own number of states (it merges duplicates of a place and splits
compound states); when the user told the learner a number (``stop.n_states``), the refined map is
brought to that number:

* too many states: the two states of one symbol whose merge loses the least log-likelihood of the
  actions and transitions (``-T (H(u|x) + H(x'|x,u))``, the split criterion's quantities) are
  merged, again and again (the reverse of the paper's split);
* too few: the paper's split (:class:`topomap.core.split.engine.Splitter`, the learner's
  criterion) continues on the refined labelling.

GDS states (those whose ``state_gds`` is a GDS id, not -1) are never merged or split.
"""

from __future__ import annotations

import numpy as np

from ..split.engine import Splitter
from ..stats import count_tables, xlogx

__all__ = ["merge_to", "split_to", "resize"]


def _rows_ll(rows: np.ndarray) -> float:
    """Log-likelihood (bits) of the counts ``rows`` (..., n) under their own row frequencies."""
    return float(xlogx(rows).sum() - xlogx(rows.sum(axis=-1)).sum())


def _merge_loss(C: np.ndarray, N: np.ndarray, i: int, j: int) -> float:
    """Log-likelihood lost by merging state ``j`` into ``i`` (transitions ``C`` (S, A, S),
    actions ``N`` (S, A)): only the rows of ``i``, ``j`` and of their predecessors change."""
    into = C[:, :, i] + C[:, :, j]
    rows = np.flatnonzero(into.sum(axis=1) > 0)
    rows = rows[(rows != i) & (rows != j)]
    before = _rows_ll(C[rows]) + _rows_ll(C[[i, j]]) + _rows_ll(N[[i, j]])
    after_rows = C[rows].copy()
    after_rows[:, :, i] += after_rows[:, :, j]
    after_rows[:, :, j] = 0
    merged = C[i] + C[j]
    merged[:, i] += merged[:, j]
    merged[:, j] = 0
    after = _rows_ll(after_rows) + _rows_ll(merged) + _rows_ll(N[i] + N[j])
    return before - after


def _relabel(labels: np.ndarray, state_symbol: np.ndarray, i: int, j: int):
    """Merge ``j`` into ``i`` and renumber the states above ``j`` down by one."""
    labels = np.where(labels == j, i, labels)
    labels = labels - (labels > j)
    return labels, np.delete(state_symbol, j)


def _pairs(state_symbol: np.ndarray, is_gds: np.ndarray, among=None):
    """Same-symbol pairs ``(i, j)``, ``i < j``, of states that may merge, GDS states left out
    (with ``among``: only the pairs with a member in it)."""
    out = []
    for s in np.unique(state_symbol[~is_gds]):
        members = np.flatnonzero((state_symbol == s) & ~is_gds)
        for a, i in enumerate(members):
            for j in members[a + 1:]:
                if among is None or i in among or j in among:
                    out.append((int(i), int(j)))
    return out


def _touched(C: np.ndarray, i: int, j: int) -> set:
    """The states whose merge losses change when ``j`` merges into ``i``: ``i``, and the
    predecessors and successors of ``i`` and ``j`` (their rows or their predecessors' rows
    change)."""
    rows = C[[i, j]].sum(axis=(0, 1)) + C[:, :, [i, j]].sum(axis=(1, 2))
    return {i, *np.flatnonzero(rows > 0).tolist()} - {j}


def merge_to(labels, state_symbol, u, n_actions: int, has_next, n_target: int, state_gds):
    """Merge same-symbol states, the least log-likelihood lost first (ties: the smallest pair),
    until ``n_target`` remain or no two mergeable states share a symbol; ``state_gds`` (S,) is
    every state's GDS id (-1: none), and GDS states never merge.  Returns
    ``(labels, state_symbol, n_merged)``.  A merge recomputes only the losses of the pairs it
    touches (:func:`_touched`)."""
    labels = np.asarray(labels, dtype=np.int64)
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    is_gds = np.asarray(state_gds) >= 0
    _, N, C = count_tables(labels, u, state_symbol.size, n_actions, has_next)
    losses = {pair: _merge_loss(C, N, *pair) for pair in _pairs(state_symbol, is_gds)}
    merged = 0
    while state_symbol.size > n_target and losses:
        i, j = min(losses, key=lambda pair: (losses[pair], pair))
        touched = _touched(C, i, j)
        labels, state_symbol = _relabel(labels, state_symbol, i, j)
        is_gds = np.delete(is_gds, j)
        merged += 1
        _, N, C = count_tables(labels, u, state_symbol.size, n_actions, has_next)
        shift = {k: k - (k > j) for k in range(state_symbol.size + 1) if k != j}
        touched = {shift[k] for k in touched}
        losses = {(shift[a], shift[b]): v for (a, b), v in losses.items()
                  if j not in (a, b) and a not in touched and b not in touched
                  and shift[a] not in touched and shift[b] not in touched}
        losses.update({pair: _merge_loss(C, N, *pair)
                       for pair in _pairs(state_symbol, is_gds, among=touched)})
    return labels, state_symbol, merged


def split_to(labels, state_symbol, u, n_actions: int, masks, n_target: int, state_gds,
             criterion):
    """Split with ``criterion`` (the paper's split on the refined labelling) until ``n_target``
    states or no state can be split (GDS states, ``state_gds`` not -1, never are).  Returns
    ``(labels, state_symbol, n_split)``."""
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    splitter = Splitter(np.array(labels, dtype=np.int64), u, n_actions, *masks,
                        symbol=state_symbol.tolist(), gds=np.asarray(state_gds).tolist(),
                        obs_entropy=np.zeros(state_symbol.size), criterion=criterion)
    n_split = 0
    while splitter.n_states < n_target and (best := splitter.best()) is not None:
        splitter.apply(best)
        n_split += 1
    return splitter.labels.astype(np.int64), np.asarray(splitter.symbol, dtype=np.int64), n_split


def resize(labels, state_symbol, u, n_actions: int, masks, n_target: int, state_gds, criterion):
    """``(labels, state_symbol, info)`` with ``n_target`` states where the data allow it (GDS
    states, ``state_gds`` (S,) not -1, stay as they are); ``info`` says what was done (``{"from": S, "to": S', "merged": m, "split": k}``)."""
    S = int(np.asarray(state_symbol).size)
    merged = split = 0
    if S > n_target:
        labels, state_symbol, merged = merge_to(labels, state_symbol, u, n_actions, masks[1],
                                                n_target, state_gds)
    elif S < n_target:
        labels, state_symbol, split = split_to(labels, state_symbol, u, n_actions, masks,
                                               n_target, state_gds, criterion)
    info = {"from": S, "to": int(np.asarray(state_symbol).size), "merged": merged, "split": split}
    return labels, state_symbol, info
