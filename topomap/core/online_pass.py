"""A wider pass of :meth:`MapLearner.partial_fit <topomap.MapLearner.partial_fit>` (the map
re-learned from the window, :mod:`topomap.core.online`) and the warm start of its refinement:
with ``refine="em"``, a pass on a window that has lost steps starts EM from the last map."""

from __future__ import annotations

import numpy as np
from sklearn.base import clone

from .data.trajectory import check_fit_data
from .online import OnlineState, lengths_of
from .refine.methods import EMRefinement
from .refine.rounds import CloneRefinement

__all__ = ["wider_pass", "warm_starts", "warm_start", "warm_labelling"]


def wider_pass(learner, state: OnlineState, X_call) -> None:
    """A wider pass of ``learner`` (a :class:`~topomap.MapLearner`): learn the map from the
    window (its fit with the codebook's symbols, or with K-means while the window holds every
    step seen; EM started from the last map's states once steps have left the window) and bind
    ``state`` to it.  ``X_call``: the observations of the call."""
    Xw, uw, gw, sw, first = state.window.arrays()
    plain = gw < 0
    symbols, present = state.window_symbols(first, plain)
    warm = None  # only a refinement that starts from the last map needs its labels
    if warm_starts(learner.refine):
        warm = state.warm_labels(getattr(learner, "map_", None), X_call.shape[0], first)
    if warm is not None:  # with whether the last map's refinement found no misread symbols
        warm = (warm, getattr(learner, "refine_info_", {}).get("soft") == "skipped")
    learner._fit(check_fit_data(Xw, uw, gw, lengths_of(sw), state.n_actions, state.action_names,
                                state.gds_names), symbols, motion=False, warm=warm)
    if symbols is None:  # phase 1's K-means symbols of every step seen become the codebook
        state.learn_codebook(X_call, Xw, plain, learner.labels_phase1_[plain],
                             learner.n_clusters_, first)
    state.after_pass(learner.map_, learner.labels_, gw, first, present)
    del learner.labels_phase1_, learner.labels_split_  # the window's: labels_ covers every step


def warm_starts(refine) -> bool:
    """Whether the learner's ``refine`` starts a wider pass from the last map once steps have
    left the window: ``"em"`` (:class:`~topomap.core.refine.methods.EMRefinement`)."""
    return refine == "em" if isinstance(refine, str) else isinstance(refine, EMRefinement)


def warm_start(refinement, warm, sym):
    """``(refinement to fit, init)`` of a pass's refinement: ``warm`` is None (a fresh start:
    ``(refinement, None)``) or ``(old, skipped)``, the last map's state of every step and
    whether its refinement found no misread symbols to correct.  A built-in refinement
    (:class:`~topomap.core.refine.rounds.CloneRefinement`) then starts from
    :func:`warm_labelling`; with ``evidence="auto"`` and ``skipped``, a copy of it with
    ``evidence="hard"`` is fitted: the symbols come from the same sensor and codebook as the
    last map's, so the soft rounds' check is not made again on every pass."""
    if warm is None or not isinstance(refinement, CloneRefinement):
        return refinement, None
    old, skipped = warm
    if skipped and refinement.evidence == "auto":
        return clone(refinement).set_params(evidence="hard"), warm_labelling(old, sym)
    return refinement, warm_labelling(old, sym)


def warm_labelling(old, sym):
    """``(labels, state_symbol)`` a warm-started refinement starts from, given the last map's
    state ``old`` of every step (-1: none) and the step's symbol id ``sym``: one state for every
    distinct ``(old state, symbol)`` pair, so every state emits one symbol, and the steps the
    last map could not label form one state per symbol."""
    old = np.asarray(old, dtype=np.int64)
    sym = np.asarray(sym, dtype=np.int64)
    n_ids = int(sym.max()) + 1
    pairs, labels = np.unique((old + 1) * n_ids + sym, return_inverse=True)
    return labels.ravel().astype(np.int64), pairs % n_ids
