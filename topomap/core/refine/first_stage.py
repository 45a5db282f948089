"""Whether :class:`~topomap.core.refine.methods.EMRefinement`'s first EM stage is *rough*, and
its settings when it is.

Stage 1 fits every clone from random counts on a prefix of the steps; where the growth stages
after it refit every state on many more steps (the prefix at most :data:`ROUGH` of them), a rough
stage 1 -- ``first_factor`` clones per split state (1: no more clones than the split found) and
Baum-Welch cut after ``first_iter`` iterations -- saves E-steps without losing the map on walks
whose symbols are read exactly (the 12 x 12 room at 10,000 steps: 0.58 s for 0.93 s).  On walks
with misread symbols it loses ARI (the office at 25.6 % symbol error: 0.9615 -> 0.8796), so with
``first="auto"`` (the default) it applies only where phase 1 reads the symbols exactly: where
the ``ambiguity`` the learner passes to ``fit`` (the share of steps whose symbol phase 1's
observation model leaves ambiguous, :func:`topomap.core.phase1.ambiguity.symbol_ambiguity`) is
below :data:`AMBIGUITY_BAR`.  ``first="rough"``: wherever the prefix is short enough;
``"plain"``: never.

The same walks take ``hard.accelerate="auto"`` (the default) as SQUAREM on the warm-started
rounds after a rough stage 1 (:func:`warm_acceleration`): where stage 1 is not rough, SQUAREM
lost ARI (MiniGrid FourRooms, stage 1 on all its steps: 0.843 -> 0.837 on seed 1; gridroom 8x6
at 2.5 % misreads), and there the rounds stay plain EM.
"""

from __future__ import annotations

from .accelerate import ACCELERATIONS

__all__ = ["AMBIGUITY_BAR", "FIRSTS", "HARD_ACCELERATIONS", "ROUGH", "check_ambiguity",
           "first_settings", "rough_first", "warm_acceleration"]

#: what ``growth.first`` of :class:`~topomap.core.refine.methods.EMRefinement` may be
FIRSTS = ("auto", "rough", "plain")

#: what ``hard.accelerate`` of :class:`~topomap.core.refine.methods.EMRefinement` may be
HARD_ACCELERATIONS = ("auto", *ACCELERATIONS)

#: stage 1 is rough (``growth.first_*``) on a prefix of at most this share of the steps (only
#: then can two growth stages follow): FourRooms at 50,000 steps (0.83) lost ARI by it, not the
#: 12x12 room (0.58)
ROUGH = 2 / 3

#: ``growth.first="auto"`` makes stage 1 rough where the symbol ambiguity is below this
AMBIGUITY_BAR = 1e-3


def first_settings(growth, rough: bool):
    """Stage 1's clone factor and Baum-Welch cap (``(iterations, rtol)`` or None): the growth
    settings' (:class:`~topomap.core.refine.settings.Growth`) ``first_*`` where ``rough``, each
    unless 0, else ``clone_factor`` and none."""
    factor = growth.first_factor if rough and growth.first_factor else growth.clone_factor
    cap = (growth.first_iter, float(growth.first_rtol)) if rough and growth.first_iter else None
    return factor, cap


def rough_first(growth, n: int, T: int, ambiguity) -> bool:
    """Whether stage 1 on the first ``n`` of ``T`` steps is rough: on at most :data:`ROUGH` of
    them, with ``growth.first_*`` that change it, and ``growth.first="rough"``, or ``"auto"``
    with an ``ambiguity`` (None: not known) below :data:`AMBIGUITY_BAR`."""
    if n > ROUGH * T or first_settings(growth, True) == first_settings(growth, False):
        return False
    if growth.first == "auto":
        return ambiguity is not None and ambiguity < AMBIGUITY_BAR
    return growth.first == "rough"


def warm_acceleration(accelerate: str, rough: bool) -> str:
    """The acceleration of a hard round's warm-started rounds (``hard.accelerate``):
    ``"auto"`` is ``"squarem"`` after a ``rough`` stage 1, else ``"none"``; the others as given."""
    if accelerate == "auto":
        return "squarem" if rough else "none"
    return accelerate


def check_ambiguity(ambiguity):
    """``ambiguity`` of ``fit`` as a float in [0, 1], or None; a ``ValueError`` naming it."""
    if ambiguity is None:
        return None
    try:
        value = float(ambiguity)
    except (TypeError, ValueError):
        raise ValueError(f"ambiguity: must be a number in [0, 1], got {ambiguity!r}") from None
    if not 0 <= value <= 1:
        raise ValueError(f"ambiguity: must be a number in [0, 1], got {ambiguity!r}")
    return value
