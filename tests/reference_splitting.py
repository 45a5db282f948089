"""The plain-numpy phase 2 that :mod:`topomap.core.split.engine` replaced: every split rebuilds all
transition instances.  Kept as the reference the incremental engine and the compiled merge are
checked against (same proposals, same labels, same floats)."""

from dataclasses import dataclass

import numpy as np

from topomap.core.split.criteria import EntropyCriterion
from topomap.core.split.engine import Proposal
from topomap.core.stats import episode_masks, xlogx

_TIE_DECIMALS = 9


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


def splits(labels, u, S, A, lengths, n_splits):
    """The numpy phase 2: rebuild every instance, propose every state, split the best."""
    has_prev, has_next = episode_masks(len(u), lengths)
    x, history, crit = labels.copy(), [], EntropyCriterion()
    for _ in range(n_splits):
        inst = build_instances(x, u, S, A, has_prev, has_next)
        props = [p for q in range(S) if (p := propose_split(inst, q, crit)) is not None]
        if not props:
            break
        best = max(props, key=lambda p: (p.score, -p.state))
        x = split_state(x, u, best, S, S, A, has_prev, has_next)
        history.append((best.state, best.score, x.copy()))
        S += 1
    return history
