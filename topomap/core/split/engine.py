"""Phase 2 (paper Section 3.3): split perceptually aliased states.

A *transition instance* at step ``t`` is ``(x[t-1], u[t-1], x[t], u[t], x[t+1])``; it exists only
when steps ``t-1`` and ``t+1`` lie in the same episode as ``t`` (so the first and last step of every
episode are never the centre of an instance).

For a state ``q`` its instances are grouped by the key ``(x[t-1], u[t-1])`` and counted by the
column ``(u[t], x[t+1])``: a (groups x columns) count matrix.  Keys and columns are encoded with
the action count ``A`` only (``key = x[t-1] * A + u[t-1]``, ``column = x[t+1] * A + u[t]``), so
they stay valid when the state count grows.  ``H(I) = H_I(u) + H_I(x'|u)`` is the entropy of the
joint distribution of ``(u, x')`` in ``I``, so everything the method needs follows from those
counts.

The work of a split is near-linear: :class:`SplitEngine` keeps every state's steps, its instance
table (the distinct ``(key, column)`` pairs with counts, as sorted codes ``key << 32 | column``),
the sparse transition counts and the state and action counts, and after a split touches only the
split state's steps and their neighbours -- a split of ``q`` relabels some steps of ``q`` only, so
an instance or a transition changes only where its centre or an end is such a step.  No
``S x A x S`` table is ever formed, and every number it reports is the same float the plain numpy
expressions over all instances give (see :mod:`topomap.core.sums`).

:class:`Splitter` asks a split criterion for every state's best split (``propose(counts) ->
(side, score)`` or ``None``; :mod:`topomap.core.split.criteria`) and performs the best; when to
stop is a stopping rule's call (:mod:`topomap.core.split.stopping`).  :func:`merge_groups`, the
paper's bottom-up merge, is shared by the entropy criterion and the refinement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .kernels import (action_table, centre_pairs, follow_keys, merge_tallies, split_table,
                      tally_codes, tally_pairs, touched_codes, transition_table)
from .threads import beside, in_threads
from .merge_kernels import (count_matrix_kernel, count_range, gain_kernel, merge_gain_kernel,
                            merge_groups_kernel)
from ..stats import conditional_entropy, sparse_conditional_entropy, xlogx

__all__ = ["merge_groups", "entropy_gain", "merge_and_gain", "Proposal", "SplitEngine",
           "Splitter"]

#: merge costs are rounded to this many decimals so that ties that are exact in real arithmetic
#: are exact in floating point too and are broken by index order, not by rounding noise
_TIE_DECIMALS = 9
_SHIFT = np.int64(32)


class _XlogxTable:
    """``c * log2(max(c, 1))`` for c = 0, 1, 2, ... computed by numpy once and grown on demand.

    numpy's ``log2`` gives the same bits for a value wherever it sits in an array, so a long table
    holds exactly the entries a table computed for each call would hold.
    """

    def __init__(self):
        self.values = xlogx(np.arange(1024))

    def upto(self, top: int) -> np.ndarray:
        """A table reaching ``top`` (threads may ask at once: each gets one long enough)."""
        values = self.values
        if top >= values.size:
            values = xlogx(np.arange(max(top + 1, 2 * values.size)))
            if values.size > self.values.size:
                self.values = values
        return values


_TABLE = _XlogxTable()


def merge_groups(counts: np.ndarray) -> np.ndarray:
    """Agglomerate the rows of an integer count matrix into two clusters, each time merging the
    pair whose union increases the weighted entropy ``n H`` least (costs rounded to 1e-9 bits;
    ties: smallest indices).  Compiled (:func:`topomap.core.split.merge_kernels.merge_groups_kernel`).

    Returns a boolean array: False for the rows in the cluster holding row 0, True for the others.
    """
    work = np.ascontiguousarray(counts, dtype=np.int64)
    if np.any(work < 0):
        raise ValueError("counts must be non-negative")
    if work.shape[0] < 2:
        return np.zeros(work.shape[0], dtype=bool)
    table = _TABLE.upto(2 * int(work.sum()))  # 2x: a row is also paired with itself
    return merge_groups_kernel(work, table, _TIE_DECIMALS)


def entropy_gain(counts: np.ndarray, side: np.ndarray) -> float:
    """``(W(I) - W(I') - W(I'')) / |I|`` for the rows of an integer count matrix cut into
    ``side`` False (``I'``) and True (``I''``), ``W`` the weighted entropy ``n H`` of the summed
    rows: the same float as :func:`topomap.core.stats.weighted_entropy` over the two halves'
    sums gives (compiled, :func:`topomap.core.split.merge_kernels.gain_kernel`).  Not clipped at 0."""
    work = np.ascontiguousarray(counts, dtype=np.int64)
    total = int(work.sum())
    if total == 0:
        return float("nan")  # 0 / 0, as numpy gives it
    table = _TABLE.upto(total)
    return gain_kernel(work, np.ascontiguousarray(side, dtype=np.bool_), table)


def merge_and_gain(counts: np.ndarray):
    """``(side, gain)``: :func:`merge_groups` and :func:`entropy_gain` of its halves, the same
    arrays and floats, in one compiled call (the paper's split of one state); ``None`` below two
    rows."""
    work = np.ascontiguousarray(counts, dtype=np.int64)
    if work.ndim != 2 or work.shape[0] < 2:
        return None
    low, total = count_range(work)
    if low < 0:
        raise ValueError("counts must be non-negative")
    if total == 0:
        return merge_groups(work), float("nan")
    return merge_gain_kernel(work, _TABLE.upto(2 * total), _TIE_DECIMALS)


@dataclass
class Proposal:
    """The best split of one state: its groups (``keys``), columns, counts, halves and score."""

    state: int
    keys: np.ndarray
    cols: np.ndarray
    counts: np.ndarray
    side: np.ndarray
    score: float


def group_steps(labels, n_states, dtype=np.int64):
    """Counting sort of steps by state: ``(order, bounds)`` with the steps of state ``s`` in
    increasing order at ``order[bounds[s]:bounds[s + 1]]`` (``order`` of ``dtype``)."""
    order = np.empty(labels.size, dtype=dtype)
    return order, _group_steps(labels, n_states, order)


@njit(cache=True)
def _group_steps(labels, n_states, order):
    bounds = np.zeros(n_states + 1, dtype=np.int64)
    for s in labels:
        bounds[s + 1] += 1
    for s in range(n_states):
        bounds[s + 1] += bounds[s]
    fill = bounds[:-1].copy()
    for t in range(labels.size):
        order[fill[labels[t]]] = t
        fill[labels[t]] += 1
    return bounds


@njit(cache=True, nogil=True)
def members_of(labels, n_states, like):
    """The steps of every state, each state's in increasing order in an array of its own (of
    ``like``'s dtype): a counting sort without a (T,) order array."""
    counts = np.zeros(n_states, dtype=np.int64)
    for s in labels:
        counts[s] += 1
    out = [np.empty(counts[s], dtype=like.dtype) for s in range(n_states)]
    fill = np.zeros(n_states, dtype=np.int64)
    for t in range(labels.size):
        s = labels[t]
        out[s][fill[s]] = t
        fill[s] += 1
    return out


def _compact_dtype(top: int, dtypes) -> type:
    """The first of ``dtypes`` (narrow to wide) that holds ``0 .. top``; int64 past them.  The
    split reads the labels and actions of scattered steps: at 2 and 1 bytes a step instead of 8
    (10^7 steps, 100 -> 200 states: 30 MB instead of 160 MB, under the 32 MB last-level cache
    measured) its 100 splits took 2.01 s CPU instead of 2.43 s (medians of 4, the same labels)."""
    for dtype in dtypes:
        if top <= np.iinfo(dtype).max:
            return dtype
    return np.int64


def _merge_delta(table, old, new, size):
    """The sorted sparse table ``(codes, counts)`` with one count moved from each code of
    ``old`` to the code of ``new`` at the same place (codes' keys and columns below ``size``);
    entries that reach zero are dropped.  O(table + delta + size)."""
    return merge_tallies(*table, *tally_codes(old, size), *tally_codes(new, size))


class SplitEngine:
    """Transition instances and counts of a labelling, updated in place split by split.

    Parameters: ``labels`` (T,) int (copied), ``actions`` (T,) int, ``n_states``, ``n_actions``,
    ``has_prev`` / ``has_next`` from :func:`topomap.core.stats.episode_masks`.
    Attributes: ``labels`` (T,) a copy as int16 while the states fit it (int32, int64 past
    that; widened when the states outgrow it), ``u`` a copy as int8 while the actions fit it
    (int16, int32, int64 past that), ``members[s]`` sorted
    steps of state ``s`` (int32 below 2**31 steps),
    ``state_counts`` (S,), ``action_counts`` (S, A), ``near`` (S,) the states next to the last
    split's moved steps.
    """

    def __init__(self, labels, actions, n_states, n_actions, has_prev, has_next):
        self.labels = np.array(labels, dtype=_compact_dtype(n_states, (np.int16, np.int32)))
        self.u = np.asarray(actions, dtype=_compact_dtype(n_actions - 1,
                                                           (np.int8, np.int16, np.int32)))
        self.S, self.A = int(n_states), int(n_actions)
        self.has_prev, self.has_next = has_prev, has_next
        self.centre = has_prev & has_next
        # every state's instance table from one pass in step order (pairs as int32 when they fit)
        size = (self.S + 1) * self.A
        bits = size.bit_length()
        pairs = np.empty(int(np.count_nonzero(self.centre)),
                         dtype=np.int32 if 2 * bits < 32 else np.int64)
        bounds = centre_pairs(self.labels, self.u, self.centre, self.S, self.A, bits, pairs)
        self.tables = [tally_pairs(pairs[bounds[s]:bounds[s + 1]], bits, size)
                       for s in range(self.S)]
        del pairs  # before the steps are sorted by state: the two never take memory at once
        # each state's steps in an array of its own (views of one array would keep all of it
        # alive as states split), as int32 while every step index fits
        like = np.empty(0, dtype=np.int32 if self.labels.size < 2**31 else np.int64)
        self.members = list(members_of(self.labels, self.S, like))
        self.state_counts = np.array([m.size for m in self.members], dtype=np.int64)
        self.action_counts = action_table(self.labels, self.u, self.S, self.A)
        self.transitions = transition_table(self.labels, self.u, np.asarray(has_next, dtype=bool),
                                            self.S, self.A)
        self.near = np.zeros(self.S, dtype=bool)  # the states next to the last split's steps

    def count_tables(self):
        """``(state_counts (S,), action_counts (S, A), transition_counts (S, A, S))`` of the
        current labelling from the tables kept (new arrays): what
        :func:`topomap.core.stats.count_tables` counts over the steps."""
        S, A = self.S, self.A
        trans = np.zeros((S * A, S), dtype=np.int64)
        codes, counts = self.transitions
        trans[codes >> _SHIFT, codes & 0xFFFFFFFF] = counts
        return self.state_counts.copy(), self.action_counts.copy(), trans.reshape(S, A, S)

    # ------------------------------------------------------------------ proposals
    def count_matrix(self, q: int):
        """``(counts, keys, cols)`` of state ``q``: the (groups x columns) count matrix of its
        instances, with its sorted group keys and columns."""
        return count_matrix_kernel(*self.tables[q], self.S * self.A)

    def propose(self, q: int, criterion) -> Proposal | None:
        """Ask ``criterion`` for the best split of state ``q``; None if it cannot be split."""
        if self.tables[q][1].sum() < 2:
            return None
        counts, keys, cols = self.count_matrix(q)
        result = criterion.propose(counts)
        if result is None:
            return None
        side, score = result
        side = np.asarray(side, dtype=bool)
        if side.shape != (keys.size,) or side.all() or not side.any():
            return None
        return Proposal(q, keys, cols, counts, side, float(score))

    # ------------------------------------------------------------------ splits
    def moving_steps(self, p: Proposal) -> np.ndarray:
        """Mask over ``members[p.state]``: the steps that go to the new state.

        Which half keeps the old id: the one with more instances (ties: the half holding the smallest
        key).  Steps of the state that are not instance centres are placed as follows:

        * a step with a predecessor follows its key ``(x[t-1], u[t-1])`` when that key is one of the
          groups, and otherwise keeps the old id -- so every step's half is a function of its key
          alone, which guarantees that relabelled successors cannot raise ``H(x'|x,u)``;
        * the first step of an episode (no predecessor) goes to the half in which its column
          ``(u[t], x[t+1])`` is relatively more frequent (ties, unseen columns, one-step episodes: the
          old id).
        """
        return self._moving(p)[0]

    def _moving(self, p: Proposal):
        """:meth:`moving_steps` and the mask over the keys that go (every instance centre of the
        state goes with its key)."""
        x, u, A = self.labels, self.u, self.A
        side = p.side
        if p.counts[side].sum() > p.counts[~side].sum():
            side = ~side
        steps = self.members[p.state]
        chosen = np.zeros(self.S * A, dtype=bool)
        chosen[p.keys[side]] = True
        goes, is_start = follow_keys(x, u, steps, self.has_prev, self.has_next, A, chosen)
        if is_start.size:
            starts = steps[is_start]
            halves = np.stack([p.counts[~side].sum(axis=0), p.counts[side].sum(axis=0)])
            freq = halves / np.maximum(halves.sum(axis=1, keepdims=True), 1)
            col = x[starts + 1].astype(np.int64) * A + u[starts]
            pos = np.minimum(np.searchsorted(p.cols, col), p.cols.size - 1)
            goes[is_start] = (p.cols[pos] == col) & (freq[1, pos] > freq[0, pos])
        return goes, chosen

    def split(self, p: Proposal, new: int) -> np.ndarray:
        """Split ``p.state``: its moving steps become state ``new`` (= the current state count).
        Returns the moved steps (sorted); ``near`` is then the mask over the states (the new one
        included) of those holding a step next to a moved one, apart from the split state and
        the new one.

        Only the steps next to the moved ones are looked at again
        (:func:`~topomap.core.split.kernels.touched_codes`): the instances and transitions they
        centre or start move from their codes before to their codes after; the split state's
        table is cut in two by the keys that go (an instance centre goes with its key), with the
        instances inside it next to a moved step moved the same way."""
        q = p.state
        goes, chosen = self._moving(p)
        steps = self.members[q]
        moved = steps[goes]
        if new > np.iinfo(self.labels.dtype).max:  # the states outgrow a compact type
            self.labels = self.labels.astype(np.int32 if new < 2**31 else np.int64)
        self.labels[moved] = new
        outside, inside, starts, self.near = touched_codes(
            moved, self.has_prev, self.has_next, self.centre, self.labels, self.u, self.A, _SHIFT,
            q, new)
        size = (self.S + 1) * self.A
        # the transitions need nothing of the instance tables: merged beside them (on long logs)
        transitions = beside(_merge_delta, self.transitions, starts[0], starts[1], size,
                             steps=self.labels.size)
        self._update_instances(*outside[1:])
        self.members[q] = steps[~goes]
        self.members.append(moved)
        halves = split_table(*self.tables[q], chosen, _SHIFT)
        went = inside[2] == 1
        self.tables[q] = _merge_delta(halves[0], inside[0][~went], inside[1][~went], size)
        self.tables.append(_merge_delta(halves[1], inside[0][went], inside[1][went], size))
        self.transitions = transitions()
        self._update_counts(q, moved)
        return moved

    def _update_instances(self, states, old, new):
        """Move instances (all outside the split state) from ``old`` codes to ``new`` codes in
        the tables of their ``states``."""
        order, bounds = group_steps(states, self.S + 1)
        for s in np.flatnonzero(np.diff(bounds)):
            pick = order[bounds[s]:bounds[s + 1]]
            self.tables[s] = _merge_delta(self.tables[s], old[pick], new[pick],
                                          (self.S + 1) * self.A)

    def _update_counts(self, q, moved):
        acts = np.bincount(self.u[moved], minlength=self.A)
        self.action_counts[q] -= acts
        self.action_counts = np.vstack([self.action_counts, acts[None]])
        self.state_counts[q] -= moved.size
        self.state_counts = np.append(self.state_counts, moved.size)
        self.S += 1

    def release(self) -> None:
        """Drop the steps, actions and instance tables of every state (no split follows); the
        labels and counts stay."""
        self.members = self.tables = self.u = None
        self.centre = self.has_prev = self.has_next = None

    # ------------------------------------------------------------------ entropies
    def entropies(self, h_state: np.ndarray) -> dict:
        """``H_o``, ``H_u``, ``H_x`` of the current labelling from the counts alone (``h_state``:
        each state's observation-model entropy; models are tied to symbols)."""
        n, S, A = self.state_counts, self.S, self.A
        return {"H_o": float(n @ h_state / self.labels.size),
                "H_u": conditional_entropy(self.action_counts),
                "H_x": sparse_conditional_entropy(*self.transitions, (S * A, S))}


class Splitter:
    """The state of phase 2: the engine, the states' origins and every state's best proposal.

    ``best()`` returns the best split (largest score; ties: smallest state id) or ``None`` when no
    state can be split; ``apply(proposal)`` performs it and returns its history record.  After a
    split only the states next to the moved steps are re-evaluated (``recompute_all`` re-evaluates
    every state instead; the results are identical).  ``labels`` is the engine's working array,
    updated in place by every split.
    """

    def __init__(self, labels, actions, n_actions: int, has_prev, has_next, *, symbol, gds,
                 obs_entropy, criterion, recompute_all: bool = False):
        self.symbol, self.gds = list(symbol), list(gds)
        self.parent = [-1] * len(self.symbol)
        self.engine = SplitEngine(labels, actions, len(self.symbol), n_actions, has_prev, has_next)
        self.has_prev, self.has_next = has_prev, has_next
        self.obs_entropy = np.asarray(obs_entropy, dtype=np.float64)
        self.criterion = criterion
        self.recompute_all = recompute_all
        self._cache: dict[int, Proposal | None] = {}
        self._dirty = set(range(self.n_states))

    @property
    def n_states(self) -> int:
        return len(self.symbol)

    @property
    def labels(self) -> np.ndarray:
        return self.engine.labels

    def best(self) -> Proposal | None:
        asked = sorted(q for q in self._dirty if self.gds[q] < 0)
        self._cache.update({q: None for q in self._dirty})
        # a criterion whose ``propose`` may run on several threads at once (``concurrent``)
        # proposes on threads where the states hold enough instances
        steps = sum(int(self.engine.tables[q][1].sum()) for q in asked) \
            if getattr(self.criterion, "concurrent", False) else 0
        self._cache.update(zip(asked, in_threads(
            lambda q: self.engine.propose(q, self.criterion), asked, steps=steps)))
        self._dirty = set()
        candidates = [p for p in self._cache.values() if p is not None]
        if not candidates:
            return None
        return max(candidates, key=lambda p: (p.score, -p.state))

    def apply(self, best: Proposal) -> dict:
        """Split ``best.state``: the steps of the moving half get a new state id."""
        q, new = best.state, self.n_states
        n_before = int(self.engine.members[q].size)
        moved = self.engine.split(best, new)
        self.symbol.append(self.symbol[q])
        self.gds.append(-1)
        self.parent.append(q)
        self.obs_entropy = np.append(self.obs_entropy, self.obs_entropy[q])
        # a state's instances change only where a neighbouring step moved q -> new
        self._dirty = set(np.flatnonzero(self.engine.near).tolist()) | {q, new}
        if self.recompute_all:
            self._dirty = set(range(self.n_states))
        return {
            "state": int(q), "new_state": int(new), "gain": best.score, "n_steps": n_before,
            "n_steps_kept": int(self.engine.members[q].size), "n_steps_new": int(moved.size),
            "n_groups": int(best.keys.size),
        }

    def count_tables(self):
        """The labelling's ``(state_counts, action_counts, transition_counts)`` from the
        engine's tables (:meth:`SplitEngine.count_tables`)."""
        return self.engine.count_tables()

    def roots(self) -> np.ndarray:
        """The phase-1 state every state descends from (a state of phase 1 is its own)."""
        root = np.arange(self.n_states)
        for s, p in enumerate(self.parent):
            if p >= 0:
                root[s] = root[p]
        return root

    def finish(self, widen: bool = False) -> None:
        """The splits are over: free what only further splits need (every state's steps);
        ``widen``: keep the labels as int64 from now on (in place of the compact copy)."""
        self.engine.release()
        if widen:
            self.engine.labels = self.engine.labels.astype(np.int64)
        self._cache, self._dirty = {}, set()
        self.has_prev = self.has_next = None

    def entropies(self) -> dict:
        """``H(o|x)``, ``H(u|x)``, ``H(x'|x,u)`` of the current labelling, from counts alone."""
        return self.engine.entropies(self.obs_entropy)
