"""Clone-structured, action-conditioned HMMs: layout, initialisation, EM, Viterbi training.

A :class:`Layout` ties one discrete sequence (symbols, actions, episode lengths) to a clone budget
(clones per symbol) and the sparse transition blocks that sequence needs (one per observed
``(action, symbol, next symbol)`` triple; see :mod:`topomap.core.refine.kernels`).  Parameters are
plain count arrays in the block layout; probabilities are derived from counts by :func:`m_step`.
:func:`fit_clones` is the fit both refinements make: Baum-Welch, then Viterbi training, then the
clones the path uses become the states.

Two normalisations are offered (``joint``):

* ``False`` -- ``P(x'|x,u)``, CSCG's model: the action is an input;
* ``True`` -- ``P(u,x'|x) = P(u|x) P(x'|x,u)``, the paper's model (Eq. 1 of Yairi et al. has the
  term ``P(u|x)``): which actions a state takes is evidence about the state too.  Measured: EM
  with it splits places by the action taken next (gridroom 8x6: 92 states for 48 places), so
  the estimators use ``False``.

The pseudocount behaves as in a dense CSCG: every one of the ``S`` (or ``A S``) entries of a row
receives it, also those never stored, so a row's normaliser is ``counts + pseudocount * S``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..progress import report
from .accelerate import squarem
from .convergence import ConvergenceMonitor
from .backward import clone_counts_into
from .kernels import (CloneTables, clone_forward_into, clone_normalize_into, clone_path_counts,
                      clone_step_offsets, clone_viterbi)

__all__ = [
    "Layout",
    "make_layout",
    "m_step",
    "EStepWork",
    "e_step",
    "baum_welch",
    "capped_baum_welch",
    "SettledPath",
    "step_argmax",
    "viterbi_training",
    "fit_clones",
    "decode",
    "random_counts",
    "clone_budget",
    "init_from_path",
    "states_to_clones",
    "compact_labels",
]


@dataclass(frozen=True)
class Layout:
    """A symbol sequence bound to a clone budget and its transition blocks.

    Attributes
    ----------
    sym, u : (T,) int64 -- symbol and action of every step
    blk : (T,) int64 -- block of the transition ``t -> t + 1`` (-1 at an episode's last step)
    triples : (B, 3) int64 -- ``(action, symbol, next symbol)`` of every block
    start : (K + 1,) int64 -- clones of symbol ``k`` are ``start[k] .. start[k + 1] - 1``
    boff : (B + 1,) int64 -- block ``b`` occupies ``boff[b] .. boff[b + 1] - 1`` of a count array
    pos : (T + 1,) int64 -- per-step offsets of the clone vectors
        (:func:`topomap.core.refine.kernels.clone_step_offsets`)
    n_actions : int

    ``tables`` bundles what the kernels read (:class:`topomap.core.refine.kernels.CloneTables`).
    """

    sym: np.ndarray
    u: np.ndarray
    blk: np.ndarray
    triples: np.ndarray
    start: np.ndarray
    boff: np.ndarray
    pos: np.ndarray
    n_actions: int

    @property
    def tables(self) -> CloneTables:
        """``sym``, ``blk``, ``start``, ``boff`` and ``pos``, as the kernels take them."""
        return CloneTables(self.sym, self.blk, self.start, self.boff, self.pos)

    @property
    def n_clones(self) -> int:
        """Total number of clones ``S``."""
        return int(self.start[-1])

    @property
    def clones_per_symbol(self) -> np.ndarray:
        """(K,) clones of every symbol."""
        return np.diff(self.start)

    @property
    def clone_symbol(self) -> np.ndarray:
        """(S,) the symbol every clone emits."""
        return np.repeat(np.arange(self.start.size - 1), self.clones_per_symbol)

    def with_clones(self, clones_per_symbol) -> "Layout":
        """The same data and blocks under another clone budget."""
        start = np.concatenate([[0], np.cumsum(clones_per_symbol)]).astype(np.int64)
        return Layout(self.sym, self.u, self.blk, self.triples, start,
                      _block_offsets(self.triples, start), clone_step_offsets(self.sym, start),
                      self.n_actions)


def _block_offsets(triples: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Offsets of the blocks of ``triples`` in a count array, for the clone ranges ``start``."""
    n = np.diff(start)
    sizes = n[triples[:, 1]] * n[triples[:, 2]]
    return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)


def make_layout(sym, u, lengths, clones_per_symbol, n_actions: int) -> Layout:
    """Bind a sequence to ``clones_per_symbol`` (K,) clones per symbol.

    ``lengths`` (episode sizes, summing to ``T``) keeps transitions inside episodes.
    """
    sym = np.ascontiguousarray(sym, dtype=np.int64)
    u = np.ascontiguousarray(u, dtype=np.int64)
    K = len(clones_per_symbol)
    T = sym.size
    has_next = np.ones(T, dtype=bool)
    has_next[np.cumsum(lengths) - 1] = False
    t = np.flatnonzero(has_next)
    key = (u[t] * K + sym[t]) * K + sym[t + 1]
    uniq, inv = np.unique(key, return_inverse=True)
    blk = np.full(T, -1, dtype=np.int64)
    blk[t] = inv
    triples = np.column_stack([uniq // (K * K), (uniq // K) % K, uniq % K]).astype(np.int64)
    base = Layout(sym, u, blk, triples, np.zeros(K + 1, np.int64), np.zeros(1, np.int64),
                  np.zeros(1, np.int64), int(n_actions))
    return base.with_clones(np.asarray(clones_per_symbol, dtype=np.int64))


def _row_keys(lay: Layout, joint: bool):
    """Row-group key per block, number of keys and dense row width (for the pseudocount)."""
    if joint:
        return np.zeros(len(lay.triples), np.int64), 1, lay.n_clones * lay.n_actions
    return np.ascontiguousarray(lay.triples[:, 0]), lay.n_actions, lay.n_clones


def m_step(lay: Layout, counts, pseudocount: float, joint: bool, out=None) -> np.ndarray:
    """Block probabilities from counts (see
    :func:`topomap.core.refine.kernels.clone_normalize_blocks`), written into ``out`` if given."""
    key, n_keys, width = _row_keys(lay, joint)
    vals, _ = clone_normalize_into(lay.tables, counts, np.ascontiguousarray(lay.triples[:, 1]),
                                   np.ascontiguousarray(lay.triples[:, 2]), key, n_keys,
                                   pseudocount, pseudocount * width,
                                   np.empty(counts.size) if out is None else out)
    return vals


@dataclass(frozen=True)
class EStepWork:
    """The arrays an E-step and its M-step write (model, its column-major copy, counts and their
    copy, occupancy, forward messages, log scaling factors), made once for a layout and
    overwritten by every E-step of a Baum-Welch run: new arrays of a few MB each E-step cost a
    page fault every 4 KB (about 465 an E-step, a sixth of the 12x12 room's E-step time)."""

    vals: np.ndarray
    vals_t: np.ndarray
    counts: np.ndarray
    counts_t: np.ndarray
    occupancy: np.ndarray
    alpha: np.ndarray
    log_c: np.ndarray

    @classmethod
    def of(cls, lay: Layout) -> "EStepWork":
        """New arrays for the E-steps of ``lay``."""
        size = int(lay.boff[-1])
        return cls(*(np.empty(n) for n in (size, size, size, size, lay.n_clones,
                                           int(lay.pos[-1]), lay.sym.size)))


def e_step(lay: Layout, vals, prune: float = 0.0):
    """Expected counts, expected clone occupancy and log-likelihood under ``vals`` (``prune``: see
    :func:`topomap.core.refine.kernels.clone_forward`)."""
    counts, occupancy, ll, _ = _e_step(lay, vals, prune, EStepWork.of(lay))
    return counts, occupancy, ll


def _e_step(lay: Layout, vals, prune: float, work: EStepWork):
    """:func:`e_step` into ``work`` (its counts, occupancy and forward messages are returned and
    overwritten by the next E-step on it), and the filtered distributions ``alpha`` of its
    forward pass."""
    tables = lay.tables
    clone_forward_into(tables, vals, prune, work.alpha, work.log_c)
    clone_counts_into(tables, vals, work.alpha, work.log_c, work.counts, work.occupancy,
                      work.vals_t, work.counts_t)
    return work.counts, work.occupancy, float(work.log_c.sum()), work.alpha


def baum_welch(lay: Layout, counts, pseudocount: float, joint: bool, *, max_iter: int,
               tol: float, min_iter: int = 10, prune: float = 0.0, settle: float = 0.0,
               accelerate: str = "none"):
    """Baum-Welch from ``counts`` until the log-likelihood gains less than ``tol`` nats per step
    (checked from iteration ``min_iter`` on: from a random start the first iterations barely move)
    or ``max_iter`` iterations; with ``settle`` > 0 also once the decoded path has settled
    (:class:`SettledPath`, judged from iteration ``min_iter`` on too).  ``accelerate="squarem"``
    runs SQUAREM's cycles instead (:func:`topomap.core.refine.accelerate.squarem`: the gain is
    judged on every cycle's plain EM step; ``max_iter`` counts E-steps).

    Returns ``(counts, occupancy, history)``: the last expected counts (whose M-step is the fitted
    model), the clone occupancy and the log-likelihood of every iteration (E-step).
    """
    path = SettledPath(lay.pos, settle) if settle > 0 else None
    if accelerate != "none":
        return _squarem_baum_welch(lay, counts, pseudocount, joint, path, max_iter=max_iter,
                                   tol=tol, min_iter=min_iter, prune=prune)
    monitor = ConvergenceMonitor(tol * lay.sym.size, max_iter, min_iter=min_iter)
    occupancy = np.zeros(lay.n_clones)
    work = EStepWork.of(lay)  # the counts read by an M-step are written by the E-step after it
    while not (monitor.converged or path is not None and monitor.iter > min_iter and path.settled):
        counts, occupancy, ll, alpha = _e_step(
            lay, m_step(lay, counts, pseudocount, joint, work.vals), prune, work)
        monitor.report(ll)
        if path is not None:
            path.report(alpha)
        report("EM", len(monitor.history), max_iter)
    report("EM", len(monitor.history), len(monitor.history))  # converged: the loop ends here
    return counts, occupancy, monitor.history


def capped_baum_welch(lay: Layout, init, pseudocount: float, *, max_iter: int, tol: float,
                      cap: int, rtol: float, prune: float = 0.0, settle: float = 0.0,
                      accelerate: str = "none"):
    """Baum-Welch (:func:`baum_welch`) stopped after ``cap`` of its ``max_iter`` iterations
    unless the last one still gained more than ``rtol`` x |its log-likelihood| (and more than
    ``tol`` nats per step); then it goes on, from where it stopped, until an iteration gains less
    than that share of the log-likelihood reached at ``cap``.  Returns the last expected counts
    and the log-likelihood of every iteration."""
    counts, _, history = baum_welch(lay, init, pseudocount, False, max_iter=min(cap, max_iter),
                                    tol=tol, prune=prune, settle=settle, accelerate=accelerate)
    T = lay.sym.size
    bar = max(tol * T, rtol * abs(history[-1]))
    if len(history) < max_iter and len(history) >= 2 and history[-1] - history[-2] > bar:
        counts, _, more = baum_welch(lay, counts, pseudocount, False,
                                     max_iter=max_iter - len(history), tol=bar / T, min_iter=1,
                                     prune=prune, settle=settle, accelerate=accelerate)
        history = [*history, *more]
    return counts, history


def _squarem_baum_welch(lay: Layout, counts, pseudocount: float, joint: bool, path, *,
                        max_iter: int, tol: float, min_iter: int, prune: float):
    """:func:`baum_welch` by SQUAREM's cycles (``path``: its :class:`SettledPath`, or None)."""
    work = EStepWork.of(lay)

    def em_step(c):  # SQUAREM keeps the counts of several E-steps: copied out of ``work``
        new, occupancy, ll, alpha = _e_step(lay, m_step(lay, c, pseudocount, joint, work.vals),
                                            prune, work)
        if path is not None:
            path.report(alpha)
        return new.copy(), occupancy.copy(), ll

    counts, occupancy, history, _ = squarem(
        em_step, counts, max_iter=max_iter, tol=tol * lay.sym.size, min_iter=min_iter,
        stop=None if path is None else lambda: path.settled)
    report("EM", len(history), len(history))
    return counts, occupancy, history


@njit(cache=True)
def step_argmax(alpha, pos):
    """(T,) the most probable clone (local index, the first of ties) of every step's vector
    ``alpha[pos[t]:pos[t + 1]]``."""
    T = pos.size - 1
    out = np.empty(T, dtype=np.int64)
    for t in range(T):
        best, arg = -1.0, 0
        for j in range(pos[t + 1] - pos[t]):
            if alpha[pos[t] + j] > best:
                best, arg = alpha[pos[t] + j], j
        out[t] = arg
    return out


class SettledPath:
    """EM's decoded path -- the most probable clone of every step given the steps so far (the
    forward pass's filtered distributions, :func:`step_argmax`) -- followed over its E-steps.

    It has *settled* once it changed on fewer than ``share`` of the steps at ``SETTLE_ITER``
    E-steps in a row: what EM does after that is its slow tail, mass moving between clones --
    which also joins the duplicate clones of one place, so a round stopped there may leave
    duplicates its merges do not join (:class:`~topomap.core.refine.methods.EMRefinement`).

    Attributes
    ----------
    changed : list -- the steps whose decoded clone changed, at every E-step after the first
    """

    def __init__(self, pos, share: float):
        self.pos, self.share = pos, share
        self.changed, self._last = [], None

    def report(self, alpha) -> None:
        """Record the filtered distributions ``alpha`` of one more E-step."""
        now = step_argmax(alpha, self.pos)
        if self._last is not None:
            self.changed.append(int(np.count_nonzero(now != self._last)))
        self._last = now

    @property
    def settled(self) -> bool:
        """Whether the path changed on fewer than ``share`` of the steps at each of the last
        ``SETTLE_ITER`` E-steps."""
        calm = [c < self.share * self._last.size for c in self.changed[-SETTLE_ITER:]]
        return len(calm) == SETTLE_ITER and all(calm)


#: the E-steps in a row a :class:`SettledPath` must change little at to have settled
SETTLE_ITER = 3


def decode(lay: Layout, counts, pseudocount: float, joint: bool):
    """Viterbi path (global clone ids) and its log-probability under the model of ``counts``."""
    vals = m_step(lay, counts, pseudocount, joint)
    with np.errstate(divide="ignore"):
        log_vals = np.log(vals)
    return clone_viterbi(lay.tables, log_vals)


def viterbi_training(lay: Layout, counts, joint: bool, *, pseudocount: float = 0.0,
                     max_iter: int = 100):
    """Hard EM: decode, re-count the path, repeat until the path's probability stops rising (a
    path no more probable than the last one, by 1e-9 of it, is not taken) or ``max_iter`` paths.

    Returns ``(path, counts, history)``; ``counts`` are the hard counts of ``path`` and
    ``history`` the log-probabilities of the paths taken.
    """
    monitor = ConvergenceMonitor(n_iter=max_iter, rtol=1e-9)
    path = None
    while not monitor.converged:
        new_path, log_p = decode(lay, counts, pseudocount, joint)
        monitor.report(log_p)
        if not monitor.stalled:
            path = new_path
            counts = clone_path_counts(path, lay.tables, np.zeros(counts.size))
    history = monitor.history[:-1] if monitor.stalled else monitor.history
    return path, counts, history


def fit_clones(lay: Layout, init, pseudocount: float, *, max_iter: int, tol: float,
               prune: float = 0.0, joint: bool = False, settle: float = 0.0,
               accelerate: str = "none"):
    """Baum-Welch from the counts ``init`` (:func:`baum_welch`, ``settle`` and ``accelerate`` as
    there), then Viterbi training without pseudocount (:func:`viterbi_training`); the clones the
    final path uses become the states.

    Returns ``(labels, state_symbol, em_history, viterbi_history)``: the state of every step
    (numbered by first use), the symbol of every state, and the log-likelihoods of Baum-Welch's
    iterations and of the Viterbi paths.
    """
    counts, _, em_history = baum_welch(lay, init, pseudocount, joint, max_iter=max_iter, tol=tol,
                                       prune=prune, settle=settle, accelerate=accelerate)
    path, _, viterbi_history = viterbi_training(lay, counts, joint)
    labels, state_symbol, _ = compact_labels(path, lay.clone_symbol)
    return labels, state_symbol, em_history, viterbi_history


def random_counts(lay: Layout, rng: np.random.Generator) -> np.ndarray:
    """CSCG's initialisation: independent uniform counts in every stored entry."""
    return rng.random(int(lay.boff[-1]))


def clone_budget(n_symbols: int, n_gds: int, per_symbol) -> np.ndarray:
    """Clones per symbol id: ``per_symbol`` (int or (n_symbols,) array) for the K-means symbols,
    then one for each of the ``n_gds`` GDS ids (a GDS state stays unique)."""
    free = np.broadcast_to(np.asarray(per_symbol, dtype=np.int64), (n_symbols,))
    return np.concatenate([free, np.ones(n_gds, dtype=np.int64)])


def init_from_path(lay: Layout, path, n_steps: int, rng, noise: float = 1.0) -> np.ndarray:
    """Initial counts on ``lay`` from a hard clone path of its first ``n_steps`` steps.

    The path's transitions are counted and scaled by ``T / n_steps`` (as if the whole sequence
    looked like its first part); ``noise`` times a uniform random count is added to every stored
    entry, so spare clones and triples the path never used start with small random weights that
    EM can grow.
    """
    blk = lay.blk[:n_steps].copy()
    blk[n_steps - 1] = -1
    prefix = CloneTables(lay.sym[:n_steps], blk, lay.start, lay.boff, lay.pos[:n_steps + 1])
    counts = clone_path_counts(np.ascontiguousarray(path[:n_steps]), prefix,
                               np.zeros(int(lay.boff[-1])))
    return counts * (lay.sym.size / n_steps) + noise * rng.random(counts.size)


def states_to_clones(labels, state_symbol, n_ids: int, n_symbols: int, spare: int):
    """Clone budget holding every state plus ``spare`` clones per K-means symbol (ids below
    ``n_symbols``; GDS ids get none), and the clone path of ``labels``: each state becomes one
    clone of its symbol."""
    per = np.bincount(state_symbol, minlength=n_ids)
    budget = per + np.where(np.arange(n_ids) < n_symbols, spare, 0)
    start = np.concatenate([[0], np.cumsum(budget)])
    return budget, (start[state_symbol] + _rank_in_symbol(state_symbol, per))[labels]


def _rank_in_symbol(state_symbol, per):
    """Every state's rank among the states of its symbol (``per``: states per symbol id)."""
    order = np.argsort(state_symbol, kind="stable")
    rank = np.empty(state_symbol.size, dtype=np.int64)
    first = np.concatenate([[0], np.cumsum(per)])
    rank[order] = np.arange(state_symbol.size) - first[state_symbol[order]]
    return rank


def spread_states(labels, state_symbol, budget, rng):
    """The clone path of ``labels`` on ``budget`` clones per symbol id (at least the states of
    each): the ``n`` states of a symbol with ``B`` clones get ``B // n`` clones each, and every
    step of a state takes one of its state's clones at random (the others of the symbol stay
    unused)."""
    per = np.bincount(state_symbol, minlength=budget.size)
    start = np.concatenate([[0], np.cumsum(budget)])
    first = start[state_symbol] + _rank_in_symbol(state_symbol, per)  # each state's first clone
    copies = np.maximum(budget // np.maximum(per, 1), 1)[state_symbol]  # clones per state
    return first[labels] + per[state_symbol][labels] * rng.integers(0, copies[labels])


def compact_labels(path, clone_symbol):
    """Renumber the clones a path uses as states ``0..n-1`` (by first use).

    Returns ``(labels, state_symbol, used)``: ``used`` are the original clone ids of the states.
    """
    used, first = np.unique(path, return_index=True)
    used = used[np.argsort(first, kind="stable")]
    rename = np.full(int(path.max()) + 1, -1, dtype=np.int64)
    rename[used] = np.arange(used.size)
    return rename[path], np.asarray(clone_symbol)[used], used
