"""The refinements' settings, one small frozen object per stage, each default in one place.

======================  ==================  =================================================
object                  config key          what it sets
======================  ==================  =================================================
:class:`HardRounds`     ``refine.hard``     every EM round of ``refine=em`` that takes the
                                            symbols as read (stages 1-3), merges and splits
:class:`CSCGRounds`     ``refine.hard``     ``refine=cscg``'s EM alone (its hard round)
:class:`Growth`         ``refine.growth``   ``refine=em``'s stage 1 on a prefix and the growth
                                            stages that lengthen it
:class:`SoftRounds`     ``refine.soft``     the soft rounds, which alternate with hard rounds
:class:`Reading`        ``refine.reading``  how a soft round takes the symbol read at a step
                                            as evidence (the confusion matrix, or the step's
                                            own observation)
======================  ==================  =================================================

A knob that differs between stages lives in each stage's object under the same name
(``hard.spare`` 2, ``soft.spare`` 1: clones added to a hard and to a soft round).  A refinement
takes each object, or a mapping of some of its fields (``soft={"rounds": 2}``);
:func:`settings_of` checks one and names a bad field ``<group>.<field>``.  Why each default is
what it is: ``benchmarks/notes/settings.md``.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ..checks import ParameterError, check_count, checked_group
from .accelerate import ACCELERATIONS
from .budget import BUDGETS
from .first_stage import FIRSTS, HARD_ACCELERATIONS

__all__ = ["HardRounds", "CSCGRounds", "Growth", "SoftRounds", "Reading", "RefineSettings",
           "settings_of", "STARTS", "OBSERVED_IN"]

INF = float("inf")

#: what stage 1 of ``refine=em`` starts from (``growth.start``)
STARTS = ("random", "split", "split_budget", "auto")

#: what a hard round on corrected symbols starts from (``growth.cycle_start``)
CYCLE_STARTS = ("random", "soft", "auto")

#: the soft rounds that take each step's evidence from its observation (``reading.observed_in``)
OBSERVED_IN = ("last", "auto", "early", "all")


@dataclass(frozen=True)
class HardRounds:
    """``refine.hard`` of ``refine=em``: every EM round that takes the symbols as read."""

    row_prior: float = 0.5
    """Pseudocount mass of a row of ``P(x'|x,u)``, spread over its clones (counts per row)."""
    tol: float = 1e-6
    """A round's Baum-Welch stops once an iteration gains less (nats per step)."""
    max_iter: int = 50
    """Baum-Welch iterations of a round at most (E-steps)."""
    settle: float = 0.0
    """A round also stops once its decoded path moved on fewer than this share of the steps at
    three E-steps in a row (share of steps; 0: off)."""
    accelerate: str = "auto"
    """``"squarem"``: the warm-started rounds' Baum-Welch as SQUAREM's cycles; ``"none"``;
    ``"auto"``: SQUAREM where stage 1 is rough (symbols read exactly), else plain."""
    prune: float = 1e-4
    """Filtered probabilities below this are dropped in the forward pass (probability)."""
    merge_threshold: float = 6.63
    """G statistic under which two bisimilar states of a symbol are merged (negative: never)."""
    split_z: float = 3.09
    """Normal score above which a compound state is split (``inf``: never)."""
    spare: int = 2
    """Random clones added per K-means symbol to every round (clones)."""
    init_noise: float = 1.0
    """Uniform random count added to every entry of a warm start's counts (counts)."""
    max_rounds: int = 8
    """Rounds on all steps (stage 3) at most (rounds)."""


@dataclass(frozen=True)
class CSCGRounds:
    """``refine.hard`` of ``refine=cscg``: EM alone, CSCG's recipe."""

    clones_per_symbol: int = 70
    """Clones of every K-means symbol (clones; a GDS id gets one)."""
    pseudocount: float = 2e-3
    """Pseudocount of every transition entry (counts)."""
    max_iter: int = 1000
    """Baum-Welch iterations at most (E-steps)."""
    tol: float = 0.0
    """Baum-Welch stops once an iteration gains less (nats per step; 0: once it does not rise)."""


@dataclass(frozen=True)
class Growth:
    """``refine.growth`` of ``refine=em``: stage 1 on a prefix, and the stages growing it."""

    clone_factor: int = 2
    """Stage 1's clones per split state of a symbol (clones)."""
    budget: str = "evidence"
    """What sizes stage 1's clones: ``"evidence"``, at least the data's bound on a view's
    places, or ``"split"``, ``clone_factor`` x its split states + ``hard.spare``."""
    prefix: int = 2000
    """Stage 1's prefix at least (steps)."""
    prefix_visits: int = 40
    """Stage 1's prefix at least this many steps per split state (steps per state)."""
    start: str = "random"
    """What stage 1 starts from: ``"random"`` counts, the split's labelling (``"split"``),
    the split's states spread over the budget (``"split_budget"``) or ``"auto"``."""
    first: str = "auto"
    """Where stage 1 is rough: ``"auto"`` where phase 1 reads the symbols exactly,
    ``"rough"`` always, ``"plain"`` never."""
    first_factor: int = 1
    """A rough stage 1's clones per split state, in place of ``clone_factor`` (0: off)."""
    first_iter: int = 25
    """A rough stage 1's Baum-Welch stops after this many iterations (E-steps; 0: no cap)..."""
    first_rtol: float = INF
    """... unless its last iteration gained more than this share of the log-likelihood; then
    it goes on until one gains less (share; ``inf``: it stops)."""
    stage_cap: int = 15
    """Where stage 1's labelling shows many misreads and pairs no two symbols, the growth
    stages' Baum-Welch stops after this many iterations (E-steps; 0: no cap)..."""
    stage_rtol: float = INF
    """... unless its last iteration gained more than this share of the log-likelihood; then
    it goes on until one gains less (share; ``inf``: it stops)."""
    cycle_start: str = "auto"
    """A hard round on corrected symbols starts from random counts (``"random"``) or, where
    the soft round read the per-step evidence, from its labelling (``"soft"``); ``"auto"``:
    from its labelling only where that round's states hold many steps each and it corrected
    not too many (:func:`~topomap.core.refine.rounds.warm_cycle`)."""


@dataclass(frozen=True)
class SoftRounds:
    """``refine.soft``: the soft rounds, Baum-Welch with the symbol read as evidence."""

    rounds: int = 3
    """Soft round + hard round cycles at most, before the last soft round (cycles)."""
    spare: int = 1
    """Random clones added per K-means symbol to a soft round of the cycles (clones)."""
    max_iter: int = 30
    """Baum-Welch iterations of a soft round at most (E-steps)."""
    tol: float = 1e-5
    """A soft round stops once an iteration gains less (nats per step)."""
    rtol: float = 0.0
    """Where misreads are many, a soft round stops once an iteration gains at most this share
    of the log-likelihood (share; 0: off)."""
    row_prior: float = 0.5
    """Pseudocount mass of a row of ``P(x'|x,u)``, spread over its clones (counts per row)."""
    prune: float = 1e-6
    """Filtered probabilities below this are dropped in the forward pass (probability)."""
    prune_loose: float = 0.0
    """``prune`` after a first hard round whose successor surprise is below ``loose_below``
    (probability; 0: off)."""
    loose_below: float = 0.12
    """Successor surprise under which ``prune_loose`` applies (share of transitions)."""
    accelerate: str = "none"
    """``"squarem"``: Baum-Welch after its first E-step as SQUAREM's cycles; ``"none"``."""
    min_steps: float = 0.3
    """States with fewer steps are dropped before a soft round (steps; below 1: that share of
    the mean steps per split state; 0: keep all)."""
    prune_every: bool = True
    """Drop small states before every soft round (false: only before the last)."""
    twin: float = 0.5
    """Predecessor overlap with a state of another symbol from which a small state is the
    residue of misreads, not a rarely visited place (share)."""
    twin_merge: float = 0.5
    """Predecessor overlap from which a state merges into its twin of another symbol (share)."""
    label_every: int = 0
    """A soft round decodes its model every this many iterations (E-steps; 0: off)..."""
    label_tol: float = 1e-3
    """... and stops once fewer than this share of the steps moved (share of steps)."""


@dataclass(frozen=True)
class Reading:
    """``refine.reading``: how a soft round takes the symbol read at a step as evidence."""

    detect: float = 0.002
    """Misread share under which readings count as exact: ``evidence="auto"`` then keeps the
    hard map (share of steps; also the unit of the misread bars of the rounds)."""
    detect_iter: int = 3
    """The first soft round judges the misread share after this many iterations (E-steps)."""
    init_error: float = 0.2
    """Misread rate the confusion matrix starts from (share of readings)."""
    conf_diag: float = 20.0
    """Dirichlet pseudocount of a confusion row's diagonal entry (counts)."""
    conf_off: float = 0.05
    """Dirichlet pseudocount of a confusion row's off-diagonal entries (counts each)."""
    conf_warmup: int = 0
    """Iterations the confusion matrix is held at its start before it is learned (E-steps)."""
    clone_prior: float = INF
    """A clone's read distribution is shrunk to its symbol's confusion row with this many
    pseudo-steps (steps; ``inf``: the row itself)."""
    floor: float = 1e-3
    """Smallest confusion entry that counts as evidence; smaller ones are 0 (probability)."""
    read_share: float = 3e-4
    """Where candidates are dense, a symbol whose share of a step's evidence, given the forward
    message, is below this is no candidate there (share; 0: off)."""
    temperature: float = 6.0
    """The observed evidence, each symbol's likelihood relative to the best, is raised to
    ``1 / temperature`` (1: the likelihood itself; 0: off, the confusion matrix throughout)."""
    observed_in: str = "early"
    """Which soft rounds take the observed evidence: ``"early"``, ``"auto"``, ``"last"`` or
    ``"all"``."""
    settle: float = 0.002
    """The first soft round on the observed evidence stops once every step's most probable
    symbol moved at fewer than this share of the steps since the E-step before (share; 0: off)."""


@dataclass(frozen=True)
class RefineSettings:
    """A refinement's settings, every group checked (``growth`` None for ``refine=cscg``)."""

    hard: HardRounds | CSCGRounds
    soft: SoftRounds
    reading: Reading
    growth: Growth | None = None


def _count(minimum: int = 1):
    return lambda value, key: check_count(value, key, minimum=minimum)


def _real(ok, what: str):
    def check(value, key):
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool) and ok(value)):
            raise ParameterError(key, f"must be {what}, got {value!r}")
    return check


def _choice(options):
    def check(value, key):
        if value not in options:
            raise ParameterError(key, f"must be one of {', '.join(options)}, got {value!r}")
    return check


def _flag(value, key):
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(key, f"must be true or false, got {value!r}")


_NUMBER = _real(lambda v: v == v, "a number")
_POSITIVE = _real(lambda v: v > 0, "> 0")
_NON_NEGATIVE = _real(lambda v: v >= 0, ">= 0")
_PROBABILITY = _real(lambda v: 0 <= v < 1, "in [0, 1)")
_SHARE = _real(lambda v: 0 <= v <= 1, "in [0, 1]")

#: what every field must be, by settings class
CHECKS = {
    HardRounds: {
        "row_prior": _POSITIVE, "tol": _NON_NEGATIVE, "max_iter": _count(), "settle": _SHARE,
        "accelerate": _choice(HARD_ACCELERATIONS), "prune": _PROBABILITY,
        "merge_threshold": _NUMBER,
        "split_z": _NUMBER, "spare": _count(0), "init_noise": _NON_NEGATIVE,
        "max_rounds": _count()},
    CSCGRounds: {"clones_per_symbol": _count(), "pseudocount": _POSITIVE, "max_iter": _count(),
                 "tol": _NON_NEGATIVE},
    Growth: {
        "clone_factor": _count(), "budget": _choice(tuple(BUDGETS)), "prefix": _count(),
        "prefix_visits": _count(0), "start": _choice(STARTS), "first": _choice(FIRSTS),
        "first_factor": _count(0), "first_iter": _count(0), "first_rtol": _NON_NEGATIVE,
        "stage_cap": _count(0), "stage_rtol": _NON_NEGATIVE,
        "cycle_start": _choice(CYCLE_STARTS)},
    SoftRounds: {
        "rounds": _count(0), "spare": _count(0), "max_iter": _count(), "tol": _NON_NEGATIVE,
        "rtol": _NON_NEGATIVE, "row_prior": _POSITIVE, "prune": _PROBABILITY,
        "prune_loose": _PROBABILITY, "loose_below": _NON_NEGATIVE,
        "accelerate": _choice(ACCELERATIONS), "min_steps": _NON_NEGATIVE, "prune_every": _flag,
        "twin": _NON_NEGATIVE, "twin_merge": _NON_NEGATIVE, "label_every": _count(0),
        "label_tol": _SHARE},
    Reading: {
        "detect": _NUMBER, "detect_iter": _count(0), "init_error": _PROBABILITY,
        "conf_diag": _POSITIVE, "conf_off": _POSITIVE, "conf_warmup": _count(0),
        "clone_prior": _POSITIVE, "floor": _real(lambda v: 0 < v < 1, "in (0, 1)"),
        "read_share": _PROBABILITY,
        "temperature": _real(lambda v: 0 <= v < INF, ">= 0 and finite"),
        "observed_in": _choice(OBSERVED_IN), "settle": _SHARE},
}


def settings_of(cls, value, group: str):
    """``value`` -- a ``cls`` (one of the settings classes above) or a mapping of some of its
    fields -- as checked settings; a :class:`~topomap.core.checks.ParameterError` names
    ``<group>.<field>`` (``hard.max_iter``), or ``group`` for a value of another kind."""
    return checked_group(cls, value, group, CHECKS[cls])
