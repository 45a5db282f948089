"""A wider pass of :meth:`MapLearner.partial_fit <topomap.MapLearner.partial_fit>` (the map
re-learned from the window, :mod:`topomap.core.online`) and how its refinement starts
(:class:`PassStart`): with ``refine="em"``, a pass on a window that has lost steps starts EM from
the last map instead of a split; a pass afresh on fewer than :data:`MIN_STEPS_PER_STATE` steps
per state keeps the split."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from sklearn.base import clone

from .components import phase1_symbols
from .data.trajectory import check_fit_data
from .online import OnlineState, lengths_of
from .refining import symbol_map
from .refine.methods import EMRefinement
from .refine.rounds import CloneRefinement

__all__ = ["MIN_STEPS_PER_STATE", "PassStart", "wider_pass", "note_cap", "warm_starts",
           "warm_start", "warm_labelling", "start_map"]

#: a wider pass afresh refines its map only when the window holds at least this many steps per
#: state of the split: EM's clones cannot be told apart by fewer visits, and on so short a walk
#: (a map of a thousand states after a thousand steps) the refinement costs more than any later
#: pass
MIN_STEPS_PER_STATE = 2


@dataclass(frozen=True)
class PassStart:
    """How a wider pass's refinement starts: ``old``, the last map's state of every step of the
    window (-1: none), which EM starts from instead of a split (None: afresh, as ``fit``);
    ``exact``, whether the last map's refinement (``refine="em"``) found no misread symbols, so
    a pass from it reads them as exact instead of making the soft check again."""

    old: np.ndarray | None = None
    exact: bool = False

    def splits(self, auto) -> bool:
        """Whether the pass makes the split: afresh, or with ``stop=auto`` (``auto`` its rule;
        the size it chooses is probed on the split); from the last map, EM starts there."""
        return self.old is None or auto is not None

    def refines(self, n_steps: int, n_states: int) -> bool:
        """Whether a pass on ``n_steps`` steps refines a split of ``n_states`` states: from the
        last map always, afresh with at least :data:`MIN_STEPS_PER_STATE` steps per state."""
        return self.old is not None or n_steps >= MIN_STEPS_PER_STATE * n_states


def wider_pass(learner, state: OnlineState, X_call) -> None:
    """A wider pass of ``learner`` (a :class:`~topomap.MapLearner`): learn the map from the
    window (its fit with the codebook's symbols, or with K-means while the window holds every
    step seen; how its refinement starts: :class:`PassStart`) and bind ``state`` to it.
    ``X_call``: the observations of the call."""
    Xw, uw, gw, sw, first = state.window.arrays()
    plain = gw < 0
    symbols, present = state.window_symbols(first, plain)
    start = PassStart()  # only a refinement that starts from the last map needs its labels
    if warm_starts(learner.refine):
        old = state.warm_labels(getattr(learner, "map_", None), X_call.shape[0], first)
        if old is not None:  # afresh, the soft check is made as fit makes it
            start = PassStart(old, getattr(learner, "refine_info_", {}).get("soft") == "skipped")
    learner._fit(check_fit_data(Xw, uw, gw, lengths_of(sw), state.n_actions, state.action_names,
                                state.gds_names), symbols, motion=False, warm=start)
    if symbols is None:  # phase 1's K-means symbols of every step seen become the codebook
        capped = learner.cluster_choice_.get("capped")
        if capped is not None:
            note_cap(learner, state, capped)
        state.learn_codebook(X_call, Xw, plain, phase1_symbols(learner)[0][plain],
                             learner.n_clusters_, first, 0 if capped is None else capped["asked"])
        if state.clusters:
            state.clusters["symbols"] = state.codebook.size
    state.after_pass(learner.map_, learner.labels_, gw, first, present)
    del learner.labels_phase1_, learner.labels_split_  # the window's: labels_ covers every step


def note_cap(learner, state: OnlineState, capped: dict) -> None:
    """Record a pass's capped cluster count (``capped``: ``asked``, ``distinct``) in
    ``state.clusters`` (``online_["clusters"]``), warning the first time."""
    if not state.clusters:
        name = "n_clusters" if learner.clusters is None else "the clusters policy's count"
        warnings.warn(f"{name}={capped['asked']} is more than the {capped['distinct']} distinct "
                      "observations the window holds (GDS steps excluded): partial_fit uses "
                      f"{capped['distinct']} symbols and gives each new view a symbol of its own "
                      f"as it appears, up to {capped['asked']} (online_['clusters'])",
                      UserWarning, stacklevel=4)
    state.clusters = {"asked": capped["asked"], "window": capped["distinct"]}


def warm_starts(refine) -> bool:
    """Whether the learner's ``refine`` starts a wider pass from the last map once steps have
    left the window: ``"em"`` (:class:`~topomap.core.refine.methods.EMRefinement`)."""
    return refine == "em" if isinstance(refine, str) else isinstance(refine, EMRefinement)


def warm_start(refinement, warm: PassStart | None, sym):
    """``(refinement to fit, init)`` of a pass's refinement: ``warm`` is None (``fit``:
    ``(refinement, None)``) or the pass's :class:`PassStart`.  A built-in refinement
    (:class:`~topomap.core.refine.rounds.CloneRefinement`) starts from :func:`warm_labelling`
    of ``warm.old`` when there is one (else afresh, ``init`` None); with ``evidence="auto"``
    and ``warm.exact``, a copy of it with ``evidence="hard"`` is fitted: the symbols come from
    the same sensor as the last map's, so the soft rounds' check is not made again on every
    pass."""
    if warm is None or not isinstance(refinement, CloneRefinement):
        return refinement, None
    init = None if warm.old is None else warm_labelling(warm.old, sym)
    if warm.exact and refinement.evidence == "auto":
        return clone(refinement).set_params(evidence="hard"), init
    return refinement, init


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


def start_map(learner, data, init):
    """``(labels, map)`` a pass from the last map refines (in place of the split it does not
    make): the labelling ``init`` of :func:`warm_labelling` and its map on ``data``, the
    reference of the refinement's guard (``refine_info_``'s ``bic`` and ``kept`` still call it
    ``"split"``) and of ``refined_from``."""
    labels, state_symbol = init
    info = dict(learner.map_split_.info, stop_reason="started from the last map")
    learner.stop_reason_ = info["stop_reason"]
    return labels, symbol_map(data, slice(None), data.lengths, labels, state_symbol,
                              learner.n_clusters_, covariance_type=learner.covariance_type,
                              reg_covar=learner.reg_covar, action_names=data.action_names,
                              gds_names=data.gds_names, split_history=learner.split_history_,
                              info=info)
