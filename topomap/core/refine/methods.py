"""The refinements after the paper's split: EM over clone-structured maps, and EM alone.

Both work on the discrete sequence phase 1 produces (a
:class:`~topomap.core.refine.sequence.SymbolSequence`).  GDS ids always get exactly one clone, so
GDS states stay unique and are never merged or split.  Transitions are CSCG's ``P(x'|x,u)`` (the
action is an input).

Each method is a scikit-learn estimator, the component :class:`topomap.MapLearner` takes:
``__init__`` stores its parameters as given, ``fit(sequence, split_state_symbol, random_state)``
checks them and returns the estimator, its learned attributes ending in ``_``: ``labels_`` (a
state per step), ``state_symbol_`` (the symbol id every state emits), ``n_states_`` and
``info_`` (the stages, stored in map.json).  The learner fits a clone, so its own ``refine``
never changes.  :meth:`provenance` is the text map.json stores as ``info["refine"]``.

* :class:`EMRefinement` (``refine="em"``) -- after the paper's split: EM learns the structure on a
  prefix with a clone budget sized by the split, the prefix grows until the structure settles,
  and every EM round is followed by hard re-assignment (Viterbi), removal of unused states,
  merging of bisimilar states and splitting of compound states
  (:mod:`topomap.core.refine.structure`).
* :class:`CSCGRefinement` (``refine="cscg"``) -- EM alone: many clones per symbol, random start,
  Baum-Welch to convergence, Viterbi training.

Both read every step's symbol as exact in a *hard round*; with ``evidence`` other than
``"hard"``, :meth:`CloneRefinement.fit` alternates hard rounds with the soft rounds of
:mod:`topomap.core.refine.soft` (the symbol read is evidence, misreads are corrected).  Their
settings are grouped by stage (:mod:`topomap.core.refine.settings`: ``hard``, ``growth``,
``soft``, ``reading``).  The clone-structured HMM they share (layout, Baum-Welch, Viterbi
training) is :mod:`topomap.core.refine.clones`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .budget import BUDGETS
from .clones import (Layout, capped_baum_welch, clone_budget, compact_labels, fit_clones,
                     init_from_path, random_counts, spread_states, states_to_clones,
                     viterbi_training)
from .first_stage import ROUGH, first_settings, rough_first, warm_acceleration
from .provenance import cscg_provenance, em_provenance
from .renamed import CSCG_RENAMED, EM_RENAMED
from .rounds import CAP_SURPRISE, CUT_SURPRISE, PAIRED_READ, CloneFit, CloneRefinement
from .sequence import SymbolSequence
from .settings import STARTS, CSCGRounds, Growth, HardRounds, Reading, SoftRounds
from .soft import successor_surprise
from .soft_states import successor_pairing
from .structure import merge_leftovers, merge_states, same_partition, split_compounds

__all__ = ["CloneFit", "CloneRefinement", "EMRefinement", "CSCGRefinement", "REFINEMENTS"]


class EMRefinement(CloneRefinement):
    """``refine="em"``: re-estimate every state jointly after the split.

    1. Stage 1 (``growth``): a prefix of ``max(prefix, prefix_visits x split states)`` steps,
       ``clone_factor`` x (split states of the symbol) + ``hard.spare`` clones per symbol (the
       ``budget``), from random counts (or the split's labelling: ``start``), Baum-Welch,
       Viterbi training; then bisimilar states are merged and compound states split.  A
       *rough* stage 1 (``first``, ``first_*``; :mod:`topomap.core.refine.first_stage`) has
       fewer clones and a capped Baum-Welch; a rough fit's ``info_`` holds ``"first": "rough"``.
    2. Growth: the prefix doubles, each stage warm-started from the last one's states plus
       ``hard.spare`` clones per symbol and ``hard.init_noise`` x uniform random counts; once two
       stages end with as many states (the structure has settled), the next stage takes all
       steps (after a rough stage 1: two growth stages, the last one's merges and splits
       changing none).  Where stage 1 shows many misreads, ``stage_cap`` caps them.
    3. On all steps, rounds repeat until EM's labelling is a fixpoint (nothing to merge or split),
       a round ends with the merged labelling of the round before (a split that EM and merging
       undo), or after ``hard.max_rounds``.

    Every EM round is a *hard round* (``hard``, :class:`~topomap.core.refine.settings.HardRounds`):
    Baum-Welch with ``row_prior`` per row of ``P(x'|x,u)`` (``row_prior / S`` per entry for ``S``
    clones), stopped by ``max_iter``, ``tol`` (and ``settle``), every warm-started round by
    SQUAREM's cycles with ``accelerate="squarem"`` (``"auto"``, the default: those after a rough
    stage 1); merges by ``merge_threshold`` and splits by ``split_z``
    (:mod:`topomap.core.refine.structure`).

    ``evidence`` (:data:`~topomap.core.refine.soft.EVIDENCE`): ``"auto"`` (default) corrects
    misread symbols when the first soft round finds some (the first hard round stops before
    stage 3 where its labelling already shows misreads: :meth:`_first_hard_round`), ``"soft"``
    always, ``"hard"`` never; ``soft`` and ``reading`` set the soft rounds
    (:class:`~topomap.core.refine.settings.SoftRounds`,
    :class:`~topomap.core.refine.settings.Reading`).  Each group is its settings object or a
    mapping of some of its fields (``hard={"max_iter": 40}``); the flat parameters of before 0.3
    (``max_iter=40``) still work until 0.4, with a ``FutureWarning``
    (:data:`~topomap.core.refine.renamed.EM_RENAMED`).

    With ``guard`` (the default) the learner keeps the refined map only if its BIC (actions and
    transitions) is no worse than the split map's: refinement never trades a good split map for a
    fragmented one.
    """

    name = "em"
    _groups = {"hard": HardRounds, "growth": Growth, "soft": SoftRounds, "reading": Reading}
    renamed_params = EM_RENAMED

    def __init__(self, *, evidence: str = "auto", guard: bool = True,
                 hard: HardRounds | Mapping = HardRounds(), growth: Growth | Mapping = Growth(),
                 soft: SoftRounds | Mapping = SoftRounds(),
                 reading: Reading | Mapping = Reading(), **renamed):
        self.evidence = evidence
        self.guard = guard
        self._store({"hard": hard, "growth": growth, "soft": soft, "reading": reading}, renamed)

    def provenance(self) -> str:
        """The text map.json stores as ``info["refine"]``: the refinement and its settings in the
        file's fixed form (:mod:`topomap.core.refine.provenance`)."""
        return em_provenance(self.settings(), self.evidence, self.guard)

    def _hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                    init=None, split_labels=None, *, cycle: bool = False) -> CloneFit:
        """The refinement taking every step's symbol as exact (stages 1 to 3 above; from
        ``init`` instead of stages 1 and 2 when given; ``cycle``: ``init`` is a soft round's
        labelling of the symbols it corrected, :meth:`_stages`)."""
        return _finish(self._stages(seq, split_state_symbol, random_state, init, split_labels,
                                    cycle=cycle))

    def _first_hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                          init=None, split_labels=None, *, cycle: bool = False):
        """:meth:`_hard_round`, cut short before stage 3 when the labelling of all steps stage 2
        gives already shows misreads: its successor surprise
        (:func:`~topomap.core.refine.soft.successor_surprise`) at least ``CUT_SURPRISE`` x
        ``reading.detect`` (with ``evidence="soft"``, the first round always).  Stage 3's rounds
        would not settle on misread symbols; the soft rounds start from that labelling instead,
        and the fit's ``resume`` finishes the round should the first soft round find no
        misreads.  The hard rounds on a soft round's corrected symbols (``cycle``) are cut by
        the same test: where the soft round left misreads, the next one corrects them.  A round
        from ``init`` is never cut."""
        if init is not None:  # its rounds are few and short: nothing to gain by a cut
            return self._hard_round(seq, split_state_symbol, random_state, init)
        stages = self._stages(seq, split_state_symbol, random_state, None, split_labels)
        labels, state_symbol, info = next(stages)
        surprise = successor_surprise(seq, labels)
        detect = self.settings_.reading.detect
        if (self.evidence == "soft" and not cycle) or surprise >= CUT_SURPRISE * detect:
            return CloneFit(labels, state_symbol, {**info, "rounds_on_all_steps": 0, "cut": True},
                            resume=lambda: _finish(stages))
        return _finish(stages)

    def _stages(self, seq: SymbolSequence, split_state_symbol, random_state: int, init=None,
                split_labels=None, *, cycle: bool = False):
        """Stages 1 to 3 as a generator: it yields ``(labels, state_symbol, info)`` of stage 2's
        last labelling, then returns the round's :class:`CloneFit` (:func:`_finish`).  With
        ``init``, a labelling ``(labels, state_symbol)`` of all steps, one EM round on all steps
        started from it (:meth:`_warm_round`) replaces stages 1 and 2, and stage 3's rounds
        are short, :data:`WARM_ITER` EM iterations, and at most :data:`WARM_ROUNDS`; from a
        soft round's labelling (``cycle``) as many as ``hard.max_rounds``, each merging the
        duplicates the soft round's states leave
        (:func:`~topomap.core.refine.structure.merge_leftovers`)."""
        rng = np.random.default_rng(random_state)
        hard, growth = self.settings_.hard, self.settings_.growth
        if init is not None:
            rounds_cap = hard.max_rounds if cycle else min(hard.max_rounds, WARM_ROUNDS)
            short = {"max_rounds": rounds_cap, "max_iter": min(hard.max_iter, WARM_ITER)}
            labels, state_symbol, iters = self._warm_round(seq, *init, rng, short["max_iter"])
            stages = [(seq.T, int(state_symbol.size), iters)]
            yield labels, state_symbol, {"stages": list(stages), "warm_start": True}
            (labels, state_symbol), rounds = self._rounds_on_all_steps(
                seq, labels, state_symbol, rng, stages, **short, leftovers=cycle)
            return CloneFit(labels, state_symbol, {"stages": stages, "warm_start": True,
                                                   "rounds_on_all_steps": rounds})
        split_state_symbol = np.asarray(split_state_symbol)
        n_split = int(np.sum(split_state_symbol >= 0))
        n = min(max(growth.prefix, growth.prefix_visits * n_split), seq.T)
        rough = rough_first(growth, n, seq.T, getattr(self, "ambiguity_", None))
        labels, state_symbol, iters = self._first_round(seq.head(n), split_state_symbol, rng,
                                                        split_labels, rough=rough)
        stages, cap = [(n, int(state_symbol.size), iters)], self._stage_cap(seq.head(n), labels)
        first = {"first": "rough"} if rough else {}
        while n < seq.T:  # growth: the prefix doubles, or takes all steps once settled
            _, split, changed = self._restructure(seq.head(n), labels, state_symbol)
            settled = (len(stages) > 1 + rough and stages[-1][1] == stages[-2][1]
                       and not (rough and changed))
            n = seq.T if settled else min(2 * n, seq.T)
            labels, state_symbol, iters = self._warm_round(seq.head(n), *split, rng, cap=cap,
                                                           rough=rough)
            stages.append((n, int(state_symbol.size), iters))
        yield labels, state_symbol, {"stages": list(stages), **first}
        (labels, state_symbol), rounds = self._rounds_on_all_steps(seq, labels, state_symbol,
                                                                   rng, stages, rough=rough)
        return CloneFit(labels, state_symbol, {"stages": stages, "rounds_on_all_steps": rounds,
                                               **first})

    def _stage_cap(self, prefix: SymbolSequence, labels):
        """``(growth.stage_cap, growth.stage_rtol)`` for the growth stages of a hard round whose
        first stage's labelling ``labels`` of the ``prefix`` already shows many misreads
        (successor surprise at least ``CAP_SURPRISE`` x ``reading.detect``), else None: on
        misread symbols the stages' Baum-Welch does not settle by ``hard.tol`` and runs its
        ``hard.max_iter`` iterations for little gain.  None with ``evidence="hard"`` or
        ``growth.stage_cap`` 0."""
        st = self.settings_
        cap = st.growth.stage_cap
        if self.evidence == "hard" or not cap or cap >= st.hard.max_iter:
            return None
        if successor_surprise(prefix, labels) < CAP_SURPRISE * st.reading.detect:
            return None
        if successor_pairing(prefix, labels) >= PAIRED_READ:  # a view cut in two: uncapped
            return None
        return cap, st.growth.stage_rtol

    def _first_round(self, seq: SymbolSequence, split_state_symbol, rng, split_labels=None, *,
                     rough: bool = False):
        """Stage 1: the clones of ``growth.budget`` (:mod:`topomap.core.refine.budget`), from
        random counts, by plain EM (``hard.accelerate`` is for the warm-started rounds: from a
        random start it is EM's path that picks the optimum, and a jump can pick another).  With
        ``growth.start="split"``, from the split's labelling of the prefix (``split_labels``,
        every split state a clone, ``hard.spare`` more per symbol: :meth:`_warm_round`); with
        ``"split_budget"``, on the clones of the budget: a symbol's clones shared out among its
        split states, every step of a state on one of its clones at random
        (:func:`~topomap.core.refine.clones.spread_states`), so EM can still tell apart places
        the split joined; with ``"auto"``, as ``"split"`` where the split's labelling of the
        prefix predicts the next symbol of all but a ``SPLIT_TRUST`` share of its transitions
        (:func:`~topomap.core.refine.soft.successor_surprise`), else from random counts.  From
        the split, the warm-started EM (``hard.accelerate`` applies; ``"auto"`` is plain EM).
        The hard rounds on the symbols a soft round corrected have no split labelling: random
        counts.  ``rough``: on a short prefix
        (:func:`~topomap.core.refine.first_stage.first_settings`)."""
        hard, growth = self.settings_.hard, self.settings_.growth
        start = growth.start
        from_split = start != "random" and split_labels is not None  # none: corrected
        if from_split:
            labels, state_symbol, _ = compact_labels(split_labels[0][:seq.T], split_labels[1])
            from_split = start != "auto" or successor_surprise(seq, labels) < SPLIT_TRUST
        if from_split and start in ("split", "auto"):
            return self._warm_round(seq, labels, state_symbol, rng)
        factor, cap = first_settings(growth, rough)
        budget = BUDGETS[growth.budget](split_state_symbol, seq, factor, hard.spare)
        if not from_split:
            lay = seq.layout(budget)
            return self._fit_layout(lay, random_counts(lay, rng), cap=cap)
        budget = np.maximum(budget, np.bincount(state_symbol, minlength=budget.size))
        lay = seq.layout(budget)
        path = spread_states(labels, state_symbol, budget, rng)
        return self._fit_layout(lay, init_from_path(lay, path, seq.T, rng, hard.init_noise),
                                cap=cap, accelerate=warm_acceleration(hard.accelerate, False))

    def _warm_round(self, seq: SymbolSequence, labels, state_symbol, rng, max_iter=None,
                    cap=None, *, rough: bool = False):
        """One EM round on ``seq`` started from a labelling of its first ``labels.size`` steps:
        each state becomes a clone, every K-means symbol gets ``hard.spare`` more (at most
        ``max_iter`` EM iterations, default: ``hard.max_iter``; ``cap`` as for
        :meth:`_fit_layout`; accelerated as ``hard.accelerate`` says after a stage 1 that was
        ``rough`` or not, :func:`~topomap.core.refine.first_stage.warm_acceleration`)."""
        hard = self.settings_.hard
        budget, path = states_to_clones(labels, state_symbol, seq.n_ids, seq.n_symbols,
                                        hard.spare)
        lay = seq.layout(budget)
        return self._fit_layout(lay, init_from_path(lay, path, labels.size, rng,
                                                    hard.init_noise), max_iter, cap,
                                accelerate=warm_acceleration(hard.accelerate, rough))

    def _fit_layout(self, lay: Layout, init, max_iter=None, cap=None, *,
                    accelerate: str = "none"):
        """Baum-Welch then Viterbi training on ``lay`` from ``init`` (at most ``max_iter`` EM
        iterations, default: ``hard.max_iter``; with ``cap``, ``(iterations, rtol)``, Baum-Welch
        as :func:`capped_baum_welch`; ``accelerate`` as there); returns the labels and state
        symbols of the clones the path uses, and the number of EM iterations."""
        hard = self.settings_.hard
        max_iter = hard.max_iter if max_iter is None else max_iter
        pseudocount = hard.row_prior / lay.n_clones
        if cap is None or cap[0] >= max_iter:
            labels, state_symbol, em_history, _ = fit_clones(
                lay, init, pseudocount, max_iter=max_iter, tol=hard.tol, prune=hard.prune,
                settle=hard.settle, accelerate=accelerate)
            return labels, state_symbol, len(em_history)
        counts, em_history = capped_baum_welch(lay, init, pseudocount, max_iter=max_iter,
                                               tol=hard.tol, cap=cap[0], rtol=cap[1],
                                               prune=hard.prune, settle=hard.settle,
                                               accelerate=accelerate)
        path, _, _ = viterbi_training(lay, counts, False)
        labels, state_symbol, _ = compact_labels(path, lay.clone_symbol)
        return labels, state_symbol, len(em_history)

    def _restructure(self, seq: SymbolSequence, labels, state_symbol, leftovers: bool = False):
        """Merge bisimilar states (``leftovers``: and the duplicates the first pass leaves,
        :func:`~topomap.core.refine.structure.merge_leftovers`), then split compound ones.
        Returns the merged labelling, the split labelling (each as ``(labels, state_symbol)``)
        and whether either step changed anything."""
        has_prev, has_next = seq.masks()
        hard = self.settings_.hard
        merge = merge_leftovers if leftovers else merge_states
        merged = merge(labels, state_symbol, seq.u, has_next, hard.merge_threshold)
        split = split_compounds(*merged, seq.u, has_prev, has_next, seq.n_actions,
                                z=hard.split_z, splittable=merged[1] < seq.n_symbols)
        changed = split[1].size > merged[1].size or merged[1].size < state_symbol.size
        return merged, split, changed

    def _rounds_on_all_steps(self, seq: SymbolSequence, labels, state_symbol, rng, stages,
                             max_rounds: int | None = None, max_iter: int | None = None,
                             leftovers: bool = False, *, rough: bool = False):
        """Stage 3: rounds on all steps until nothing is merged or split, a round's merged
        labelling is the one of the round before, or ``max_rounds`` rounds (EM rounds of at most
        ``max_iter`` iterations; defaults: ``hard.max_rounds``, ``hard.max_iter``; ``rough``: as
        for :meth:`_warm_round`); appends every EM round to ``stages``.  Returns the last merged
        labelling and the number of rounds."""
        previous, rounds = None, 0
        max_rounds = self.settings_.hard.max_rounds if max_rounds is None else max_rounds
        while True:
            merged, split, changed = self._restructure(seq, labels, state_symbol, leftovers)
            rounds += 1
            if not changed or rounds >= max_rounds or (
                    previous is not None and same_partition(previous, merged[0])):
                return merged, rounds
            previous = merged[0]
            labels, state_symbol, iters = self._warm_round(seq, *split, rng, max_iter,
                                                           rough=rough)
            stages.append((seq.T, int(state_symbol.size), iters))


#: ``growth.start="auto"`` starts from the split where its labelling of the prefix has a successor
#: surprise below this.  Measured on all 10,000 steps of the bench_em worlds (seed 0): the
#: office 0.0 and the crossing 0.012 gain from the split start (half the E-steps); the random
#: graph (0.037) neither gains nor loses; MiniGrid Empty (0.048-0.051: the split joins places
#: the next view does not tell apart) loses ARI, 1.0 -> 0.82-0.92; the 8 x 6 and 12 x 12 rooms
#: (about 0.2) take 1.4 x the E-steps
SPLIT_TRUST = 0.02

#: rounds on all steps at most after a warm start (``init``), and the EM iterations of each: the
#: labelling it starts from has had its rounds already (the last map's), so a few short EM
#: rounds with their merges and splits bring it to the steps it had not seen.  A hard round on
#: a soft round's corrections (``cycle``) runs up to ``hard.max_rounds`` of them instead: with 3,
#: gridroom 8x6 at 18.2 % misreads, seed 2, kept states the later soft rounds drained in 69
#: E-steps instead of 27 (``benchmarks/notes/misread-views.md``, 2026-12-02)
WARM_ROUNDS = 3
WARM_ITER = 15

def _finish(stages) -> CloneFit:
    """The return of the generator ``stages`` (:meth:`EMRefinement._stages`), run to its end."""
    while True:
        try:
            next(stages)
        except StopIteration as done:
            return done.value


class CSCGRefinement(CloneRefinement):
    """``refine="cscg"``: EM alone from phase 1 with CSCG's recipe (George et al., 2021), written
    afresh on the clone kernels, ignoring the split; the comparison the paper asked for.

    ``hard`` (:class:`~topomap.core.refine.settings.CSCGRounds`): ``clones_per_symbol`` clones
    for every K-means symbol (one per GDS id), random uniform initial counts, Baum-Welch with
    ``pseudocount`` per transition entry until it gains less than ``tol`` nats per step (0:
    CSCG's rule, until the log-likelihood stops rising; checked from iteration 10 on) or
    ``max_iter`` iterations, then Viterbi training without pseudocount; clones the final Viterbi
    path never visits are dropped.  ``evidence``, ``soft`` and ``reading`` as for
    :class:`EMRefinement` (``split_state_symbol`` of ``fit`` only sizes the soft rounds'
    pruning); the flat parameters of before 0.3 (``max_iter=30``) still work until 0.4
    (:data:`~topomap.core.refine.renamed.CSCG_RENAMED`).
    """

    name = "cscg"
    _groups = {"hard": CSCGRounds, "soft": SoftRounds, "reading": Reading}
    renamed_params = CSCG_RENAMED

    def __init__(self, *, evidence: str = "auto", hard: CSCGRounds | Mapping = CSCGRounds(),
                 soft: SoftRounds | Mapping = SoftRounds(),
                 reading: Reading | Mapping = Reading(), **renamed):
        self.evidence = evidence
        self._store({"hard": hard, "soft": soft, "reading": reading}, renamed)

    def provenance(self) -> str:
        """The text map.json stores as ``info["refine"]``: the refinement and its settings in the
        file's fixed form (:mod:`topomap.core.refine.provenance`)."""
        return cscg_provenance(self.settings(), self.evidence)

    def _hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                    init=None, split_labels=None, *, cycle: bool = False) -> CloneFit:
        """EM alone taking every step's symbol as exact (neither the split, ``init``,
        ``split_labels`` nor ``cycle`` is used)."""
        hard = self.settings_.hard
        lay = seq.layout(clone_budget(seq.n_symbols, seq.n_gds, hard.clones_per_symbol))
        rng = np.random.default_rng(random_state)
        labels, state_symbol, em, viterbi = fit_clones(
            lay, random_counts(lay, rng), float(hard.pseudocount), max_iter=hard.max_iter,
            tol=float(hard.tol))
        info = {"em_iterations": len(em), "em_loglik": em[-1], "viterbi_iterations": len(viterbi),
                "viterbi_logp": viterbi[-1], "clones": lay.n_clones}
        return CloneFit(labels, state_symbol, info)


REFINEMENTS = {cls.name: cls for cls in (EMRefinement, CSCGRefinement)}
