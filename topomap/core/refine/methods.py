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
:mod:`topomap.core.refine.soft` (the symbol read is evidence, misreads are corrected), set by the
``soft`` parameter (:class:`~topomap.core.refine.soft.SoftSettings`).  The clone-structured HMM
they share (layout, Baum-Welch, Viterbi training) is :mod:`topomap.core.refine.clones`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..checks import check_count
from .accelerate import check_accelerate
from .budget import BUDGETS
from .clones import (Layout, capped_baum_welch, clone_budget, compact_labels, fit_clones,
                     init_from_path, random_counts, spread_states, states_to_clones,
                     viterbi_training)
from .first_stage import FIRSTS, ROUGH, first_settings, rough_first
from .rounds import CAP_SURPRISE, CloneFit, CloneRefinement, _check
from .sequence import SymbolSequence
from .soft import SoftSettings, soft_settings, successor_surprise
from .structure import merge_states, same_partition, split_compounds

__all__ = ["CloneFit", "CloneRefinement", "EMRefinement", "CSCGRefinement", "REFINEMENTS"]


#: the knobs of every EM round of :class:`EMRefinement`, in the order :meth:`provenance` lists
_EM_ROUND = ("row_prior", "tol", "max_iter", "prune", "merge_threshold", "split_z", "spare",
             "init_noise")


class EMRefinement(CloneRefinement):
    """``refine="em"``: re-estimate every state jointly after the split.

    1. Structure on a prefix of ``max(prefix, prefix_visits x split states)`` steps (about
       ``prefix_visits`` visits per place): ``clone_factor`` x (split states of the symbol) +
       ``spare`` clones per symbol, random start, Baum-Welch, Viterbi training; then bisimilar
       states are merged and compound states split.
    2. Growth: the prefix doubles, each stage warm-started from the last one's states plus
       ``spare`` clones per symbol and ``init_noise`` x uniform random counts; once two stages end
       with as many states (the structure has settled), the next stage takes all steps (after a
       rough stage 1, below: two growth stages, the last one's merges and splits changing none).
    3. On all steps, rounds repeat until EM's labelling is a fixpoint (nothing to merge or split),
       a round ends with the merged labelling of the round before (a split that EM and merging
       undo), or after ``max_rounds``.

    Every EM round: Baum-Welch with a pseudocount mass of ``row_prior`` per row of ``P(x'|x,u)``
    (``row_prior / S`` per entry for ``S`` clones, so the prior does not grow with the clone count:
    CSCG's fixed 2e-3 per entry weighs 6 counts per row at 3,000 clones and folds FourRooms'
    congruent rooms onto each other), stopped after ``max_iter`` iterations or when it gains less
    than ``tol`` nats per step (the structure moves, not EM's slow tail, finish the job), and with
    ``settle`` > 0 (default 0: off) also once its decoded path has settled: every step's most
    probable clone changed on fewer than a ``settle`` share of the steps at three E-steps in a
    row (:class:`~topomap.core.refine.clones.SettledPath`; from the 11th iteration on).  That
    saves E-steps but not always the map: the slow tail also moves the mass of one place's
    duplicate clones onto one, and cut short it can leave duplicates the merges do not join.
    ``accelerate="squarem"`` (default ``"none"``) runs the Baum-Welch of every warm-started round
    (stages 2 and 3) as SQUAREM's cycles on the expected counts
    (:mod:`topomap.core.refine.accelerate`): the same stops, in E-steps, judged on each cycle's
    plain EM step; stage 1, from random counts, stays plain EM.  ``prune`` drops filtered
    probabilities below it (:func:`topomap.core.refine.kernels.clone_forward`).
    ``merge_threshold`` is the G-test threshold of merging bisimilar states (negative: never
    merge; 6.63 = chi-square(1) at 1 %) and ``split_z`` the normal score of splitting compound
    states (``inf``: never split; 3.09: p = 0.001).

    ``budget`` sizes the first stage's clones (:data:`topomap.core.refine.budget.BUDGETS`):
    ``"evidence"`` (default) gives a view at least as many clones as the data's lower bound on the
    places showing it (the same action sequence from the view followed by that many different
    symbol sequences), ``"split"`` only ``clone_factor`` x its split states + ``spare``.
    ``start`` (:data:`STARTS`): what stage 1 starts from, random counts (default) or the split's
    labelling ``split_labels`` of :meth:`fit` (``"split"``, ``"split_budget"``, ``"auto"``:
    :meth:`_first_round`).  A *rough* stage 1 (:mod:`topomap.core.refine.first_stage`):
    ``first_factor`` (default 1) replaces ``clone_factor`` and its Baum-Welch stops after
    ``first_iter`` (default 25) iterations unless the last still gained ``first_rtol`` x
    |log-likelihood| (:func:`~topomap.core.refine.clones.capped_baum_welch`; each 0: off).  It
    applies only on a prefix of at most :data:`ROUGH` of the steps (the growth stages refit every
    state on many more), and by ``first``: ``"auto"`` (default) where the ``ambiguity`` passed to
    :meth:`fit` (the learner's estimate of the share of misread symbols) is below
    :data:`~topomap.core.refine.first_stage.AMBIGUITY_BAR` (none given: never), ``"rough"``
    always, ``"plain"`` never.  A rough fit's ``info_`` holds ``"first": "rough"``.

    ``evidence`` (:data:`~topomap.core.refine.soft.EVIDENCE`): ``"auto"`` (default) corrects
    misread symbols when the first soft round finds some (the first hard round stops before
    stage 3 where its labelling already shows misreads: :meth:`_first_hard_round`; where the
    prefix shows many, the growth stages stop after ``soft.stage_cap`` EM iterations, 0 and
    off by default: :meth:`_stage_cap`), ``"soft"`` always, ``"hard"`` never;
    ``soft`` holds the soft rounds' settings (:class:`~topomap.core.refine.soft.SoftSettings`, or
    a mapping of some of its fields, e.g. ``{"conf_warmup": 10}``).

    With ``guard`` (the default) the learner keeps the refined map only if its BIC (actions and
    transitions) is no worse than the split map's: refinement never trades a good split map for a
    fragmented one (with many actions and few visits per place and action, the split test of
    :func:`topomap.core.refine.structure.split_compounds` finds differences in noise).
    """

    name = "em"

    def __init__(self, *, clone_factor: int = 2, prefix: int = 2000, prefix_visits: int = 40,
                 max_rounds: int = 8, row_prior: float = 0.5, tol: float = 1e-6,
                 max_iter: int = 50, settle: float = 0.0, prune: float = 1e-4,
                 merge_threshold: float = 6.63, split_z: float = 3.09, spare: int = 2,
                 init_noise: float = 1.0, guard: bool = True, budget: str = "evidence",
                 accelerate: str = "none", start: str = "random", first: str = "auto",
                 first_factor: int = 1, first_iter: int = 25, first_rtol: float = float("inf"),
                 evidence: str = "auto", soft: SoftSettings | Mapping = SoftSettings()):
        self.clone_factor = clone_factor
        self.prefix = prefix
        self.prefix_visits = prefix_visits
        self.max_rounds = max_rounds
        self.row_prior = row_prior
        self.tol = tol
        self.max_iter = max_iter
        self.settle = settle
        self.prune = prune
        self.merge_threshold = merge_threshold
        self.split_z = split_z
        self.spare = spare
        self.init_noise = init_noise
        self.guard = guard
        self.budget = budget
        self.accelerate = accelerate
        self.start = start
        self.first = first
        self.first_factor = first_factor
        self.first_iter = first_iter
        self.first_rtol = first_rtol
        self.evidence = evidence
        self.soft = soft

    def check_params(self) -> None:
        for param in ("clone_factor", "prefix", "max_rounds", "max_iter"):
            check_count(getattr(self, param), param)
        for param in ("prefix_visits", "spare", "first_factor", "first_iter"):
            check_count(getattr(self, param), param, minimum=0)
        _check(self.row_prior > 0, "row_prior", self.row_prior, "> 0")
        _check(self.tol >= 0, "tol", self.tol, ">= 0")
        _check(self.first_rtol >= 0, "first_rtol", self.first_rtol, ">= 0")
        _check(0 <= self.settle <= 1, "settle", self.settle, "in [0, 1]")
        _check(0 <= self.prune < 1, "prune", self.prune, "in [0, 1)")
        _check(self.budget in BUDGETS, "budget", self.budget, f"one of {', '.join(BUDGETS)}")
        check_accelerate(self.accelerate)
        _check(self.start in STARTS, "start", self.start, f"one of {', '.join(STARTS)}")
        _check(self.first in FIRSTS, "first", self.first, f"one of {', '.join(FIRSTS)}")
        super().check_params()

    def provenance(self) -> str:
        """The text map.json stores as ``info["refine"]``: the refinement and its settings in the
        file's fixed form -- the EM round's knobs grouped as ``settings=EMSettings(...)`` (a
        label of the file format, not a class), the other settings only where not the default."""
        rounds = ", ".join(f"{k}={getattr(self, k)!r}" for k in _EM_ROUND)
        changed = "" if self.budget == "evidence" else f"budget={self.budget!r}, "
        changed += f"settle={self.settle!r}, " if self.settle else ""
        changed += "" if self.accelerate == "none" else f"accelerate={self.accelerate!r}, "
        changed += "" if self.start == "random" else f"start={self.start!r}, "
        for k, default in (("first", "auto"), ("first_factor", 1), ("first_iter", 25),
                           ("first_rtol", float("inf"))):
            changed += "" if getattr(self, k) == default else f"{k}={getattr(self, k)!r}, "
        changed += "" if self.evidence == "auto" else f"evidence={self.evidence!r}, "
        soft = self._provenance_soft()
        changed += f"{soft}, " if soft else ""
        return (f"EMRefinement(clone_factor={self.clone_factor}, prefix={self.prefix}, "
                f"prefix_visits={self.prefix_visits}, max_rounds={self.max_rounds}, "
                f"guard={bool(self.guard)}, {changed}settings=EMSettings({rounds}))")

    def _hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                    init=None, split_labels=None) -> CloneFit:
        """The refinement taking every step's symbol as exact (stages 1 to 3 above; from
        ``init`` instead of stages 1 and 2 when given)."""
        return _finish(self._stages(seq, split_state_symbol, random_state, init, split_labels))

    def _first_hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                          init=None, split_labels=None, *, cycle: bool = False):
        """:meth:`_hard_round`, cut short before stage 3 when the labelling of all steps stage 2
        gives already shows misreads: its successor surprise
        (:func:`~topomap.core.refine.soft.successor_surprise`) at least ``CUT_SURPRISE`` x
        ``soft.detect`` (with ``evidence="soft"``, the first round always).  Stage 3's rounds
        would not settle on misread symbols; the soft rounds start from that labelling instead,
        and the fit's ``resume`` finishes the round should the first soft round find no
        misreads.  The hard rounds on a soft round's corrected symbols (``cycle``) are cut by
        the same test: where the soft round left misreads, the next one corrects them.  A round
        from ``init`` is never cut."""
        if init is not None:  # its rounds are few and short: nothing to gain by a cut
            return self._hard_round(seq, split_state_symbol, random_state, init)
        s = soft_settings(self.soft)
        stages = self._stages(seq, split_state_symbol, random_state, None, split_labels)
        labels, state_symbol, info = next(stages)
        surprise = successor_surprise(seq, labels)
        if (self.evidence == "soft" and not cycle) or surprise >= CUT_SURPRISE * s.detect:
            return CloneFit(labels, state_symbol, {**info, "rounds_on_all_steps": 0, "cut": True},
                            resume=lambda: _finish(stages))
        return _finish(stages)

    def _stages(self, seq: SymbolSequence, split_state_symbol, random_state: int, init=None,
                split_labels=None):
        """Stages 1 to 3 as a generator: it yields ``(labels, state_symbol, info)`` of stage 2's
        last labelling, then returns the round's :class:`CloneFit` (:func:`_finish`).  With
        ``init``, a labelling ``(labels, state_symbol)`` of all steps, one EM round on all steps
        started from it (:meth:`_warm_round`) replaces stages 1 and 2, and stage 3 is kept
        short: at most :data:`WARM_ROUNDS` rounds of :data:`WARM_ITER` EM iterations."""
        rng = np.random.default_rng(random_state)
        if init is not None:
            short = {"max_rounds": min(self.max_rounds, WARM_ROUNDS),
                     "max_iter": min(self.max_iter, WARM_ITER)}
            labels, state_symbol, iters = self._warm_round(seq, *init, rng, short["max_iter"])
            stages = [(seq.T, int(state_symbol.size), iters)]
            yield labels, state_symbol, {"stages": list(stages), "warm_start": True}
            (labels, state_symbol), rounds = self._rounds_on_all_steps(
                seq, labels, state_symbol, rng, stages, **short)
            return CloneFit(labels, state_symbol, {"stages": stages, "warm_start": True,
                                                   "rounds_on_all_steps": rounds})
        split_state_symbol = np.asarray(split_state_symbol)
        n_split = int(np.sum(split_state_symbol >= 0))
        n = min(max(self.prefix, self.prefix_visits * n_split), seq.T)
        rough = rough_first(self, n, seq.T, getattr(self, "ambiguity_", None))
        labels, state_symbol, iters = self._first_round(seq.head(n), split_state_symbol, rng,
                                                        split_labels, rough=rough)
        stages, cap = [(n, int(state_symbol.size), iters)], self._stage_cap(seq.head(n), labels)
        first = {"first": "rough"} if rough else {}
        while n < seq.T:  # growth: the prefix doubles, or takes all steps once settled
            _, split, changed = self._restructure(seq.head(n), labels, state_symbol)
            settled = (len(stages) > 1 + rough and stages[-1][1] == stages[-2][1]
                       and not (rough and changed))
            n = seq.T if settled else min(2 * n, seq.T)
            labels, state_symbol, iters = self._warm_round(seq.head(n), *split, rng, cap=cap)
            stages.append((n, int(state_symbol.size), iters))
        yield labels, state_symbol, {"stages": list(stages), **first}
        (labels, state_symbol), rounds = self._rounds_on_all_steps(seq, labels, state_symbol,
                                                                   rng, stages)
        return CloneFit(labels, state_symbol, {"stages": stages, "rounds_on_all_steps": rounds,
                                               **first})

    def _stage_cap(self, prefix: SymbolSequence, labels):
        """``(soft.stage_cap, soft.stage_rtol)`` for the growth stages of a hard round whose
        first stage's labelling ``labels`` of the ``prefix`` already shows many misreads
        (successor surprise at least ``CAP_SURPRISE`` x ``soft.detect``), else None: on misread
        symbols the stages' Baum-Welch does not settle by ``tol`` and runs its ``max_iter``
        iterations for little gain.  None with ``evidence="hard"`` or ``soft.stage_cap`` 0."""
        s = soft_settings(self.soft)
        if self.evidence == "hard" or not s.stage_cap or s.stage_cap >= self.max_iter:
            return None
        if successor_surprise(prefix, labels) < CAP_SURPRISE * s.detect:
            return None
        return s.stage_cap, s.stage_rtol

    def _first_round(self, seq: SymbolSequence, split_state_symbol, rng, split_labels=None, *,
                     rough: bool = False):
        """Stage 1: the clones of ``budget`` (:mod:`topomap.core.refine.budget`), from random
        counts, by plain EM (``accelerate`` is for the warm-started rounds: from a random start it
        is EM's path that picks the optimum, and a jump can pick another).  With ``start="split"``,
        from the split's labelling of the prefix (``split_labels``, every split state a clone,
        ``spare`` more per symbol: :meth:`_warm_round`); with ``"split_budget"``, on the clones of
        ``budget``: a symbol's clones shared out among its split states, every step of a state on
        one of its clones at random (:func:`~topomap.core.refine.clones.spread_states`), so EM can
        still tell apart places the split joined; with ``"auto"``, as ``"split"`` where the split's
        labelling of the prefix predicts the next symbol of all but a ``SPLIT_TRUST`` share of its
        transitions (:func:`~topomap.core.refine.soft.successor_surprise`), else from random counts.
        From the split, the warm-started EM (``accelerate`` applies).  The hard rounds on the
        symbols a soft round corrected have no split labelling: random counts.  ``rough``: on a
        short prefix (:func:`~topomap.core.refine.first_stage.first_settings`)."""
        from_split = self.start != "random" and split_labels is not None  # none: corrected
        if from_split:
            labels, state_symbol, _ = compact_labels(split_labels[0][:seq.T], split_labels[1])
            from_split = self.start != "auto" or successor_surprise(seq, labels) < SPLIT_TRUST
        if from_split and self.start in ("split", "auto"):
            return self._warm_round(seq, labels, state_symbol, rng)
        factor, cap = first_settings(self, rough)
        budget = BUDGETS[self.budget](split_state_symbol, seq, factor, self.spare)
        if not from_split:
            lay = seq.layout(budget)
            return self._fit_layout(lay, random_counts(lay, rng), cap=cap, warm=False)
        budget = np.maximum(budget, np.bincount(state_symbol, minlength=budget.size))
        lay = seq.layout(budget)
        path = spread_states(labels, state_symbol, budget, rng)
        return self._fit_layout(lay, init_from_path(lay, path, seq.T, rng, self.init_noise),
                                cap=cap)

    def _warm_round(self, seq: SymbolSequence, labels, state_symbol, rng, max_iter=None,
                    cap=None):
        """One EM round on ``seq`` started from a labelling of its first ``labels.size`` steps:
        each state becomes a clone, every K-means symbol gets ``spare`` more (at most
        ``max_iter`` EM iterations, default: the parameter's; ``cap`` as for
        :meth:`_fit_layout`)."""
        budget, path = states_to_clones(labels, state_symbol, seq.n_ids, seq.n_symbols,
                                        self.spare)
        lay = seq.layout(budget)
        return self._fit_layout(lay, init_from_path(lay, path, labels.size, rng,
                                                    self.init_noise), max_iter, cap)

    def _fit_layout(self, lay: Layout, init, max_iter=None, cap=None, *, warm: bool = True):
        """Baum-Welch then Viterbi training on ``lay`` from ``init`` (at most ``max_iter`` EM
        iterations, default: the parameter's; with ``cap``, ``(iterations, rtol)``, Baum-Welch
        as :func:`capped_baum_welch`; ``accelerate`` only where ``warm``); returns the labels and
        state symbols of the clones the path uses, and the number of EM iterations."""
        max_iter = self.max_iter if max_iter is None else max_iter
        accelerate = self.accelerate if warm else "none"
        pseudocount = self.row_prior / lay.n_clones
        if cap is None or cap[0] >= max_iter:
            labels, state_symbol, em_history, _ = fit_clones(
                lay, init, pseudocount, max_iter=max_iter, tol=self.tol, prune=self.prune,
                settle=self.settle, accelerate=accelerate)
            return labels, state_symbol, len(em_history)
        counts, em_history = capped_baum_welch(lay, init, pseudocount, max_iter=max_iter,
                                               tol=self.tol, cap=cap[0], rtol=cap[1],
                                               prune=self.prune, settle=self.settle,
                                               accelerate=accelerate)
        path, _, _ = viterbi_training(lay, counts, False)
        labels, state_symbol, _ = compact_labels(path, lay.clone_symbol)
        return labels, state_symbol, len(em_history)

    def _restructure(self, seq: SymbolSequence, labels, state_symbol):
        """Merge bisimilar states, then split compound ones.  Returns the merged labelling, the
        split labelling (each as ``(labels, state_symbol)``) and whether either step changed
        anything."""
        has_prev, has_next = seq.masks()
        merged = merge_states(labels, state_symbol, seq.u, has_next, self.merge_threshold)
        split = split_compounds(*merged, seq.u, has_prev, has_next, seq.n_actions,
                                z=self.split_z, splittable=merged[1] < seq.n_symbols)
        changed = split[1].size > merged[1].size or merged[1].size < state_symbol.size
        return merged, split, changed

    def _rounds_on_all_steps(self, seq: SymbolSequence, labels, state_symbol, rng, stages,
                             max_rounds: int | None = None, max_iter: int | None = None):
        """Stage 3: rounds on all steps until nothing is merged or split, a round's merged
        labelling is the one of the round before, or ``max_rounds`` rounds (EM rounds of at most
        ``max_iter`` iterations; defaults: the parameters'); appends every EM round to
        ``stages``.  Returns the last merged labelling and the number of rounds."""
        previous, rounds = None, 0
        max_rounds = self.max_rounds if max_rounds is None else max_rounds
        while True:
            merged, split, changed = self._restructure(seq, labels, state_symbol)
            rounds += 1
            if not changed or rounds >= max_rounds or (
                    previous is not None and same_partition(previous, merged[0])):
                return merged, rounds
            previous = merged[0]
            labels, state_symbol, iters = self._warm_round(seq, *split, rng, max_iter)
            stages.append((seq.T, int(state_symbol.size), iters))


#: what :meth:`EMRefinement._first_round` starts from: random counts, or the split's labelling
STARTS = ("random", "split", "split_budget", "auto")

#: ``start="auto"`` starts from the split where its labelling of the prefix has a successor
#: surprise below this.  Measured on all 10,000 steps of the bench_em worlds (seed 0): the
#: office 0.0 and the crossing 0.012 gain from the split start (half the E-steps); the random
#: graph (0.037) neither gains nor loses; MiniGrid Empty (0.048-0.051: the split joins places
#: the next view does not tell apart) loses ARI, 1.0 -> 0.82-0.92; the 8 x 6 and 12 x 12 rooms
#: (about 0.2) take 1.4 x the E-steps
SPLIT_TRUST = 0.02

#: rounds on all steps at most after a warm start (``init``), and the EM iterations of each: the
#: labelling it starts from has had its rounds already (the last map's), so a few short EM
#: rounds with their merges and splits bring it to the steps it had not seen
WARM_ROUNDS = 3
WARM_ITER = 15

#: the successor surprise (in ``soft.detect``) that cuts :meth:`EMRefinement._first_hard_round`
CUT_SURPRISE = 5.0


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

    ``clones_per_symbol`` clones for every K-means symbol (one per GDS id), random uniform initial
    counts, Baum-Welch with ``pseudocount`` per transition entry until it gains less than ``tol``
    nats per step (0: CSCG's rule, until the log-likelihood stops rising; checked from iteration
    10 on) or ``max_iter`` iterations, then Viterbi training without pseudocount; clones the final
    Viterbi path never visits are dropped.  ``evidence`` and ``soft`` as for
    :class:`EMRefinement` (``split_state_symbol`` of ``fit`` only sizes the soft rounds' pruning).
    """

    name = "cscg"

    def __init__(self, *, clones_per_symbol: int = 70, pseudocount: float = 2e-3,
                 max_iter: int = 1000, tol: float = 0.0, evidence: str = "auto",
                 soft: SoftSettings | Mapping = SoftSettings()):
        self.clones_per_symbol = clones_per_symbol
        self.pseudocount = pseudocount
        self.max_iter = max_iter
        self.tol = tol
        self.evidence = evidence
        self.soft = soft

    def check_params(self) -> None:
        super().check_params()
        check_count(self.clones_per_symbol, "clones_per_symbol")
        check_count(self.max_iter, "max_iter")
        _check(self.pseudocount > 0, "pseudocount", self.pseudocount, "> 0")
        _check(self.tol >= 0, "tol", self.tol, ">= 0")

    def provenance(self) -> str:
        """The text map.json stores as ``info["refine"]``: the refinement and its settings in the
        file's fixed form (``evidence`` and ``soft`` only when changed from their defaults)."""
        soft = self._provenance_soft()
        return (f"CSCGRefinement(clones_per_symbol={int(self.clones_per_symbol)}, "
                f"pseudocount={float(self.pseudocount)}, max_iter={int(self.max_iter)}, "
                f"tol={float(self.tol)}"
                f"{'' if self.evidence == 'auto' else f', evidence={self.evidence!r}'}"
                f"{', ' + soft if soft else ''})")

    def _hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                    init=None, split_labels=None) -> CloneFit:
        """EM alone taking every step's symbol as exact (neither the split, ``init`` nor
        ``split_labels`` is used)."""
        lay = seq.layout(clone_budget(seq.n_symbols, seq.n_gds, self.clones_per_symbol))
        rng = np.random.default_rng(random_state)
        labels, state_symbol, em, viterbi = fit_clones(
            lay, random_counts(lay, rng), float(self.pseudocount), max_iter=self.max_iter,
            tol=float(self.tol))
        info = {"em_iterations": len(em), "em_loglik": em[-1], "viterbi_iterations": len(viterbi),
                "viterbi_logp": viterbi[-1], "clones": lay.n_clones}
        return CloneFit(labels, state_symbol, info)


REFINEMENTS = {cls.name: cls for cls in (EMRefinement, CSCGRefinement)}
