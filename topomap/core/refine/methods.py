"""The refinement phase: EM over clone-structured maps after the paper's split, and EM alone.

Both work on the discrete sequence phase 1 produces: ``sym[t]`` is the K-means symbol of step
``t`` (``0..ns-1``) or ``ns + g`` for a step recognised as GDS ``g`` (``labels_phase1_`` of
:class:`topomap.MapLearner`).  GDS ids always get exactly one clone, so GDS states stay fixed and
unique.  Transitions are CSCG's ``P(x'|x,u)`` (the action is an input).  Every fit returns a
:class:`CloneFit`: a hard labelling of the steps into states, each state emitting one symbol.

:func:`cscg_fit` -- EM alone: many clones per symbol, random start, Baum-Welch to convergence,
Viterbi training.

:func:`refine_fit` -- after the paper's split: EM learns the structure on a prefix with a clone
budget sized by the split, the prefix grows until the structure settles, and every EM round is
followed by hard re-assignment (Viterbi), removal of unused states, merging of bisimilar states
and splitting of compound states (:mod:`topomap.core.refine.structure`).

:class:`EMRefinement` (``refine="em"``) and :class:`CSCGRefinement` (``refine="cscg"``) are the
components :class:`topomap.MapLearner` takes; their parameters are the knobs of the two fits.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .clones import (Layout, baum_welch, clone_budget, compact_labels, init_from_path, make_layout,
                     random_counts, states_to_clones, viterbi_training)
from .structure import episode_masks, merge_states, same_partition, split_compounds

__all__ = ["CloneFit", "EMSettings", "SymbolSequence", "cscg_fit", "refine_fit", "EMRefinement",
           "CSCGRefinement", "REFINEMENTS"]


@dataclass
class CloneFit:
    """A learned clone-structured map as a hard labelling.

    Attributes
    ----------
    labels : (T,) int -- state of every step (states ``0..n_states-1``, numbered by first use)
    state_symbol : (n_states,) int -- symbol id each state emits
    info : dict -- iterations and log-likelihoods of the stages (no times: it is stored in
        ``map.json``, which the same config and seed must reproduce byte for byte; the learner's
        ``timings_`` holds the refinement's seconds)
    """

    labels: np.ndarray
    state_symbol: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.state_symbol.size)


@dataclass(frozen=True)
class SymbolSequence:
    """The discrete input of the EM phases.

    ``sym`` (T,) symbol ids (K-means symbols ``0..n_symbols-1``, then GDS ids), ``u`` (T,) actions,
    ``lengths`` episode lengths, ``n_ids`` the number of symbol ids (K-means symbols + GDS).
    """

    sym: np.ndarray
    u: np.ndarray
    lengths: np.ndarray
    n_actions: int
    n_ids: int
    n_symbols: int

    @classmethod
    def build(cls, sym, u, lengths, n_actions: int, n_symbols: int) -> "SymbolSequence":
        """From array-likes; symbol ids past ``n_symbols`` are GDS ids."""
        sym = np.asarray(sym, dtype=np.int64)
        return cls(sym, np.asarray(u, dtype=np.int64), np.asarray(lengths, dtype=np.int64),
                   int(n_actions), max(int(sym.max()) + 1, int(n_symbols)), int(n_symbols))

    @property
    def T(self) -> int:
        """Number of steps."""
        return int(self.sym.size)

    def head(self, n_steps: int) -> "SymbolSequence":
        """The first ``n_steps`` steps (the last episode cut short)."""
        ends = np.cumsum(self.lengths)
        k = int(np.searchsorted(ends, n_steps))
        lengths = self.lengths[:k + 1].copy()
        lengths[-1] -= ends[k] - n_steps
        return SymbolSequence(self.sym[:n_steps], self.u[:n_steps], lengths, self.n_actions,
                              self.n_ids, self.n_symbols)

    def layout(self, budget) -> Layout:
        """The sequence bound to ``budget`` clones per symbol id."""
        return make_layout(self.sym, self.u, self.lengths, budget, self.n_actions)

    def masks(self):
        """``(has_prev, has_next)`` of every step."""
        return episode_masks(self.lengths, self.T)


def cscg_fit(sym, u, lengths, n_actions: int, n_symbols: int, *, clones_per_symbol=70,
             pseudocount: float = 2e-3, joint: bool = False, max_iter: int = 1000,
             tol: float = 0.0, random_state: int = 0) -> CloneFit:
    """EM alone, CSCG's recipe (George et al., 2021) written afresh on the clone kernels.

    ``clones_per_symbol`` clones for every K-means symbol (one per GDS id), random uniform initial
    counts, Baum-Welch with ``pseudocount`` until the gain is below ``tol`` nats per step (0:
    CSCG's rule, until the log-likelihood stops rising; checked from iteration 10 on) or
    ``max_iter`` iterations, then Viterbi training without pseudocount; clones the final Viterbi
    path never visits are dropped.  ``joint=True`` models ``P(u,x'|x)`` instead of ``P(x'|x,u)``
    (the paper's ``P(u|x)`` term; it over-splits places by their next action).
    """
    seq = SymbolSequence.build(sym, u, lengths, n_actions, n_symbols)
    lay = seq.layout(clone_budget(n_symbols, seq.n_ids - n_symbols, clones_per_symbol))
    rng = np.random.default_rng(random_state)
    counts, _, em_hist = baum_welch(lay, random_counts(lay, rng), pseudocount, joint,
                                    max_iter=max_iter, tol=tol)
    path, _, vit_hist = viterbi_training(lay, counts, joint)
    labels, state_symbol, _ = compact_labels(path, lay.clone_symbol)
    info = {"em_iterations": len(em_hist), "em_loglik": em_hist[-1],
            "viterbi_iterations": len(vit_hist), "viterbi_logp": vit_hist[-1],
            "clones": lay.n_clones}
    return CloneFit(labels, state_symbol, info)


@dataclass(frozen=True)
class EMSettings:
    """Knobs of every EM round of the refinement.

    ``row_prior`` is the pseudocount mass of a row of ``P(x'|x,u)``: CSCG's pseudocount is
    ``row_prior / S`` per entry, so the prior does not grow with the clone count ``S`` (CSCG's
    fixed 2e-3 per entry weighs 6 counts per row at 3,000 clones and folds FourRooms' congruent
    rooms onto each other).  Baum-Welch stops after ``max_iter`` iterations or when it gains less
    than ``tol`` nats per step (the structure moves, not EM's slow tail, finish the job);
    ``prune`` drops filtered probabilities below it (:func:`topomap.core.map.kernels.clone_forward`);
    ``merge_threshold`` is the G-test threshold of merging (negative: never merge) and
    ``split_z`` the normal score of splitting (``inf``: never split); a warm-started round gives
    every K-means symbol ``spare`` extra clones and adds ``init_noise`` x uniform random counts.
    """

    row_prior: float = 0.5
    tol: float = 1e-6
    max_iter: int = 50
    prune: float = 1e-4
    merge_threshold: float = 6.63
    split_z: float = 3.09
    spare: int = 2
    init_noise: float = 1.0


def _fit_layout(lay: Layout, init, cfg: EMSettings):
    """Baum-Welch then Viterbi training on ``lay`` from ``init``; returns the labels and state
    symbols of the clones the path uses, and the number of EM iterations."""
    counts, _, history = baum_welch(lay, init, cfg.row_prior / lay.n_clones, False,
                                    max_iter=cfg.max_iter, tol=cfg.tol, prune=cfg.prune)
    path, _, _ = viterbi_training(lay, counts, False)
    labels, state_symbol, _ = compact_labels(path, lay.clone_symbol)
    return labels, state_symbol, len(history)


def _warm_round(seq: SymbolSequence, labels, state_symbol, cfg: EMSettings, rng):
    """One EM round on ``seq`` started from a labelling of its first ``labels.size`` steps."""
    budget, path = states_to_clones(labels, state_symbol, seq.n_ids, seq.n_symbols, cfg.spare)
    lay = seq.layout(budget)
    return _fit_layout(lay, init_from_path(lay, path, labels.size, rng, cfg.init_noise), cfg)


def _restructure(seq: SymbolSequence, labels, state_symbol, cfg: EMSettings):
    """Merge bisimilar states, then split compound ones.  Returns the merged labelling, the split
    labelling (each as ``(labels, state_symbol)``) and whether either step changed anything."""
    has_prev, has_next = seq.masks()
    merged = merge_states(labels, state_symbol, seq.u, has_next, cfg.merge_threshold)
    split = split_compounds(*merged, seq.u, has_prev, has_next, seq.n_actions,
                            splittable=merged[1] < seq.n_symbols, z=cfg.split_z)
    changed = split[1].size > merged[1].size or merged[1].size < state_symbol.size
    return merged, split, changed


def split_budget(split_state_symbol, seq: SymbolSequence, factor: int, spare: int):
    """Clones per symbol id sized by the split: ``factor`` x (split states of the symbol) +
    ``spare`` for K-means symbols, one per GDS id."""
    split_state_symbol = np.asarray(split_state_symbol)
    per = np.bincount(split_state_symbol[split_state_symbol >= 0], minlength=seq.n_symbols)
    return clone_budget(seq.n_symbols, seq.n_ids - seq.n_symbols, factor * per + spare)


def _grow(seq: SymbolSequence, n: int, labels, state_symbol, cfg: EMSettings,
          max_rounds: int, rng, stages: list):
    """Stages 2 and 3 of :func:`refine_fit` from a labelling of the first ``n`` steps; appends
    ``(steps, states, EM iterations)`` per round to ``stages`` and returns the merged
    labelling of the last round."""
    rounds, previous = 0, None
    while True:
        merged, split, changed = _restructure(seq.head(n), labels, state_symbol, cfg)
        rounds += n == seq.T
        if n == seq.T and (not changed or rounds >= max_rounds or (
                previous is not None and same_partition(previous, merged[0]))):
            return merged, rounds
        previous = merged[0] if n == seq.T else None
        settled = len(stages) > 1 and stages[-1][1] == stages[-2][1]
        n = seq.T if settled else min(2 * n, seq.T)
        labels, state_symbol, iters = _warm_round(seq.head(n), *split, cfg, rng)
        stages.append((n, int(state_symbol.size), iters))


def refine_fit(sym, u, lengths, n_actions: int, n_symbols: int, split_state_symbol, *,
               clone_factor: int = 2, prefix: int = 2000, prefix_visits: int = 40,
               max_rounds: int = 8, settings: EMSettings = EMSettings(),
               random_state: int = 0) -> CloneFit:
    """The refinement phase after the paper's split.

    ``split_state_symbol`` is the symbol of every split state (``map_.state_symbol``, -1 for GDS).

    1. Structure on a prefix of ``max(prefix, prefix_visits x split states)`` steps (about
       ``prefix_visits`` visits per place): ``clone_factor`` x (split states of the symbol) + spare
       clones per symbol, random start, Baum-Welch, Viterbi training; then bisimilar states are
       merged and compound states split.
    2. Growth: the prefix doubles, each stage warm-started from the last one's states plus spare
       clones; once two stages end with as many states (the structure has settled), the next
       stage takes all steps.
    3. On all steps, rounds repeat until EM's labelling is a fixpoint (nothing to merge or split),
       a round ends with the merged labelling of the round before (a split that EM and merging
       undo), or after ``max_rounds``.

    Returns a :class:`CloneFit` whose labels are the last merged Viterbi labelling.
    """
    seq = SymbolSequence.build(sym, u, lengths, n_actions, n_symbols)
    rng = np.random.default_rng(random_state)
    n_split = int(np.sum(np.asarray(split_state_symbol) >= 0))
    n = min(max(prefix, prefix_visits * n_split), seq.T)
    lay = seq.head(n).layout(split_budget(split_state_symbol, seq, clone_factor, settings.spare))
    labels, state_symbol, iters = _fit_layout(lay, random_counts(lay, rng), settings)
    stages = [(n, int(state_symbol.size), iters)]
    (labels, state_symbol), rounds = _grow(seq, n, labels, state_symbol, settings, max_rounds,
                                           rng, stages)
    return CloneFit(labels, state_symbol, {"stages": stages, "rounds_on_all_steps": rounds})


class EMRefinement:
    """``refine="em"``: re-estimate every state jointly after the split (:func:`refine_fit`).

    Parameters are :func:`refine_fit`'s and :class:`EMSettings`'s: ``clone_factor`` clones per
    split state of a symbol on the first prefix, ``prefix`` / ``prefix_visits`` its length,
    ``max_rounds`` rounds on all steps, ``row_prior`` the pseudocount mass of a transition row,
    ``tol`` / ``max_iter`` Baum-Welch's stop, ``prune`` the filtered probabilities dropped,
    ``merge_threshold`` the G test of merging bisimilar states (negative: never), ``split_z`` the
    normal score of splitting compound states (``inf``: never), ``spare`` clones added per symbol
    at every warm start and ``init_noise`` the random counts added to a warm start.  With
    ``guard`` (the default) the learner keeps the refined map only if its BIC (actions and
    transitions) is no worse than the split map's: refinement never trades a good split map for a
    fragmented one (with many actions and few visits per place and action, the split test of
    :func:`topomap.core.refine.structure.split_compounds` finds differences in noise).
    """

    name = "em"

    def __init__(self, clone_factor: int = 2, prefix: int = 2000, prefix_visits: int = 40,
                 max_rounds: int = 8, row_prior: float = 0.5, tol: float = 1e-6,
                 max_iter: int = 50, prune: float = 1e-4, merge_threshold: float = 6.63,
                 split_z: float = 3.09, spare: int = 2, init_noise: float = 1.0,
                 guard: bool = True):
        for key, value in (("clone_factor", clone_factor), ("prefix", prefix),
                           ("max_rounds", max_rounds), ("max_iter", max_iter)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"refine.{key} must be a positive integer, got {value!r}")
        if not (row_prior > 0 and tol >= 0 and 0 <= prune < 1 and spare >= 0):
            raise ValueError("refine.row_prior must be > 0, refine.tol >= 0, refine.prune in "
                             "[0, 1) and refine.spare >= 0")
        self.clone_factor, self.prefix, self.prefix_visits = clone_factor, prefix, prefix_visits
        self.max_rounds, self.guard = max_rounds, bool(guard)
        self.settings = EMSettings(row_prior, tol, max_iter, prune, merge_threshold, split_z,
                                   spare, init_noise)

    def fit(self, seq: SymbolSequence, split_state_symbol, random_state: int) -> CloneFit:
        return refine_fit(seq.sym, seq.u, seq.lengths, seq.n_actions, seq.n_symbols,
                          split_state_symbol, clone_factor=self.clone_factor, prefix=self.prefix,
                          prefix_visits=self.prefix_visits, max_rounds=self.max_rounds,
                          settings=self.settings, random_state=random_state)

    def __repr__(self) -> str:
        return (f"EMRefinement(clone_factor={self.clone_factor}, prefix={self.prefix}, "
                f"prefix_visits={self.prefix_visits}, max_rounds={self.max_rounds}, "
                f"guard={self.guard}, settings={self.settings})")


class CSCGRefinement:
    """``refine="cscg"``: EM alone from phase 1 with CSCG's recipe (:func:`cscg_fit`), ignoring
    the split: ``clones_per_symbol`` clones per symbol, ``pseudocount`` per transition entry,
    Baum-Welch until it gains less than ``tol`` nats per step (0: until it stops rising) or
    ``max_iter`` iterations, then Viterbi training.  The comparison the paper asked for."""

    name = "cscg"

    def __init__(self, clones_per_symbol: int = 70, pseudocount: float = 2e-3,
                 max_iter: int = 1000, tol: float = 0.0):
        if isinstance(clones_per_symbol, bool) or not isinstance(clones_per_symbol, (int, np.integer)) \
                or clones_per_symbol < 1:
            raise ValueError(f"refine.clones_per_symbol must be a positive integer, got "
                             f"{clones_per_symbol!r}")
        if not (pseudocount > 0 and tol >= 0 and max_iter >= 1):
            raise ValueError("refine.pseudocount must be > 0, refine.tol >= 0, refine.max_iter >= 1")
        self.clones_per_symbol, self.pseudocount = int(clones_per_symbol), float(pseudocount)
        self.max_iter, self.tol = int(max_iter), float(tol)

    def fit(self, seq: SymbolSequence, split_state_symbol, random_state: int) -> CloneFit:
        return cscg_fit(seq.sym, seq.u, seq.lengths, seq.n_actions, seq.n_symbols,
                        clones_per_symbol=self.clones_per_symbol, pseudocount=self.pseudocount,
                        max_iter=self.max_iter, tol=self.tol, random_state=random_state)

    def __repr__(self) -> str:
        return (f"CSCGRefinement(clones_per_symbol={self.clones_per_symbol}, "
                f"pseudocount={self.pseudocount}, max_iter={self.max_iter}, tol={self.tol})")


REFINEMENTS = {cls.name: cls for cls in (EMRefinement, CSCGRefinement)}
