"""Learning while the steps arrive: what :meth:`MapLearner.partial_fit` keeps between calls.

The map is learned from a stream of chunks, at a cost per chunk that does not grow with the steps
seen before it:

* **Symbols.** While the window still holds every step seen, every pass runs phase 1's K-means
  on all of them (a walk no longer than the window is learned as :meth:`MapLearner.fit` learns
  it).  Once steps have left the window, the symbols of the last such pass are fixed (a
  :class:`Codebook` of the symbols' mean observations), and a new step takes the symbol of the
  nearest mean: for the Euclidean metric (the paper's) this is K-means' own assignment.  Symbols
  are then fixed rather than updated (``MiniBatchKMeans.partial_fit``) because every state,
  count and label is defined on them: moving a centre would silently change the symbol of steps
  already counted.  A count asked for above the distinct observations of a pass's window is
  capped at them, and the codebook grows as new views appear
  (:mod:`topomap.core.online_codebook`).
* **Every chunk** is decoded with the current map (Viterbi over the chunk's symbols and actions,
  continuing from the last steps before it) and its transitions are added to the map's count
  tables: only the rows of the states the chunk visits change.
* **A wider pass** re-learns the map's structure -- the split, the refinement, ``stop=auto``'s
  size choice: the learner's fit with the codebook's symbols -- on a bounded window of the
  latest ``window`` steps.  It runs on the first call, then whenever the steps since the last
  pass reach ``refit_every`` or the steps the map was last learned from (so passes come at
  doubling sizes early on; with ``refine="em"``, none between half the window and the full
  window, :meth:`OnlineState.interval`), and at once when a chunk brings a GDS id, an action or a
  symbol the map does not know, or a call declares more actions (``n_actions``) than the map
  has.
* **A warm start** (:mod:`topomap.core.online_pass`).  With ``refine="em"``, a pass on a window
  that has lost steps starts EM from the last map (the states its steps hold, the call's new
  steps decoded with it first) instead of from the split, which it does not make, and runs a
  few short rounds on all steps: most of EM's work is done already.  While the window holds
  every step, K-means runs again and its symbols change, so those passes start afresh, as
  ``fit`` does.  A pass afresh on fewer than two steps per state of its split keeps the
  split (any refinement).

**Labels.** Every step's label is kept in the :class:`StepRecord` (``labels_`` is a view of it),
always a state of the current map (or -1): a chunk's steps get the states they are decoded to; a
pass gives the window's steps the states of its fit, decodes with the new map the steps that
left the window since the pass before, and translates the labels of the steps before them from
the last map's states to the new map's (each old state to the new state most of its steps since
the last pass now hold; -1 if none of them has one): one integer lookup per step, once per pass,
the only part of a call whose cost grows with the steps seen.

Memory kept: the window (``window`` rows of observations, actions, GDS ids) and the map's tables,
bounded by the world, not by the steps; and, per step seen, five int32 in the record: its symbol,
action and GDS id, whether an episode starts there, and its label, so O(T) small integers.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .online_codebook import Codebook
from .refine.clones import decode, make_layout
from .stats import majority_match

__all__ = ["StepRecord", "Window", "Codebook", "OnlineState", "decode_symbols", "lengths_of"]

#: steps before a chunk decoded with it, so a chunk's first states are not guessed blind
CONTEXT = 16
#: the share of a count every unseen transition gets when a chunk is decoded
PSEUDOCOUNT = 1e-3


class StepRecord:
    """Five int32 values for every step seen -- its symbol (-1 at a GDS), action, GDS id,
    episode start (1 or 0) and label -- in one array grown by doubling, so :attr:`labels` is a
    view of every step's label, not a copy."""

    def __init__(self):
        self._rows = np.empty((5, 1024), dtype=np.int32)
        self.size = 0

    def append(self, sym, act, gds, start) -> None:
        """Record a chunk's steps (their labels -1 until they are decoded)."""
        n = self.size + len(act)
        if n > self._rows.shape[1]:
            grown = np.empty((5, max(n, 2 * self._rows.shape[1])), np.int32)
            grown[:, :self.size] = self._rows[:, :self.size]
            self._rows = grown
        self._rows[:, self.size:n] = [sym, act, gds, start, np.full(len(act), -1)]
        self.size = n

    def _field(self, i: int) -> np.ndarray:
        return self._rows[i, :self.size]

    sym = property(lambda self: self._field(0), doc="the symbol of every step (-1 at a GDS)")
    act = property(lambda self: self._field(1), doc="the action of every step")
    gds = property(lambda self: self._field(2), doc="the GDS id of every step (-1: none)")
    start = property(lambda self: self._field(3), doc="1 where an episode starts, else 0")
    labels = property(lambda self: self._field(4), doc="the label of every step (-1: none)")

    @property
    def nbytes(self) -> int:
        return int(self._rows.nbytes)


@dataclass
class Window:
    """The latest ``capacity`` steps: observations, actions, GDS ids, episode starts and the
    absolute index of the first one.  Chunks are kept as they came and dropped from the front."""

    capacity: int
    chunks: list = field(default_factory=list)
    size: int = 0
    first: int = 0

    def push(self, X, u, g, starts) -> None:
        self.chunks.append((X.copy(), u.copy(), g.copy(), starts.copy()))
        self.size += X.shape[0]
        while self.size - self.chunks[0][0].shape[0] >= self.capacity:
            dropped = self.chunks.pop(0)[0].shape[0]
            self.size -= dropped
            self.first += dropped

    def arrays(self):
        """``(X, u, gds, starts, first)`` of the last ``capacity`` steps (the oldest chunk
        trimmed), ``first`` the index of their first step; that step always starts an episode."""
        X, u, g, s = (np.concatenate([c[i] for c in self.chunks]) for i in range(4))
        cut = max(0, X.shape[0] - self.capacity)
        X, u, g, s = X[cut:], u[cut:], g[cut:], s[cut:].copy()
        s[0] = True
        return X, u, g, s, self.first + cut

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for c in self.chunks for a in c))


def lengths_of(starts: np.ndarray) -> np.ndarray:
    """Episode lengths of a run of steps from its episode-start flags (the first step starts)."""
    first = np.flatnonzero(starts)
    return np.diff(np.concatenate([first, [starts.size]])).astype(np.int64)


def decode_symbols(ids, u, starts, state_id, transitions, n_ids: int):
    """The most likely state of every step of a sequence of symbol ids under a map.

    ``ids`` (T,) are the steps' symbol ids (K-means symbols, then one id per GDS), ``state_id``
    (S,) the id every state emits and ``transitions`` (S, A, S) the map's transition counts; a
    state emits its id only, so a step can be in the states of its id alone (Viterbi over the
    clone layout of :mod:`topomap.core.refine.clones`).  Steps whose id no state emits, or whose
    action the map does not have, get -1 and cut the sequence there.  Returns (T,) int64.
    """
    ids = np.asarray(ids, dtype=np.int64)
    u = np.asarray(u, dtype=np.int64)
    A = transitions.shape[1]
    per = np.bincount(state_id, minlength=n_ids)
    known = (ids < n_ids) & (ids >= 0)
    known[known] = per[ids[known]] > 0
    labels = np.full(ids.size, -1, dtype=np.int64)
    if not known.any():
        return labels
    keep = np.flatnonzero(known)
    sub_starts = np.asarray(starts, dtype=bool)[keep].copy()
    sub_starts[0] = True
    sub_starts[1:] |= np.diff(keep) > 1          # a step left out cuts the sequence
    bad_action = u[keep] >= A
    sub_starts[1:] |= bad_action[:-1]            # so does an action the map lacks
    sub_u = np.where(bad_action, 0, u[keep])
    order = np.argsort(state_id, kind="stable")  # clone c of id k is state order[start[k] + c]
    lay = make_layout(ids[keep], sub_u, lengths_of(sub_starts), per, A)
    counts = _block_counts(lay, order, transitions)
    path, _ = decode(lay, counts, PSEUDOCOUNT, joint=False)
    labels[keep] = order[path]
    return labels


def _block_counts(lay, order, transitions) -> np.ndarray:
    """The map's transition counts placed in the blocks of ``lay`` (one per observed
    ``(action, id, next id)``): entry ``(i, j)`` of block ``(a, k, k')`` is
    ``transitions[i-th state of k, a, j-th state of k']``."""
    counts = np.empty(int(lay.boff[-1]))
    start = lay.start
    for b, (a, k, k2) in enumerate(lay.triples):
        rows = order[start[k]:start[k + 1]]
        cols = order[start[k2]:start[k2 + 1]]
        counts[lay.boff[b]:lay.boff[b + 1]] = transitions[np.ix_(rows, [a], cols)].ravel()
    return counts


@dataclass
class OnlineState:
    """What ``partial_fit`` keeps between calls (see the module docstring): the window, the
    record, the codebook, the symbol id every state of the map emits, and the pass schedule."""

    window: Window
    record: StepRecord = field(default_factory=StepRecord)
    n_actions: int = 0
    action_names: list | None = None
    gds_names: list | None = None
    codebook: Codebook | None = None
    gds_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    state_id: np.ndarray | None = None         # (S,) the symbol id every state of the map emits
    n_ids: int = 0                             # symbol ids: K-means symbols, then known GDS ids
    map_symbols: int = 0                       # the codebook's symbols when the map was learned
    clusters: dict = field(default_factory=dict)  # a capped count (:meth:`summary`)
    pass_first: int = 0                        # first step of the last pass's window
    pass_steps: int = 0                        # steps seen at the last pass
    n_calls: int = 0
    n_passes: int = 0
    last_work: dict = field(default_factory=dict)

    @property
    def n_steps(self) -> int:
        return self.record.size

    def snapshot(self):
        """What :meth:`restore` brings back when a call fails."""
        w = self.window
        return (list(w.chunks), w.size, w.first, self.record.size, self.n_actions,
                self.action_names, self.gds_names, self.codebook, self.state_id, self.n_ids,
                dict(self.clusters))

    def restore(self, saved) -> None:
        w = self.window
        (w.chunks, w.size, w.first, self.record.size, self.n_actions, self.action_names,
         self.gds_names, self.codebook, self.state_id, self.n_ids, self.clusters) = saved

    def take(self, X, u, g, starts, n_actions, action_names, gds_names) -> None:
        """Record a chunk (its steps' symbols: the codebook's) and the names and action count
        the call gives (``n_actions`` may grow on any call, never shrink)."""
        if self.codebook is not None and X.shape[1] != self.codebook.means.shape[1]:
            raise ValueError(f"observations have {X.shape[1]} features but the earlier steps "
                             f"had {self.codebook.means.shape[1]}")
        if n_actions is not None and int(n_actions) < max(self.n_actions, int(u.max()) + 1):
            raise ValueError(f"n_actions is {int(n_actions)} but the steps use "
                             f"{max(self.n_actions, int(u.max()) + 1)} actions")
        self.action_names = self.action_names if action_names is None else action_names
        self.gds_names = self.gds_names if gds_names is None else gds_names
        sym = np.full(X.shape[0], -1, dtype=np.int64)
        plain = g < 0
        if self.codebook is not None and plain.any():
            sym[plain] = self.assign(X[plain])
        self.window.push(X, u, g, starts)
        self.record.append(sym, u, g, starts)
        names = 0 if self.action_names is None else len(self.action_names)
        self.n_actions = max(self.n_actions, int(u.max()) + 1, int(n_actions or 0), names)

    def assign(self, X) -> np.ndarray:
        """The codebook's symbols of the rows ``X`` (:meth:`Codebook.assign
        <topomap.core.online_codebook.Codebook.assign>`: a new view may get a new symbol, which
        no state of the map emits yet; the GDS ids after the symbols move up with it)."""
        sym, grown = self.codebook.assign(X)
        added = grown.size - self.codebook.size
        if added and self.state_id is not None:
            self.state_id = np.where(self.state_id >= self.codebook.size, self.state_id + added,
                                     self.state_id)
            self.n_ids += added
        self.codebook = grown
        if self.clusters:
            self.clusters["symbols"] = grown.size
        return sym

    def ids(self, sym, g) -> np.ndarray:
        """Symbol ids of steps: K-means symbols, then ``K + i`` for the ``i``-th known GDS id
        (-1 for a GDS id the map does not know)."""
        out = np.asarray(sym, dtype=np.int64).copy()
        g = np.asarray(g)
        is_g = g >= 0
        if is_g.any():
            pos = np.minimum(np.searchsorted(self.gds_ids, g[is_g]), max(self.gds_ids.size - 1, 0))
            ok = (self.gds_ids[pos] == g[is_g]) if self.gds_ids.size else np.zeros(pos.size, bool)
            out[is_g] = np.where(ok, self.codebook.size + pos, -1)
        return out

    def needs_pass(self, m, every: int, grow: bool = False) -> bool:
        """A pass is due: no map yet, :meth:`interval` new steps, more actions than the map
        has, or a GDS id or symbol the map does not know (a view that got a new symbol since
        the map was learned waits for the next pass: its steps are labelled -1 until then)."""
        if self.codebook is None or self.state_id is None or m is None:
            return True
        if self.n_steps - self.pass_steps >= self.interval(every, grow):
            return True
        if self.n_actions > m.n_actions:
            return True
        since = slice(self.pass_steps, self.n_steps)
        ids = self.ids(self.record.sym[since], self.record.gds[since])
        per = np.bincount(self.state_id, minlength=self.n_ids)
        new_view = (ids >= self.map_symbols) & (ids < self.codebook.size)
        return bool((ids < 0).any() or ((per[ids] == 0) & ~new_view).any())

    def interval(self, every: int, grow: bool = False) -> int:
        """New steps after which the next pass comes: as many as the last pass saw, at most
        ``every`` (passes at doubling sizes early on, then every ``every`` steps).  With
        ``grow`` (a refinement that starts later passes from the last map:
        :func:`~topomap.core.online_pass.warm_starts`), once a pass that saw every step saw
        at least half the window, the next comes when the window is full: such passes run
        K-means and the refinement afresh on every step, and cost the more the more steps."""
        cap = self.window.capacity
        if grow and self.pass_first == 0 and cap <= 2 * self.pass_steps < 2 * cap:
            return cap - self.pass_steps
        return min(every, max(self.pass_steps, 1))

    def window_symbols(self, first: int, plain: np.ndarray):
        """``(symbols, present)`` a pass fits the window from ``first`` on with: the codebook's
        symbols of its non-GDS steps (``plain``), renumbered ``0..`` over the symbols
        ``present`` in it; ``(None, None)`` while the window holds every step seen (K-means
        runs again)."""
        if self.codebook is None or first == 0:
            return None, None
        sym = self.record.sym[first:].astype(np.int64)[plain]
        present = np.unique(sym)
        return np.searchsorted(present, sym), present

    def learn_codebook(self, X_call, Xw, plain, symbols, K: int, first: int,
                       limit: int = 0) -> None:
        """The codebook of a pass that ran K-means on the window (``symbols`` of its ``plain``
        steps; ``limit``: the count asked for, when the pass capped it at the window's ``K``
        views); the window's steps take those symbols, and the steps before it (all in the
        call's ``X_call``, at the first call) the codebook's (:meth:`assign`)."""
        self.codebook = Codebook.from_symbols(Xw[plain], symbols, K, limit)
        self.record.sym[first:][plain] = symbols
        if first > 0:
            old = np.flatnonzero(self.record.gds[:first] < 0)
            self.record.sym[old] = self.assign(X_call[old])

    def after_pass(self, m, labels, gw, first: int, present) -> None:
        """Bind the state to the map ``m`` a pass learned from the window (from step ``first``,
        GDS ids ``gw``, its steps' ``labels``) and relabel every step with ``m``'s states: the
        window's steps get ``labels``, the steps that left the window since the last pass are
        decoded with ``m``, and the steps before them are translated from the last map's states
        (each to the state of ``m`` most of its steps since the last pass now hold)."""
        n_old = 0 if self.state_id is None else self.state_id.size
        self.gds_ids = np.unique(gw[gw >= 0]).astype(np.int64)
        K = self.codebook.size
        present = np.arange(K) if present is None else present
        self.n_ids = K + self.gds_ids.size
        self.map_symbols = K
        self.state_id = np.where(m.state_gds >= 0, K + np.searchsorted(self.gds_ids, m.state_gds),
                                 present[np.maximum(m.state_symbol, 0)]).astype(np.int64)
        rec, since = self.record, slice(self.pass_first, self.pass_steps)
        before = rec.labels[since].copy()  # the last map's states
        left = slice(self.pass_first, first)
        rec.labels[first:] = labels
        rec.labels[left] = decode_symbols(self.ids(rec.sym[left], rec.gds[left]), rec.act[left],
                                          rec.start[left].astype(bool), self.state_id,
                                          m.transition_counts, self.n_ids)
        old = rec.labels[:self.pass_first]
        if old.size:  # new state of every old state, and -1 (at index -1) for -1
            match = np.append(majority_match(before, rec.labels[since], n_old, m.n_states), -1)
            np.take(match.astype(np.int32), old, out=old)
        self.last_work = {"decoded": first - self.pass_first, "pass": int(gw.size),
                          "relabelled": int(old.size)}
        self.pass_first, self.pass_steps = first, self.n_steps
        self.n_passes += 1

    def _decode_last(self, m, n: int) -> int:
        """Label the last ``n`` steps with the states of ``m`` (decoded after up to
        :data:`CONTEXT` steps before them); returns the first step decoded."""
        rec, total = self.record, self.n_steps
        lo = max(self.pass_first, total - n - CONTEXT)
        sl = slice(lo, total)
        path = decode_symbols(self.ids(rec.sym[sl], rec.gds[sl]), rec.act[sl],
                              rec.start[sl].astype(bool), self.state_id, m.transition_counts,
                              self.n_ids)
        rec.labels[total - n:] = path[-n:]
        return lo

    def decode_chunk(self, m, n: int):
        """The map ``m`` with the last ``n`` steps decoded (after up to :data:`CONTEXT` steps
        before them) and their counts added to its tables."""
        total = self.n_steps
        lo = self._decode_last(m, n)
        self.last_work = {"decoded": int(total - lo), "pass": 0, "relabelled": 0}
        j = max(total - n - 1, self.pass_first)  # the transition into the chunk counts too
        rec = self.record
        return add_counts(m, rec.labels[j:], rec.act[j:], rec.start[j:], total - j - n)

    def warm_labels(self, m, n: int, first: int):
        """The labels a pass on the window from step ``first`` starts EM from: the states of
        the map ``m`` its steps hold, the call's ``n`` new steps decoded with ``m`` first
        (-1 where ``m`` cannot label a step); None while the window holds every step seen
        (its pass runs K-means again, so the symbols change) or before the first map."""
        if m is None or self.state_id is None or first == 0:
            return None
        self._decode_last(m, n)
        return self.record.labels[first:].astype(np.int64)

    def summary(self) -> dict:
        """``online_``: steps seen, calls, wider passes, the steps the last call's kernels
        touched (decoded; learned from and relabelled by a pass), the first step the last pass
        learned from, the bytes kept (``per_step`` is the O(T) part) and, once a pass capped
        the cluster count, ``clusters``: the count ``asked`` for, the distinct views the
        ``window`` of the last capped pass held and the ``symbols`` there are now."""
        book = self.codebook
        kept = 0 if book is None else int(book.means.nbytes) + sum(map(len, book.views or ()))
        return {"n_steps": self.n_steps, "n_calls": self.n_calls, "n_passes": self.n_passes,
                "last_work": dict(self.last_work), "pass_from": self.pass_first,
                "memory": {"per_step": self.record.nbytes, "window": self.window.nbytes,
                           "codebook": kept},
                **({"clusters": dict(self.clusters)} if self.clusters else {})}


def add_counts(m, labels, actions, starts, n_old: int):
    """The map ``m`` with the counts of a run of labelled steps added: the steps and actions of
    all but the first ``n_old`` of them (counted already), and every transition between them
    inside an episode.  Steps labelled -1 are left out."""
    x, a = labels.astype(np.int64), actions.astype(np.int64)
    S, A = m.n_states, m.n_actions
    new = x[n_old:] >= 0
    state_counts = m.state_counts + np.bincount(x[n_old:][new], minlength=S)
    action_counts = m.action_counts + np.bincount(x[n_old:][new] * A + a[n_old:][new],
                                                  minlength=S * A).reshape(S, A)
    t = np.flatnonzero((starts[1:] == 0) & (x[:-1] >= 0) & (x[1:] >= 0))
    trans = m.transition_counts + np.bincount((x[t] * A + a[t]) * S + x[t + 1],
                                              minlength=S * A * S).reshape(S, A, S)
    return replace(m, state_counts=state_counts, action_counts=action_counts,
                   transition_counts=trans)
