"""The learner's refinement stage, as functions of their inputs: the told size, the map of a
refined labelling, the BIC guard, which split state every refined state came from, the refined
size ``stop=auto`` chooses.

A refinement (:mod:`topomap.core.refine.methods`) labels the steps with states that each emit a
symbol id (K-means symbols ``0..n_symbols-1``, then GDS ids); :class:`~topomap.MapLearner`
brings it to a told number of states (:func:`resized`), turns it into a map
(:func:`symbol_map`), keeps it only when :func:`bic_scores` says it is no worse than the split
map (with ``guard``), records :func:`refined_from`, and with ``stop=auto`` chooses the refined
size by :func:`heldout_scores`.
"""

from __future__ import annotations

import numpy as np

from .components import fit_refinement, naming, refinement_hints
from .map.model import TopologicalMap
from .refine.methods import CloneFit
from .refine.resize import resize
from .refine.sequence import SymbolSequence
from .size import bic, parameter_count, refined_sizes, split_holdout
from .stats import majority_match

__all__ = ["state_gds", "symbol_map", "resized", "bic_scores", "heldout_scores", "refined_from",
           "split_symbol", "alphabet", "choose_refined_size"]


def state_gds(state_symbol, n_symbols: int, gds_ids) -> np.ndarray:
    """(S,) the GDS id of every state of a labelling whose states emit ``state_symbol`` (symbol
    id ``n_symbols + i`` is the ``i``-th of the sorted ``gds_ids``), -1 for the others."""
    sym = np.asarray(state_symbol, dtype=np.int64)
    out = np.full(sym.size, -1, dtype=np.int64)
    is_gds = sym >= n_symbols
    out[is_gds] = np.asarray(gds_ids)[sym[is_gds] - n_symbols]
    return out


def symbol_map(data, steps: slice, lengths, labels, sym, n_symbols: int, *, covariance_type,
               reg_covar, **fields) -> TopologicalMap:
    """The map of a labelling whose states emit the symbol ids ``sym`` (K-means symbols, then GDS
    ids), estimated on ``data``'s ``steps`` (``fields``: the map's keyword fields)."""
    gds = state_gds(sym, n_symbols, np.unique(data.gds[data.gds >= 0]))
    return TopologicalMap.from_labels(
        data.X[steps], data.u[steps], labels, lengths=lengths,
        state_symbol=np.where(gds >= 0, -1, sym), state_gds=gds,
        state_parent=np.full(np.asarray(sym).size, -1), n_actions=data.n_actions,
        covariance_type=covariance_type, reg_covar=reg_covar, **fields)


def resized(fit: CloneFit, data, n_target: int, criterion, n_symbols: int) -> CloneFit:
    """The refinement ``fit`` of all of ``data`` brought to ``n_target`` states where the data
    allow it (:func:`topomap.core.refine.resize.resize`, with the split's ``criterion``; GDS
    states stay whole); ``info["resized"]`` says what was done."""
    gds = state_gds(fit.state_symbol, n_symbols, np.unique(data.gds[data.gds >= 0]))
    labels, state_symbol, info = resize(fit.labels, fit.state_symbol, data.u, data.n_actions,
                                        data.masks, n_target, gds, criterion)
    return CloneFit(labels, state_symbol, dict(fit.info, resized=info))


def bic_scores(data, maps: dict) -> dict:
    """``{name: BIC}`` of every ``name: (map, labels)`` (actions and transitions,
    :func:`topomap.core.size.bic`), all on ``data``."""
    has_next = data.masks[1]
    n_next = int(has_next.sum())
    return {name: bic(m.entropies(), parameter_count(x, data.u, data.n_actions, has_next),
                      data.u.size, n_next)
            for name, (m, x) in maps.items()}


def heldout_scores(data, seq, fit, held, criterion, n_symbols: int, emitted=None,
                   **map_kw) -> dict:
    """``{n: score}``: the refinement ``fit`` of the first ``seq.T`` steps of ``data`` brought
    to every size of :func:`topomap.core.size.refined_sizes` (:func:`resize`, with the split's
    ``criterion``), each map's mean log-likelihood of the held-out steps after them (episode
    lengths ``held``); ``map_kw``: the maps' ``covariance_type`` and ``reg_covar``.  Where the
    refinement's symbol ids (``seq.n_symbols`` before the GDS ones) are not the ``n_symbols``
    K-means symbols, ``emitted`` gives the K-means symbol of an id (``n_symbols + g`` for GDS
    ``g``)."""
    gds = state_gds(fit.state_symbol, seq.n_symbols, np.unique(data.gds[data.gds >= 0]))
    cut, scores = seq.T, {}
    for n in refined_sizes(fit.n_states, int(np.unique(seq.sym).size)):
        labels, sym, _ = resize(fit.labels, fit.state_symbol, seq.u, data.n_actions, seq.masks(),
                                n, gds, criterion)
        sym = sym if emitted is None else emitted(sym)
        m = symbol_map(data, slice(0, cut), seq.lengths, labels, sym, n_symbols, **map_kw)
        scores[int(sym.size)] = float(m.score(data.X[cut:], data.u[cut:], gds=data.gds[cut:],
                                              lengths=held))
    return scores


def refined_from(labels, split_labels, n_refined: int, n_split: int) -> list[int]:
    """For every refined state, the split state most of its steps held."""
    return majority_match(labels, split_labels, n_refined, n_split).tolist()


def split_symbol(splitter) -> np.ndarray:
    """The symbol id of every split state -- its phase-1 state, a symbol or a (symbol, heading)
    pair -- and -1 for GDS states: a refinement's second argument."""
    return np.where(np.asarray(splitter.gds) < 0, splitter.roots(), -1)


def alphabet(learner) -> tuple:
    """``(ns, ids, emitted)``: a fitted learner's K-means symbols, the symbol ids a refinement
    sees before the GDS ones (the symbols, or the (symbol, heading) pairs of
    :mod:`~topomap.core.phase1.heading`) and the function giving the K-means symbol (``ns + g``
    for GDS ``g``) of such ids."""
    ns, headed = learner.n_clusters_, getattr(learner, "_headed", None)
    if headed is None:
        return ns, ns, lambda ids: ids
    return ns, headed.n_pairs, headed.emitted


def choose_refined_size(learner, data, splitter, refinement, rule) -> int:
    """``stop=auto`` with a refinement: refine all but the held-out final block of ``data``,
    bring that refined map to the sizes of :func:`topomap.core.size.refined_sizes` and keep the
    size whose map scores the held-out block best (``learner.size_choice_["refined"]``)."""
    L, held, cut = split_holdout(data.u.size, data.lengths, rule.holdout)
    ns, ids, emitted = alphabet(learner)
    seq = SymbolSequence.build(learner.labels_phase1_[:cut], data.u[:cut], L, data.n_actions, ids)
    with naming(learner, "refine"):
        fit = fit_refinement(refinement, seq, split_symbol(splitter), learner.random_state,
                             split_labels=learner.labels_split_[:cut],
                             **refinement_hints(learner, data, refinement, cut))
    scores = heldout_scores(data, seq, fit, held, splitter.criterion, ns, emitted,
                            covariance_type=learner.covariance_type, reg_covar=learner.reg_covar)
    chosen = max(sorted(scores), key=lambda n: scores[n])
    learner.size_choice_["refined"] = {"own": fit.n_states, "chosen": chosen, "scores": scores}
    return chosen
