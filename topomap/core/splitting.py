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

from .stats import conditional_entropy, count_tables, weighted_entropy, xlogx

__all__ = [
    "EntropyCriterion",
    "TargetStates",
    "MinGain",
    "CRITERIA",
    "merge_groups",
    "Instances",
    "build_instances",
    "Proposal",
    "propose_split",
    "split_state",
    "Splitter",
]

#: merge costs are rounded to this many decimals so that ties that are exact in real arithmetic
#: are exact in floating point too and are broken by index order, not by rounding noise
_TIE_DECIMALS = 9


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
    table = xlogx(np.arange(2 * int(work.sum()) + 1))  # 2x: a row is also paired with itself
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
    """Stop when the best split scores below ``min_gain`` (bits), or when the map reaches
    ``max_states`` states (None: three times the states phase 1 creates, so that a small
    ``min_gain`` cannot split a map into fragments without end)."""

    name = "min_gain"

    def __init__(self, min_gain: float = 0.05, max_states: int | None = None):
        if not np.isfinite(min_gain) or min_gain < 0:
            raise ValueError(f"stop.min_gain must be a finite number >= 0, got {min_gain!r}")
        if max_states is not None and (not isinstance(max_states, (int, np.integer)) or max_states < 1):
            raise ValueError(f"stop.max_states must be a positive integer or None, got {max_states!r}")
        self.min_gain = float(min_gain)
        self.max_states = None if max_states is None else int(max_states)
        self._limit = self.max_states

    def check(self, n_initial: int) -> None:
        if self.max_states is not None and self.max_states < n_initial:
            raise ValueError(
                f"stop.max_states={self.max_states} is below the {n_initial} states that phase 1 creates"
            )
        self._limit = self.max_states if self.max_states is not None else 3 * int(n_initial)

    def should_stop(self, n_states: int, best_score: float) -> bool:
        if self._limit is not None and n_states >= self._limit:
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


class Splitter:
    """The state of phase 2: the labelling, the states' origins and every state's best proposal.

    ``best()`` returns the best split (largest score; ties: smallest state id) or ``None`` when no
    state can be split; ``apply(proposal)`` performs it and returns its history record.  After a
    split only the states next to the relabelled steps are re-evaluated (``recompute_all``
    re-evaluates every state instead; the results are identical).
    """

    def __init__(self, labels, actions, n_actions: int, has_prev, has_next, *, symbol, gds,
                 obs_entropy, criterion, recompute_all: bool = False):
        self.labels = labels
        self.u, self.A = actions, int(n_actions)
        self.has_prev, self.has_next = has_prev, has_next
        self.symbol, self.gds = list(symbol), list(gds)
        self.parent = [-1] * len(self.symbol)
        self.obs_entropy = np.asarray(obs_entropy, dtype=np.float64)
        self.criterion = criterion
        self.recompute_all = recompute_all
        self._cache: dict[int, Proposal | None] = {}
        self._dirty = set(range(self.n_states))

    @property
    def n_states(self) -> int:
        return len(self.symbol)

    def best(self) -> Proposal | None:
        inst = build_instances(self.labels, self.u, self.n_states, self.A, self.has_prev,
                               self.has_next)
        for q in self._dirty:
            self._cache[q] = propose_split(inst, q, self.criterion) if self.gds[q] < 0 else None
        self._dirty = set()
        candidates = [p for p in self._cache.values() if p is not None]
        if not candidates:
            return None
        return max(candidates, key=lambda p: (p.score, -p.state))

    def apply(self, best: Proposal) -> dict:
        """Split ``best.state``: the steps of the moving half get a new state id."""
        q, new = best.state, self.n_states
        x = self.labels
        n_before = int(np.sum(x == q))
        x = self.labels = split_state(x, self.u, best, new, new, self.A, self.has_prev,
                                      self.has_next)
        # a state's instances change only where a neighbouring step was relabelled q -> new
        touched = np.flatnonzero(x == new)
        near = np.concatenate([touched, touched[self.has_prev[touched]] - 1,
                               touched[self.has_next[touched]] + 1])
        self.symbol.append(self.symbol[q])
        self.gds.append(-1)
        self.parent.append(q)
        self.obs_entropy = np.append(self.obs_entropy, self.obs_entropy[q])
        self._dirty = set(np.unique(x[near]).tolist()) | {q, new}
        if self.recompute_all:
            self._dirty = set(range(self.n_states))
        return {
            "state": int(q), "new_state": int(new), "gain": best.score, "n_steps": n_before,
            "n_steps_kept": int(np.sum(x == q)), "n_steps_new": int(np.sum(x == new)),
            "n_groups": int(best.keys.size),
        }

    def entropies(self) -> dict:
        """``H(o|x)``, ``H(u|x)``, ``H(x'|x,u)`` of the current labelling, from counts alone.

        Observation models are tied to symbols, so ``H(o|x)`` only needs each state's share and
        its model's entropy.
        """
        S, x = self.n_states, self.labels
        n, ac, tc = count_tables(x, self.u, S, self.A, self.has_next)
        return {"H_o": float(n @ self.obs_entropy / x.size), "H_u": conditional_entropy(ac),
                "H_x": conditional_entropy(tc.reshape(S * self.A, S))}
