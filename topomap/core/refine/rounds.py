"""What the built-in refinements share: a labelling of the steps (:class:`CloneFit`) and the fit
as a template (:class:`CloneRefinement`) -- a hard round, then, unless ``evidence="hard"``, hard
and soft rounds in turn (the soft rounds of :mod:`topomap.core.refine.soft`).  The refinements
themselves, the hard rounds, are :mod:`topomap.core.refine.methods`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Self

import numpy as np
from sklearn.base import BaseEstimator

from ..checks import ParameterError
from .first_stage import check_ambiguity
from .observed import observed_evidence, observed_round
from .renamed import fold_renamed
from .sequence import SymbolSequence
from .settings import RefineSettings, settings_of
from .soft import check_evidence, soft_round, successor_surprise
from .soft_states import keep_states, merge_twins, min_steps_of, successor_pairing
from .structure import same_partition

__all__ = ["CloneFit", "CloneRefinement"]

@dataclass
class CloneFit:
    """A labelling of the steps into states, each state emitting one symbol: what one hard round
    gives (and what a refinement's ``fit`` returned before it returned the estimator).

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
    #: for a hard round cut short (:meth:`EMRefinement._first_hard_round`): finishes it, giving
    #: the fit the whole round gives (None: the round is whole)
    resume: Callable[[], "CloneFit"] | None = field(default=None, repr=False, compare=False)

    @property
    def n_states(self) -> int:
        """Number of states."""
        return int(self.state_symbol.size)


def _check(ok: bool, param: str, value, what: str) -> None:
    """A :class:`ParameterError` naming ``param`` unless ``ok``."""
    if not ok:
        raise ParameterError(param, f"must be {what}, got {value!r}")


def _checked_init(seq: SymbolSequence, labels, state_symbol, name: str = "init"):
    """``init`` of :meth:`CloneRefinement.fit` as int64 arrays, or a ``ValueError`` naming what
    is wrong: a label for every step, each a state, each state emitting its steps' symbol."""
    labels = np.asarray(labels, dtype=np.int64)
    state_symbol = np.asarray(state_symbol, dtype=np.int64)
    if labels.shape != (seq.T,):
        raise ValueError(f"{name}: {labels.size} labels for {seq.T} steps")
    if labels.size and (labels.min() < 0 or labels.max() >= state_symbol.size):
        raise ValueError(f"{name}: labels must be states 0..{state_symbol.size - 1}")
    if not np.array_equal(state_symbol[labels], seq.sym):
        raise ValueError(f"{name}: a state does not emit the symbol of every step labelled "
                         "with it")
    return labels, state_symbol


class CloneRefinement(BaseEstimator):
    """What the built-in refinements share: ``fit`` as a template -- check the parameters, a
    hard round (the subclass's :meth:`_hard_round`), then, unless ``evidence="hard"``, hard and
    soft rounds in turn (:meth:`_soft_rounds`) -- and their settings: ``evidence`` and the
    groups of :mod:`topomap.core.refine.settings` (``soft``, ``reading``, ...), each a settings
    object or a mapping of some of its fields, the parameters of before 0.3 accepted until 0.4
    (:mod:`topomap.core.refine.renamed`)."""

    name = ""
    #: the settings groups the refinement takes (parameter name: settings class)
    _groups: dict = {}
    #: every parameter and soft setting of before 0.3 and its place now ("" for none)
    renamed_params: dict = {}

    def _store(self, groups: dict, old: dict) -> None:
        """``__init__``'s: every group as given, the values ``old`` gave under the names of
        before 0.3 moved in (:func:`~topomap.core.refine.renamed.fold_renamed`)."""
        for name, value in fold_renamed(type(self).__name__, self._groups, groups, old,
                                        self.renamed_params, stacklevel=3).items():
            setattr(self, name, value)

    def set_params(self, **params):
        """scikit-learn's ``set_params``; a parameter of before 0.3 is accepted until 0.4 with a
        ``FutureWarning``, set where it lives now."""
        old = {k: params.pop(k) for k in list(params) if k in self.renamed_params}
        groups = {g: params.pop(g) for g in list(params) if g in self._groups}
        if old or "soft" in groups:
            groups = fold_renamed(type(self).__name__, self._groups,
                                  {g: groups.get(g, getattr(self, g)) for g in self._groups},
                                  old, self.renamed_params)
        return super().set_params(**params, **groups)

    def settings(self) -> RefineSettings:
        """Every settings group, checked (:func:`~topomap.core.refine.settings.settings_of`): a
        :class:`~topomap.core.checks.ParameterError` names ``<group>.<field>``."""
        return RefineSettings(**{name: settings_of(cls, getattr(self, name), name)
                                 for name, cls in self._groups.items()})

    def fit(self, seq: SymbolSequence, split_state_symbol=None, random_state: int = 0, *,
            init=None, split_labels=None, ambiguity=None, observed=None) -> Self:
        """Refine ``seq``; ``split_state_symbol`` is the symbol of every split state
        (``map_.state_symbol``, -1 for GDS); ``init``, optional, a labelling ``(labels,
        state_symbol)`` of every step of ``seq`` (each state emitting one symbol id) the first
        hard round starts from instead (a warm start: :class:`EMRefinement` runs its rounds on
        all steps from it; :class:`CSCGRefinement` ignores it); ``split_labels``, optional, the
        split state of every step (``labels_split_``), the first EM stage starts from with
        :class:`EMRefinement`'s ``growth.start="split"``; ``ambiguity``, optional, the share of
        steps whose symbol phase 1 may have misread (the learner's estimate,
        :func:`~topomap.core.phase1.ambiguity.symbol_ambiguity`), kept as ``ambiguity_``:
        :class:`EMRefinement`'s ``growth.first="auto"`` makes its first stage rough below
        :data:`~topomap.core.refine.first_stage.AMBIGUITY_BAR`; ``observed``, optional, the (T,
        n_symbols) log-density of every step's observation under each symbol's model (or a
        function returning it, called only if a soft round runs), which the soft rounds take
        as evidence with ``reading.temperature`` > 0 (:mod:`~topomap.core.refine.observed`; without
        it they use the confusion matrix).  Sets ``labels_``,
        ``state_symbol_``, ``n_states_``, ``info_`` (with ``evidence`` other than ``"hard"``
        also ``"soft"`` and ``"soft_rounds"``) and ``settings_`` (the checked settings,
        :meth:`settings`); returns ``self``."""
        self.settings_ = self.check_params()
        self.ambiguity_ = check_ambiguity(ambiguity)
        if init is not None:
            init = _checked_init(seq, *init)
        split = None if init is not None else self._checked_split(seq, split_labels)
        if self.evidence == "hard":
            fit = self._hard_round(seq, split_state_symbol, random_state, init, split)
        else:
            hard = self._first_hard_round(seq, split_state_symbol, random_state, init, split)
            n_reference = None if split_state_symbol is None else len(split_state_symbol)
            fit = self._soft_rounds(seq, hard, n_reference, random_state, observed)
            if fit.info["soft"] == "skipped" and hard.resume is not None:
                # a hard round cut short, and nothing to correct: finish it, start again from it
                fit = self._soft_rounds(seq, hard.resume(), n_reference, random_state, observed)
        self.labels_, self.state_symbol_, self.info_ = fit.labels, fit.state_symbol, fit.info
        self.n_states_ = fit.n_states
        return self

    def _checked_split(self, seq: SymbolSequence, split_labels):
        """``split_labels`` of :meth:`fit` as ``(labels, state_symbol)`` (each split state's
        symbol id, read off the steps) where the first stage may start from it (``start`` other
        than ``"random"``), else None; a ``ValueError`` naming what is wrong."""
        growth = self.settings_.growth
        if growth is None or growth.start == "random":
            return None
        if split_labels is None:
            raise ValueError(f"split_labels: start={growth.start!r} needs the split state of "
                             "every step")
        labels = np.asarray(split_labels)
        if labels.shape != (seq.T,) or not np.issubdtype(labels.dtype, np.integer):
            raise ValueError(f"split_labels: must be {seq.T} integer states, one per step, got "
                             f"shape {labels.shape} of {labels.dtype}")
        if labels.size and labels.min() < 0:
            raise ValueError("split_labels: states must be >= 0")
        state_symbol = np.full(int(labels.max(initial=-1)) + 1, -1, dtype=np.int64)
        state_symbol[labels] = seq.sym
        return _checked_init(seq, labels, state_symbol, "split_labels")

    def check_params(self) -> RefineSettings:
        """Check the parameters (``fit`` does); a :class:`ParameterError` names the bad one
        (``evidence``, ``hard.max_iter``, ...).  Returns the checked settings."""
        check_evidence(self.evidence)
        return self.settings()

    def _hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                    init=None, split_labels=None, *, cycle: bool = False) -> CloneFit:
        raise NotImplementedError

    def _first_hard_round(self, seq: SymbolSequence, split_state_symbol, random_state: int,
                          init=None, split_labels=None, *, cycle: bool = False):
        """A hard round a soft round starts from: the first, or (``cycle``) one on the
        corrected symbols of the cycles (default: :meth:`_hard_round`; a subclass may cut it
        short where its labelling still shows misreads, setting the fit's ``resume``)."""
        return self._hard_round(seq, split_state_symbol, random_state, init, split_labels)

    def _soft_rounds(self, seq: SymbolSequence, hard_fit: CloneFit, n_reference, random_state,
                     observed=None):
        """Hard and soft rounds in turn, from the hard round ``hard_fit`` on ``seq``:

        1. ``soft.rounds`` times: twin states merged, small states dropped, a soft round (the
           states found plus ``soft.spare`` clones per symbol), every step's symbol replaced by
           its decoded clone's, and a hard round on them (:meth:`_cycle_hard_round`); until a
           hard round gives back the labelling it started from, or a soft round after the
           first re-reads all but fewer than ``SETTLE_REREAD`` x ``reading.detect`` of the
           steps as the last hard round's symbols (``reread``: a hard round would repeat it);
        2. a last soft round without spare clones gives the map (tried first after a hard round
           that explains its symbols: :func:`_settled_map`).

        With ``evidence="auto"``, the hard round is kept without a soft round when its labelling
        predicts the next symbol of all but a ``reading.detect`` share of its transitions
        (:func:`~topomap.core.refine.soft.successor_surprise`: nothing to correct), and after
        the first soft round when it explains and corrects fewer steps than ``reading.detect``
        as misread (:func:`~topomap.core.refine.soft.misread_share`).  Where
        misreads are many, the soft rounds stop by ``soft.rtol`` (:func:`_round_settings`).
        ``n_reference``: the states a fractional ``soft.min_steps`` refers to (default: the hard
        round's); ``observed`` :meth:`fit`'s."""
        surprise = successor_surprise(seq, hard_fit.labels)
        st = _round_settings(self.settings_, self.evidence, surprise)
        detect = st.reading.detect  # -1 with evidence="soft"
        if surprise < detect:
            return _skipped(hard_fit, surprise, [])
        rng = np.random.default_rng(random_state)
        ev = observed_evidence(seq, st.reading.temperature, observed)
        cycle_ev, early = _first_evidence(seq, hard_fit, st.reading, ev, surprise)
        labels, state_symbol = hard_fit.labels, hard_fit.state_symbol
        n_ref = state_symbol.size if n_reference is None else int(n_reference)
        conf, rounds, read, explained = None, [], seq.sym, False
        for r in range(st.soft.rounds):
            last = explained and _settled_map(seq, labels, state_symbol, conf, st, rng, n_ref,
                                              read, ev)
            if last:  # the last hard round explained its symbols, and they are re-read
                return _soft_fit(hard_fit, surprise, [*rounds, last.info], last)
            soft, labels, state_symbol = _spare_soft_round(seq, labels, state_symbol, conf, st,
                                                           rng, n_ref, r == 0, cycle_ev)
            conf = soft.conf
            rounds.append(soft.info)
            if r == 0:
                nothing, cycle_ev = _after_first(soft, st.reading, ev, seq.n_symbols, early)
                if nothing:
                    return _skipped(hard_fit, surprise, rounds)
            else:
                rounds[-1]["reread"] = reread_share(soft.sym, read)
                if rounds[-1]["reread"] < SETTLE_REREAD * detect:
                    break  # the next hard round would read (nearly) the symbols the last one did
            read = soft.sym
            hard, explained = self._cycle_hard_round(seq, soft, random_state, detect)
            settled = hard.n_states == state_symbol.size and same_partition(hard.labels, labels)
            labels, state_symbol = hard.labels, hard.state_symbol
            rounds[-1].update(hard_states=int(state_symbol.size),
                              **({"hard_cut": True} if hard.resume is not None else {}))
            if settled:
                break
        soft = _last_soft_round(seq, labels, state_symbol, conf, st, rng, n_ref, ev)
        rounds.append(soft.info)
        return _soft_fit(hard_fit, surprise, rounds, soft)

    def _cycle_hard_round(self, seq: SymbolSequence, soft, random_state: int, detect: float):
        """The hard round on the symbols the soft round ``soft`` corrected -- started from its
        labelling (short rounds on all steps, which also merge the duplicates its states leave:
        :meth:`EMRefinement._stages`) with ``growth.cycle_start="soft"`` where it read the
        per-step evidence (``"auto"``: and :func:`warm_cycle` holds); else from random counts,
        cut short like the first where misreads still show, the next soft round correcting what
        is left, unless the soft round corrected fewer than ``CUT_CORRECTED`` x ``detect`` of
        the steps -- and whether it explains them: not cut, and its labelling predicts the next
        symbol of all but a ``detect`` share of its transitions (the next soft round is then
        tried without spare clones first: if it re-reads the symbols as they are, it is the map)."""
        split_symbol = np.where(soft.state_symbol < seq.n_symbols, soft.state_symbol, -1)
        read = replace(seq, sym=soft.sym)
        growth = self.settings_.growth  # None for refine=cscg, which starts no round warm
        if (growth is not None and soft.info.get("evidence") == "observed"
                and (growth.cycle_start == "soft"
                     or growth.cycle_start == "auto" and warm_cycle(soft, seq.T))):
            hard = self._hard_round(read, split_symbol, random_state,
                                    init=(soft.labels, soft.state_symbol), cycle=True)
        elif soft.info["corrected"] < CUT_CORRECTED * detect:  # hardly any misreads to cut for
            hard = self._hard_round(read, split_symbol, random_state)
        else:
            hard = self._first_hard_round(read, split_symbol, random_state, cycle=True)
        return hard, hard.resume is None and successor_surprise(read, hard.labels) < detect


#: the successor surprise (in ``reading.detect``) from which misreads count as many: the growth
#: stages of a hard round whose first stage's labelling of the prefix shows it are capped
#: (``growth.stage_cap``), and the soft rounds after a hard round whose labelling shows it stop
#: by ``soft.rtol``.  Gridroom 8x6's prefixes show 0.6-1.1 % without misreads, 3.5-3.8 % at 2.5 %
#: misreads (where the cap cost ARI), 8-10 % at 9.7 %
CAP_SURPRISE = 25.0


#: ``growth.cycle_start="auto"`` starts a hard round on corrected symbols from the soft round's
#: labelling where its states hold at least this many steps each on average (steps per state).
#: After the first soft round: gridroom 8x6 132-167 at 9.7-23.4 % misreads (seeds 0-5) and
#: random_graph 60 141-167 at 0.7-8.2 % (seeds 0-2), where warm rounds kept every ARI up to
#: 18.2 %; the 12x12 room 56-71 at 4.9-16.6 % (seeds 0-2), where they moved rarely visited
#: places (10.6 % seed 1: 0.9973 -> 0.9965; 16.6 %: median 1.0000 -> 0.9985)
WARM_VISITS = 100.0
#: ... and where that soft round corrected at most this share of the steps (share).  Gridroom
#: 8x6, seeds 0-5: at 18.2 % misreads 17.5-20.5 % corrected (warm: every ARI kept), at 23.4 %
#: 22.1-28.0 % (warm, seed 2 at 22.7 % kept two places split in two: ARI 1.0000 -> 0.9806)
WARM_CORRECTED = 0.21


def warm_cycle(soft, n_steps: int) -> bool:
    """Whether ``growth.cycle_start="auto"`` starts the hard round after the soft round ``soft``
    (a :class:`~.soft.SoftFit` of ``n_steps`` steps) from its labelling: its states hold at
    least :data:`WARM_VISITS` steps each on average, it corrected at most :data:`WARM_CORRECTED`."""
    return (n_steps >= WARM_VISITS * soft.state_symbol.size
            and soft.info["corrected"] <= WARM_CORRECTED)


#: the successor surprise (in ``reading.detect``) that cuts :meth:`EMRefinement._first_hard_round`
#: and from which the first soft round takes the per-step evidence (``reading.observed_in="early"``)
CUT_SURPRISE = 5.0


#: the share of steps (in ``reading.detect``) a soft round must correct for the hard round on its
#: symbols to be cut short: below it the surprise left is the walk's own, not misreads (MiniGrid
#: Empty-16x16 at 10,000 steps, seed 0, 0.2 % corrected: a cut round gave ARI 0.431, not 0.481)
CUT_CORRECTED = 5.0


#: the share of steps (in ``reading.detect``) below which a soft round's re-read symbols count as
#: the ones the last hard round learned on: the hard and soft rounds stop there (at 5, the
#: rounds stopped earlier and gridroom 8x6 at 9.7 % misreads lost ARI: seed 1 0.981 -> 0.978)
SETTLE_REREAD = 1.0


#: ``reading.observed_in="auto"``: the rounds after the first take each step's own evidence unless
#: the first one's confusion matrix reads some symbol as another at least this often -- a view
#: phase 1 cut into two symbols, which the per-step evidence would keep as two places (the
#: office at 10.8-25.6 % misreads: 0.20-0.50 on every seed; gridroom 8x6 at 9.7-23.4 %,
#: random_graph 60 at 8.2 % and the 12x12 room at 10.6 %: 0.09 at most)
PAIRED_READ = 0.15


def _first_evidence(seq, hard_fit, reading, ev, surprise: float):
    """The per-step evidence ``ev`` the first soft round takes (None: the confusion matrix),
    and what its record notes: with ``reading.observed_in="all"`` always; with ``"early"``
    where the first hard round's labelling shows misreads (a successor ``surprise`` at least
    :data:`CUT_SURPRISE` x ``reading.detect``) and its moves pair no two symbols at least
    :data:`PAIRED_READ` (:func:`~topomap.core.refine.soft_states.successor_pairing`, its
    record's ``hard_paired``)."""
    if ev is None or reading.observed_in not in ("all", "early"):
        return None, {}
    if reading.observed_in == "all":
        return ev, {}
    if surprise < CUT_SURPRISE * reading.detect:  # few misreads: the first round judges them
        return None, {}
    paired = successor_pairing(seq, hard_fit.labels)
    return (ev if paired < PAIRED_READ else None), {"hard_paired": paired}


def _after_first(soft, reading, ev, n_symbols: int, early: dict):
    """After the first soft round ``soft`` (``early``, what :func:`_first_evidence` noted, added
    to its record): whether it found nothing to correct (stopped early on exact readings, or it
    explains and corrects fewer than ``reading.detect`` of the steps as misread), and the
    per-step evidence ``ev`` the rounds after it take as ``reading.observed_in`` says
    (``"auto"``: unless the round's confusion matrix pairs two symbols at least
    :data:`PAIRED_READ`, ``paired`` in its record)."""
    soft.info.update(early)
    if "stopped" in soft.info or max(soft.info["corrected"], soft.info["misread"]) < reading.detect:
        return True, None
    if reading.observed_in == "all" or soft.info.get("evidence") == "observed":
        return False, ev  # "early" took it from the first round: nothing paired
    if reading.observed_in == "last" or ev is None:
        return False, None
    soft.info["paired"] = paired = pair_read(soft.conf, n_symbols)
    return False, ev if paired < PAIRED_READ else None


def pair_read(conf, n_symbols: int) -> float:
    """The largest off-diagonal entry of the K-means rows of the confusion matrix ``conf``: how
    often a symbol is read as the one it is most confused with."""
    block = np.array(conf, dtype=float)[:n_symbols, :n_symbols]
    np.fill_diagonal(block, 0.0)
    return float(block.max(initial=0.0))


def reread_share(sym, read) -> float:
    """The share of steps whose symbol ``sym`` differs from ``read``."""
    return float(np.mean(np.asarray(sym) != np.asarray(read))) if len(read) else 0.0


def _round_settings(settings: RefineSettings, evidence: str, surprise: float):
    """The settings of the soft rounds after a hard round whose labelling shows the successor
    ``surprise``: ``reading.detect`` -1 with ``evidence="soft"`` (the soft rounds always run);
    ``soft.rtol`` 0 (the soft rounds run to ``tol``) unless misreads are many, a surprise at
    least ``CAP_SURPRISE`` x ``reading.detect`` -- there the slow tail of a soft round only moves
    what the next round corrects anyway; ``soft.prune`` ``soft.prune_loose`` (if not 0) where
    the surprise is below ``soft.loose_below`` -- misreads too few for the sparser soft passes to
    cost ARI."""
    s, r = settings.soft, settings.reading
    few = surprise < CAP_SURPRISE * r.detect
    loose = s.prune_loose > 0 and surprise < s.loose_below
    return replace(settings,
                   soft=replace(s, rtol=0.0 if few else s.rtol,
                                prune=s.prune_loose if loose else s.prune),
                   reading=replace(r, detect=-1.0 if evidence == "soft" else r.detect))


def _skipped(hard_fit: CloneFit, surprise: float, rounds) -> CloneFit:
    """The hard round ``hard_fit`` kept: nothing to correct."""
    return CloneFit(hard_fit.labels, hard_fit.state_symbol,
                    {**hard_fit.info, "soft": "skipped", "surprise": surprise,
                     "soft_rounds": rounds})


def _soft_fit(hard_fit: CloneFit, surprise: float, rounds, soft) -> CloneFit:
    """The map of the soft round ``soft``, the last of ``rounds``."""
    return CloneFit(soft.labels, soft.state_symbol,
                    {**hard_fit.info, "soft": "on", "surprise": surprise, "soft_rounds": rounds})


def _settled_map(seq, labels, state_symbol, conf, st, rng, n_ref, read, ev=None):
    """The last soft round (:func:`_last_soft_round`) if it re-reads all but fewer than
    ``SETTLE_REREAD`` x ``reading.detect`` of the steps as ``read``, the symbols the last hard
    round learned on (``reread`` in its record): it is the map; None otherwise (the cycles go on
    as if it had not run: it draws nothing from ``rng``)."""
    last = _last_soft_round(seq, labels, state_symbol, conf, st, rng, n_ref, ev)
    last.info["reread"] = reread_share(last.sym, read)
    return last if last.info["reread"] < SETTLE_REREAD * st.reading.detect else None


def _spare_soft_round(seq, labels, state_symbol, conf, st, rng, n_ref, first: bool, ev=None):
    """A soft round of the cycles (``st``, the round's :class:`RefineSettings`): twins merged,
    small states dropped (``soft.prune_every``), ``soft.spare`` clones per symbol; the ``first``
    stops early on exact readings.  Returns the round (its info starting with ``states_in`` and
    ``twins_merged``) and the labelling with twins merged."""
    s = st.soft
    labels, state_symbol, n_merged = merge_twins(seq, labels, state_symbol, s.twin_merge)
    keep = keep_states(seq, labels, state_symbol,
                       min_steps_of(s, seq.T, n_ref) if s.prune_every else 0, s.twin)
    soft = _round(ev)(seq, labels, state_symbol, conf, spare=s.spare, soft=s,
                      reading=st.reading, rng=rng, keep=keep,
                      exact_below=st.reading.detect if first else None)
    soft.info = {"states_in": int(state_symbol.size), "twins_merged": n_merged, **soft.info}
    return soft, labels, state_symbol


def _last_soft_round(seq, labels, state_symbol, conf, st, rng, n_ref, ev=None):
    """The map: twins merged, states under ``soft.min_steps`` dropped, a soft round without spare
    clones; its info holds ``states_in``, the states kept."""
    s = st.soft
    labels, state_symbol, _ = merge_twins(seq, labels, state_symbol, s.twin_merge)
    keep = keep_states(seq, labels, state_symbol, min_steps_of(s, seq.T, n_ref), s.twin)
    soft = _round(ev)(seq, labels, state_symbol, conf, spare=0, soft=s, reading=st.reading,
                      rng=rng, keep=keep)
    soft.info = {"states_in": int(keep.sum()), **soft.info}
    return soft


def _round(ev):
    """The soft round: with the confusion matrix (``ev`` None) or with the per-step evidence
    ``ev`` (:func:`~topomap.core.refine.observed.observed_round`)."""
    if ev is None:
        return soft_round
    return lambda *args, **kw: observed_round(*args, evidence=ev, **kw)
