"""Phase 2 (paper Section 3.3): split perceptually aliased states.

A *transition instance* at step ``t`` is ``(x[t-1], u[t-1], x[t], u[t], x[t+1])``; it exists only
when steps ``t-1`` and ``t+1`` lie in the same episode as ``t`` (so the first and last step of every
episode are never the centre of an instance).

For a state ``q`` its instances are grouped by the key ``(x[t-1], u[t-1])`` and counted by the
column ``(u[t], x[t+1])``: a (groups x columns) count matrix.  Keys and columns are encoded
with the action count ``A`` only, so they stay valid when the state count grows.  ``H(I) = H_I(u) + H_I(x'|u)`` is the
entropy of the joint distribution of ``(u, x')`` in ``I``, so everything the method needs follows
from those counts.

Swappable pieces, each a small object:

* split criteria -- ``propose(counts) -> (side, score)`` or ``None``: :class:`EntropyCriterion`
  (the paper's bottom-up merge and entropy gain);
* stopping rules -- ``check(n_initial)`` and ``should_stop(n_states, best_score)``:
  :class:`TargetStates` (the paper's "until the number of states reaches a specified number") and
  :class:`MinGain`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "EntropyCriterion",
    "TargetStates",
    "MinGain",
    "CRITERIA",
    "weighted_entropy",
    "merge_cost",
    "merge_groups",
    "Instances",
    "build_instances",
    "Proposal",
    "propose_split",
    "split_state",
]

#: merge costs are rounded to this many decimals so that ties that are exact in real arithmetic
#: are exact in floating point too and are broken by index order, not by rounding noise
_TIE_DECIMALS = 9


def _xlogx(c: np.ndarray) -> np.ndarray:
    """``c * log2(c)`` with ``0 log 0 = 0``."""
    c = np.asarray(c, dtype=np.float64)
    return c * np.log2(np.maximum(c, 1.0)) if np.all(c == np.round(c)) else np.where(
        c > 0, c * np.log2(np.where(c > 0, c, 1.0)), 0.0)


def weighted_entropy(counts: np.ndarray) -> np.ndarray:
    """``n * H`` in bits for each row of a count matrix (``n`` = row sum, ``H`` = row entropy)."""
    counts = np.atleast_2d(counts)
    return _xlogx(counts.sum(axis=1)) - _xlogx(counts).sum(axis=1)


def merge_cost(counts: np.ndarray, i: int) -> np.ndarray:
    """Weighted-entropy increase ``W(i+j) - W(i) - W(j)`` of merging row ``i`` with every row ``j``."""
    joined = counts + counts[i]
    return weighted_entropy(joined) - weighted_entropy(counts) - weighted_entropy(counts[i])[0]


class EntropyCriterion:
    """The paper's split test.

    Groups (rows of ``counts``) are merged bottom-up, each time the pair whose union increases the
    instance-weighted entropy ``n H`` least (ties: the pair of smallest indices), until two remain.
    The score is the entropy gain ``H(I) - (|I'|/|I| H(I') + |I''|/|I| H(I''))`` in bits.
    """

    name = "entropy"

    def propose(self, counts: np.ndarray):
        """Return ``(side, gain)`` -- ``side[g]`` is True for the groups of the second half -- or
        ``None`` when the state has fewer than two groups."""
        counts = np.asarray(counts)
        if counts.shape[0] < 2:
            return None
        side = merge_groups(counts)
        halves = np.stack([counts[~side].sum(axis=0), counts[side].sum(axis=0)])
        gain = (weighted_entropy(halves.sum(axis=0))[0] - weighted_entropy(halves).sum()) / counts.sum()
        return side, float(max(gain, 0.0))

    def __repr__(self) -> str:
        return "EntropyCriterion()"


#: pairwise merge costs are computed in one broadcast when groups^2 * columns stays below this
_BROADCAST_LIMIT = 2_000_000


def merge_groups(counts: np.ndarray) -> np.ndarray:
    """Agglomerate the rows of an integer count matrix into two clusters, each time merging the
    pair whose union increases the weighted entropy ``n H`` least (ties: smallest indices).

    Returns a boolean array: False for the rows in the cluster holding row 0, True for the others.
    """
    work = np.asarray(counts, dtype=np.int64).copy()
    if np.any(work < 0):
        raise ValueError("counts must be non-negative")
    G, K = work.shape
    # c log2 c for every integer a count can reach: merged counts stay integers
    table = _xlogx(np.arange(2 * int(work.sum()) + 1))  # 2x: a row is also paired with itself
    n = work.sum(axis=1)
    W = table[n] - table[work].sum(axis=1)

    def row_cost(a):
        return np.round(table[n[a] + n] - table[work[a] + work].sum(axis=1) - W[a] - W,
                        _TIE_DECIMALS)

    if G * G * K <= _BROADCAST_LIMIT:
        pair = (table[n[:, None] + n[None, :]] - table[work[:, None, :] + work[None, :, :]].sum(-1)
                - W[:, None] - W[None, :])
        cost = np.round(pair, _TIE_DECIMALS)
    else:
        cost = np.stack([row_cost(a) for a in range(G)])
    cost[np.tril_indices(G)] = np.inf  # only cost[a, b] with a < b is used
    owner = np.arange(G)
    for _ in range(G - 2):
        a, b = divmod(int(np.argmin(cost)), G)
        work[a] += work[b]
        work[b] = 0
        n[a] += n[b]
        n[b] = 0
        W[a] = table[n[a]] - table[work[a]].sum()
        owner[owner == b] = a
        cost[b, :] = np.inf
        cost[:, b] = np.inf
        row = row_cost(a)
        dead = owner != np.arange(G)
        row[dead] = np.inf
        cost[a, a + 1:] = row[a + 1:]
        cost[:a, a] = row[:a]
    return owner != owner[0]


class TargetStates:
    """Stop when the map has ``n_states`` states (the paper: 30)."""

    name = "n_states"

    def __init__(self, n_states: int = 30):
        if isinstance(n_states, bool) or not isinstance(n_states, (int, np.integer)) or n_states < 1:
            raise ValueError(f"stop.n_states must be a positive integer, got {n_states!r}")
        self.n_states = int(n_states)

    def check(self, n_initial: int) -> None:
        if self.n_states < n_initial:
            raise ValueError(
                f"stop.n_states={self.n_states} is below the {n_initial} states that phase 1 "
                "creates (clusters plus GDS); splitting can only add states"
            )

    def should_stop(self, n_states: int, best_score: float) -> bool:
        return n_states >= self.n_states

    def __repr__(self) -> str:
        return f"TargetStates(n_states={self.n_states})"


class MinGain:
    """Stop when the best split scores below ``min_gain`` (or the map reaches ``max_states``)."""

    name = "min_gain"

    def __init__(self, min_gain: float = 0.05, max_states: int | None = None):
        if not np.isfinite(min_gain) or min_gain < 0:
            raise ValueError(f"stop.min_gain must be a finite number >= 0, got {min_gain!r}")
        if max_states is not None and (not isinstance(max_states, (int, np.integer)) or max_states < 1):
            raise ValueError(f"stop.max_states must be a positive integer or None, got {max_states!r}")
        self.min_gain = float(min_gain)
        self.max_states = None if max_states is None else int(max_states)

    def check(self, n_initial: int) -> None:
        if self.max_states is not None and self.max_states < n_initial:
            raise ValueError(
                f"stop.max_states={self.max_states} is below the {n_initial} states that phase 1 creates"
            )

    def should_stop(self, n_states: int, best_score: float) -> bool:
        if self.max_states is not None and n_states >= self.max_states:
            return True
        return best_score < self.min_gain

    def __repr__(self) -> str:
        return f"MinGain(min_gain={self.min_gain}, max_states={self.max_states})"


CRITERIA = {EntropyCriterion.name: EntropyCriterion}


@dataclass
class Instances:
    """All transition instances of a labelling, sorted by centre state.

    ``center`` holds the step index of every instance; ``key`` the group key
    ``x[t-1] * A + u[t-1]``; ``col`` the column ``x[t+1] * A + u[t]``; ``bounds[q]:bounds[q+1]``
    is the slice of state ``q``.
    """

    center: np.ndarray
    key: np.ndarray
    col: np.ndarray
    bounds: np.ndarray

    def of(self, q: int) -> slice:
        return slice(int(self.bounds[q]), int(self.bounds[q + 1]))


def episode_masks(T: int, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(has_prev, has_next)``: whether step ``t`` has a predecessor / successor in its episode."""
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    ends = np.cumsum(lengths) - 1
    has_prev = np.ones(T, dtype=bool)
    has_next = np.ones(T, dtype=bool)
    has_prev[starts] = False
    has_next[ends] = False
    return has_prev, has_next


def build_instances(x: np.ndarray, u: np.ndarray, n_states: int, n_actions: int,
                    has_prev: np.ndarray, has_next: np.ndarray) -> Instances:
    """Collect the transition instances of labelling ``x`` (see module docstring)."""
    center = np.flatnonzero(has_prev & has_next)
    order = np.argsort(x[center], kind="stable")
    center = center[order]
    key = x[center - 1] * n_actions + u[center - 1]
    col = x[center + 1] * n_actions + u[center]
    bounds = np.searchsorted(x[center], np.arange(n_states + 1), side="left")
    return Instances(center, key, col, bounds)


def group_counts(key: np.ndarray, col: np.ndarray):
    """(groups x columns) count matrix of one state's instances and the sorted unique keys."""
    keys, g = np.unique(key, return_inverse=True)
    cols, c = np.unique(col, return_inverse=True)
    counts = np.bincount(g * cols.size + c, minlength=keys.size * cols.size)
    return counts.reshape(keys.size, cols.size), keys, cols


@dataclass
class Proposal:
    """The best split of one state: its groups (``keys``), columns, counts, halves and score."""

    state: int
    keys: np.ndarray
    cols: np.ndarray
    counts: np.ndarray
    side: np.ndarray
    score: float


def propose_split(inst: Instances, q: int, criterion) -> Proposal | None:
    """Ask ``criterion`` for the best split of state ``q``; ``None`` if it cannot be split."""
    sl = inst.of(q)
    if sl.stop - sl.start < 2:
        return None
    counts, keys, cols = group_counts(inst.key[sl], inst.col[sl])
    result = criterion.propose(counts)
    if result is None:
        return None
    side, score = result
    side = np.asarray(side, dtype=bool)
    if side.shape != (keys.size,) or side.all() or not side.any():
        return None
    return Proposal(q, keys, cols, counts, side, float(score))


def split_state(x: np.ndarray, u: np.ndarray, p: Proposal, new: int, n_states: int,
                n_actions: int, has_prev: np.ndarray, has_next: np.ndarray) -> np.ndarray:
    """Return a copy of ``x`` where the steps of ``p.state`` in the second half become ``new``.

    Which half keeps the old id: the one with more instances (ties: the half holding the smallest
    key).  Steps of the state that are not instance centres are placed as follows:

    * a step with a predecessor follows its key ``(x[t-1], u[t-1])`` when that key is one of the
      groups, and otherwise keeps the old id -- so every step's half is a function of its key
      alone, which guarantees that relabelled successors cannot raise ``H(x'|x,u)``;
    * the first step of an episode (no predecessor) goes to the half in which its column
      ``(u[t], x[t+1])`` is relatively more frequent (ties, unseen columns, one-step episodes: the
      old id).
    """
    side = p.side
    if p.counts[side].sum() > p.counts[~side].sum():
        side = ~side
    steps = np.flatnonzero(x == p.state)
    out = x.copy()
    with_prev = steps[has_prev[steps]]
    key = x[with_prev - 1] * n_actions + u[with_prev - 1]
    out[with_prev[np.isin(key, p.keys[side])]] = new
    starts = steps[~has_prev[steps] & has_next[steps]]
    if starts.size:
        halves = np.stack([p.counts[~side].sum(axis=0), p.counts[side].sum(axis=0)])
        freq = halves / np.maximum(halves.sum(axis=1, keepdims=True), 1)
        col = x[starts + 1] * n_actions + u[starts]
        pos = np.minimum(np.searchsorted(p.cols, col), p.cols.size - 1)
        known = p.cols[pos] == col
        goes = known & (freq[1, pos] > freq[0, pos])
        out[starts[goes]] = new
    return out
