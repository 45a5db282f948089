"""Learning while the steps arrive: what :meth:`MapLearner.partial_fit` keeps between calls.

The map is learned from a stream of chunks, at a cost per chunk that does not grow with the steps
seen before it:

* **Symbols.** While the window still holds every step seen, every pass runs phase 1's K-means
  on all of them (a walk no longer than the window is learned as :meth:`MapLearner.fit` learns
  it).  Once steps have left the window, the symbols of the last such pass are fixed (a codebook
  of the symbols' mean observations), and a new step takes the symbol of the nearest mean: for
  the Euclidean metric (the paper's) this is K-means' own assignment.  Symbols are then fixed
  rather than updated (``MiniBatchKMeans.partial_fit``) because every state, count and label is
  defined on them: moving a centre would silently change the symbol of steps already counted.
* **Every chunk** is decoded with the current map (Viterbi over the chunk's symbols and actions,
  continuing from the last steps before it) and its transitions are added to the map's count
  tables: only the rows of the states the chunk visits change.
* **A wider pass** re-learns the map's structure -- the split, the refinement, ``stop=auto``'s
  size choice: :meth:`MapLearner.fit` with the codebook's symbols -- on a bounded window of the
  latest ``window`` steps.  It runs on the first call, then whenever the steps since the last
  pass reach ``refit_every`` or the steps the map was last learned from (so passes come at
  doubling sizes early on), and at once when a chunk brings a GDS id, an action or a symbol the
  map does not know.

Memory kept: the window (``window`` rows of observations, actions, GDS ids) and the map's tables,
bounded by the world, not by the steps; and, per step seen, five int32: its symbol, action and
GDS id (from which ``labels_`` is decoded), whether an episode starts there, and the label it was
decoded to when it arrived, so O(T) small integers in all.  Reading ``labels_``
decodes the steps before the window with the current map: O(T), once per call (cached).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .refine.clones import decode, make_layout

__all__ = ["GrowingInts", "Window", "OnlineState", "decode_symbols", "nearest_symbols"]

#: steps before a chunk decoded with it, so a chunk's first states are not guessed blind
CONTEXT = 16
#: the share of a count every unseen transition gets when a chunk is decoded
PSEUDOCOUNT = 1e-3


class GrowingInts:
    """An int32 array that grows by amortised doubling (the O(T) per-step record)."""

    def __init__(self):
        self._a = np.empty(1024, dtype=np.int32)
        self.size = 0

    def extend(self, values) -> None:
        values = np.asarray(values)
        need = self.size + values.size
        if need > self._a.size:
            grown = np.empty(max(need, 2 * self._a.size), dtype=np.int32)
            grown[:self.size] = self._a[:self.size]
            self._a = grown
        self._a[self.size:need] = values
        self.size = need

    def truncate_or_pad(self, n: int) -> None:
        """Keep the first ``n`` values, padding with -1 when fewer are stored."""
        if n <= self.size:
            self.size = n
        else:
            self.extend(np.full(n - self.size, -1))

    @property
    def values(self) -> np.ndarray:
        """A view of the stored values."""
        return self._a[:self.size]

    @property
    def nbytes(self) -> int:
        return int(self._a.nbytes)


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
        """``(X, u, gds, starts)`` of the last ``capacity`` steps (the oldest chunk trimmed); the
        first step always starts an episode."""
        X, u, g, s = (np.concatenate([c[i] for c in self.chunks]) for i in range(4))
        cut = max(0, X.shape[0] - self.capacity)
        X, u, g, s = X[cut:], u[cut:], g[cut:], s[cut:].copy()
        s[0] = True
        return X, u, g, s, self.first + cut

    def tail(self, n: int):
        """``(u, gds, starts)`` of the last ``n`` steps (fewer when the window holds fewer)."""
        parts, have = [], 0
        for c in reversed(self.chunks):
            parts.append(c)
            have += c[0].shape[0]
            if have >= n:
                break
        u, g, s = (np.concatenate([c[i] for c in reversed(parts)])[-n:] for i in (1, 2, 3))
        return u, g, s

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for c in self.chunks for a in c))


def lengths_of(starts: np.ndarray) -> np.ndarray:
    """Episode lengths of a run of steps from its episode-start flags (the first step starts)."""
    first = np.flatnonzero(starts)
    return np.diff(np.concatenate([first, [starts.size]])).astype(np.int64)


def nearest_symbols(X: np.ndarray, codebook: np.ndarray) -> np.ndarray:
    """The symbol of every row: the index of its nearest codebook row (squared Euclidean)."""
    d = (X * X).sum(1)[:, None] - 2.0 * X @ codebook.T + (codebook * codebook).sum(1)[None, :]
    return np.argmin(d, axis=1).astype(np.int64)


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
    S, A = transitions.shape[0], transitions.shape[1]
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
    """What ``partial_fit`` keeps between calls (see the module docstring)."""

    window: Window
    n_actions: int | None = None
    action_names: list | None = None
    gds_names: list | None = None
    codebook: np.ndarray | None = None       # (K, D) mean observation of every symbol
    gds_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    sym: GrowingInts = field(default_factory=GrowingInts)    # symbol id per step (-1: GDS)
    act: GrowingInts = field(default_factory=GrowingInts)
    gds: GrowingInts = field(default_factory=GrowingInts)
    start: GrowingInts = field(default_factory=GrowingInts)  # 1 where an episode starts
    labels: GrowingInts = field(default_factory=GrowingInts)  # per step, as decoded at the time
    state_id: np.ndarray | None = None        # (S,) the symbol id every state of the map emits
    n_ids: int = 0                             # symbol ids: K-means symbols, then known GDS ids
    pass_first: int = 0                        # first step of the last pass's window
    pass_steps: int = 0                        # steps seen at the last pass
    n_calls: int = 0
    n_passes: int = 0
    last_work: dict = field(default_factory=dict)
    cached_labels: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        return self.sym.size

    def ids(self, sym, g) -> np.ndarray:
        """Symbol ids of steps: K-means symbols, then ``K + i`` for the ``i``-th known GDS id
        (-1 for a GDS id the map does not know)."""
        K = 0 if self.codebook is None else self.codebook.shape[0]
        out = np.asarray(sym, dtype=np.int64).copy()
        is_g = np.asarray(g) >= 0
        if is_g.any():
            pos = np.searchsorted(self.gds_ids, g[is_g])
            pos = np.minimum(pos, max(self.gds_ids.size - 1, 0))
            found = self.gds_ids.size > 0
            ok = found & (self.gds_ids[pos] == g[is_g]) if found else np.zeros(pos.size, bool)
            out[is_g] = np.where(ok, K + pos, -1)
        return out

    def memory(self) -> dict:
        """Bytes kept: the per-step record (O(T)) and the rest (bounded)."""
        per_step = sum(a.nbytes for a in (self.sym, self.act, self.gds, self.start, self.labels))
        return {"per_step": per_step, "window": self.window.nbytes,
                "codebook": 0 if self.codebook is None else int(self.codebook.nbytes)}


def replace_counts(m, state_counts, action_counts, transition_counts):
    """The map ``m`` with new count tables (observation models and records unchanged)."""
    return replace(m, state_counts=state_counts, action_counts=action_counts,
                   transition_counts=transition_counts)


# ---------------------------------------------------------------------------------- the calls
#: learned attributes a pass hands from the window's fit to the learner (the ``labels_*`` of the
#: window are not: ``labels_`` covers every step)
PASSED_ON = ("map_", "map_phase1_", "map_split_", "split_history_", "entropies_", "stop_reason_",
             "n_clusters_", "cluster_choice_", "phase1_method_", "n_features_in_", "refine_info_",
             "size_choice_", "timings_")


def partial_fit(learner, observations, actions, gds=None, *, new_episode: bool = False,
                n_actions=None, action_names=None, gds_names=None):
    """:meth:`topomap.MapLearner.partial_fit` (see the module docstring)."""
    from .data.trajectory import check_sequences

    X, u, g, _ = check_sequences(observations, actions, gds, None, min_length=1)
    window, every = learner._online_settings()
    st = learner.__dict__.get("_online")
    if st is None:
        learner._forget_fit()
        st = OnlineState(Window(window), n_actions=None if n_actions is None else int(n_actions),
                         action_names=action_names, gds_names=gds_names)
    elif st.codebook is not None and X.shape[1] != st.codebook.shape[1]:
        raise ValueError(f"observations have {X.shape[1]} features but the earlier steps had "
                         f"{st.codebook.shape[1]}")
    if action_names is not None:
        st.action_names = action_names
    if gds_names is not None:
        st.gds_names = gds_names
    starts = np.zeros(X.shape[0], dtype=bool)
    starts[0] = new_episode or st.n_steps == 0
    saved = _snapshot(st)
    try:
        _take(st, X, u, g, starts)
        if _needs_pass(learner, st, every):
            _pass(learner, st, X)
        else:
            _chunk(learner, st, X.shape[0])
    except BaseException:
        _restore(st, saved)
        raise
    st.n_calls += 1
    st.cached_labels = None
    learner._online = st
    return learner


def _snapshot(st: OnlineState):
    w = st.window
    return (list(w.chunks), w.size, w.first, st.n_steps, st.labels.size, st.n_actions,
            st.codebook)


def _restore(st: OnlineState, saved) -> None:
    w = st.window
    w.chunks, w.size, w.first, n, n_lab, st.n_actions, st.codebook = saved
    for rec in (st.sym, st.act, st.gds, st.start):
        rec.size = n
    st.labels.truncate_or_pad(n_lab)


def _take(st: OnlineState, X, u, g, starts) -> None:
    """Record a chunk: its steps' symbols (nearest codebook row), actions, GDS ids, starts."""
    sym = np.full(X.shape[0], -1, dtype=np.int64)
    plain = g < 0
    if st.codebook is not None and plain.any():
        sym[plain] = nearest_symbols(X[plain], st.codebook)
    st.window.push(X, u, g, starts)
    for rec, v in ((st.sym, sym), (st.act, u), (st.gds, g), (st.start, starts)):
        rec.extend(v)
    st.n_actions = max(st.n_actions or 0, int(u.max()) + 1,
                       len(st.action_names) if st.action_names is not None else 0)


def _needs_pass(learner, st: OnlineState, every: int) -> bool:
    """A pass is due: no map yet, ``refit_every`` (or, early on, as many steps as the last pass
    saw) new steps, or a GDS id, action or symbol the map does not know."""
    if st.codebook is None or st.state_id is None:
        return True
    new = st.n_steps - st.pass_steps
    if new >= min(every, max(st.pass_steps, 1)):
        return True
    m = learner.map_
    since = slice(st.pass_steps, st.n_steps)
    if int(st.act.values[since].max()) >= m.n_actions:
        return True
    ids = st.ids(st.sym.values[since], st.gds.values[since])
    per = np.bincount(st.state_id, minlength=st.n_ids)
    return bool((ids < 0).any() or (per[ids] == 0).any())


def _pass(learner, st: OnlineState, X_call) -> None:
    """Learn the map from the window (:meth:`MapLearner.fit` with the codebook's symbols)."""
    from sklearn.base import clone

    Xw, uw, gw, sw, first = st.window.arrays()
    plain = gw < 0
    inner = clone(learner)
    inner.callbacks = ()
    present = None
    relearn = st.codebook is None or first == 0   # the window still holds every step seen
    if not relearn:
        sym = st.sym.values[first:].astype(np.int64)[plain]
        present = np.unique(sym)
        inner._given_symbols = np.searchsorted(present, sym)
    inner.fit(Xw, uw, gw, lengths_of(sw), n_actions=st.n_actions, action_names=st.action_names,
              gds_names=st.gds_names)
    if relearn:  # phase 1's K-means symbols of every step seen become the codebook
        sym = inner.labels_phase1_[plain]
        K = inner.n_clusters_
        counts = np.bincount(sym, minlength=K)[:, None]
        st.codebook = np.zeros((K, Xw.shape[1]))
        np.add.at(st.codebook, sym, Xw[plain])
        st.codebook /= np.maximum(counts, 1)
        present = np.arange(K)
        rec = st.sym.values
        rec[first:][plain] = sym
        if first > 0:  # the first pass comes at the first call: its steps before the window
            old = np.flatnonzero(st.gds.values[:first] < 0)
            rec[old] = nearest_symbols(X_call[old], st.codebook)
    m = inner.map_
    st.gds_ids = np.unique(gw[gw >= 0]).astype(np.int64)
    K = st.codebook.shape[0]
    st.n_ids = K + st.gds_ids.size
    is_g = m.state_gds >= 0
    st.state_id = np.where(is_g, K + np.searchsorted(st.gds_ids, m.state_gds),
                           present[np.maximum(m.state_symbol, 0)]).astype(np.int64)
    for name in PASSED_ON:
        if hasattr(inner, name):
            setattr(learner, name, getattr(inner, name))
    st.labels.truncate_or_pad(first)  # labels before the window are decoded when read
    st.labels.extend(inner.labels_)
    st.pass_first, st.pass_steps = first, st.n_steps
    st.n_passes += 1
    st.last_work = {"decoded": 0, "pass": int(Xw.shape[0])}


def _chunk(learner, st: OnlineState, n: int) -> None:
    """Decode the chunk's ``n`` steps with the map (after up to :data:`CONTEXT` steps before it)
    and add its counts to the map's tables."""
    m = learner.map_
    total = st.n_steps
    lo = max(st.pass_first, total - n - CONTEXT)
    sl = slice(lo, total)
    starts = st.start.values[sl].astype(bool)
    ids = st.ids(st.sym.values[sl], st.gds.values[sl])
    u = st.act.values[sl].astype(np.int64)
    path = decode_symbols(ids, u, starts, st.state_id, m.transition_counts, st.n_ids)
    st.labels.extend(path[-n:])
    # counts of the chunk: its steps, and its transitions including the one into its first step
    S, A = m.n_states, m.n_actions
    x = st.labels.values[total - n:].astype(np.int64)
    a = st.act.values[total - n:].astype(np.int64)
    ok = x >= 0
    state_counts = m.state_counts + np.bincount(x[ok], minlength=S)
    action_counts = m.action_counts + np.bincount(x[ok] * A + a[ok], minlength=S * A).reshape(S, A)
    j = max(total - n - 1, st.pass_first)
    xs = st.labels.values[j:].astype(np.int64)
    us = st.act.values[j:].astype(np.int64)
    nxt = ~st.start.values[j + 1:total].astype(bool)
    t = np.flatnonzero(nxt & (xs[:-1] >= 0) & (xs[1:] >= 0))
    trans = m.transition_counts + np.bincount((xs[t] * A + us[t]) * S + xs[t + 1],
                                              minlength=S * A * S).reshape(S, A, S)
    learner.map_ = replace_counts(m, state_counts, action_counts, trans)
    st.last_work = {"decoded": int(total - lo), "pass": 0}


def all_labels(st: OnlineState, m) -> np.ndarray:
    """``labels_`` of an online fit: the steps before the last pass's window decoded with the
    current map ``m`` (O(T), cached until the next call), then the labels kept since."""
    if st.cached_labels is not None:
        return st.cached_labels
    if st.state_id is None:
        out = np.full(st.n_steps, -1, dtype=np.int64)
    else:
        n = st.pass_first
        kept = st.labels.values[n:].astype(np.int64)
        if n == 0:
            out = kept
        else:
            starts = st.start.values[:n].astype(bool)
            ids = st.ids(st.sym.values[:n], st.gds.values[:n])
            before = decode_symbols(ids, st.act.values[:n], starts, st.state_id,
                                    m.transition_counts, st.n_ids)
            out = np.concatenate([before, kept])
    st.cached_labels = out
    return out
