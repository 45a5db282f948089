"""What every soft round runs, whatever its evidence: the steps, the warm start, the E-step, the
transitions' M-step and the decoding.

A soft round weighs a clone of symbol ``k`` at a step by its *evidence*, the ``emit`` table of a
:class:`~topomap.core.refine.soft_kernels.SoftModel` (clones x read symbols): the confusion
matrix's row of ``k`` at the symbol read (:func:`~topomap.core.refine.soft.soft_round`, steps
as read: :func:`episode_data`), or, each step its own "read symbol", the likelihood of ``k``
under the step's own observation (:func:`~topomap.core.refine.observed.observed_round`).  Both
start from a hard labelling (:func:`warm_counts`), iterate :func:`soft_estep` and
:func:`normalise_transitions`, and decode with :func:`decode`.  Kernels:
:mod:`topomap.core.refine.soft_kernels`.
"""

from __future__ import annotations

import numpy as np

from .soft_kernels import (SoftData, SoftModel, SoftStats, read_tables, soft_backward,
                           soft_candidates, soft_forward, soft_forward_read, soft_offsets,
                           soft_viterbi)

__all__ = ["READ_DENSE", "episode_data", "warm_counts", "evidence_model", "log_model",
           "normalise_transitions", "soft_estep", "decode"]

#: ``reading.read_share`` acts where the candidates are at least this share of the clones
#: (gridroom 8 x 6 1.0, random_graph 60 0.85; the office 0.1-0.13, where it saved no time but
#: moved ARIs)
READ_DENSE = 0.5


def episode_data(seq) -> SoftData:
    """The steps of ``seq`` (a :class:`~topomap.core.refine.sequence.SymbolSequence`) as a soft
    round reads them: every step's symbol as read, its action, and whether a step follows it in
    its episode."""
    has_next = np.ones(seq.T, dtype=bool)
    has_next[np.cumsum(seq.lengths) - 1] = False
    return SoftData(np.ascontiguousarray(seq.sym, dtype=np.int64),
                    np.ascontiguousarray(seq.u, dtype=np.int64), has_next)


def warm_counts(data: SoftData, labels, state_symbol, keep, n_symbols: int, n_actions: int,
                spare: int, rng):
    """Transition counts (A, S, S) of a warm start and the clones' symbols: every kept state a
    clone (renumbered) with the labelling's transitions between kept states, then ``spare`` clones
    of every K-means symbol with random rows."""
    labels, n_kept = np.asarray(labels, dtype=np.int64), int(keep.sum())
    rename = np.full(state_symbol.size, -1, dtype=np.int64)
    rename[keep] = np.arange(n_kept)
    clone_symbol = np.concatenate([state_symbol[keep],
                                   np.repeat(np.arange(n_symbols, dtype=np.int64), spare)])
    S, A = clone_symbol.size, n_actions
    x = rename[labels]
    t = np.flatnonzero(data.has_next)
    ok = (x[t] >= 0) & (x[t + 1] >= 0)
    counts = np.zeros((A, S, S))
    np.add.at(counts, (data.u[t[ok]], x[t[ok]], x[t[ok] + 1]), 1.0)
    if spare:
        per_row = max(1.0, counts.sum() / max(n_kept, 1) / A)
        counts[:, n_kept:, :] = rng.random((A, S - n_kept, S)) * per_row / S * 4
        counts[:, :, n_kept:] += rng.random((A, S, S - n_kept)) * 0.1
    return counts, clone_symbol


def evidence_model(trans, emit, init, floor) -> SoftModel:
    """The model of a soft E-step: evidence ``emit`` under ``floor`` is 0 (a read symbol no
    clone may explain then allows every clone, at ``floor``), and its candidates."""
    emit = np.where(emit >= floor, emit, 0.0)
    empty = emit.sum(axis=0) == 0
    emit[:, empty] = floor
    cptr, cidx = soft_candidates(emit)
    return SoftModel(trans, np.ascontiguousarray(emit), init, cptr, cidx)


def log_model(model: SoftModel) -> SoftModel:
    """``model`` with the logarithms of its transitions, evidence and start (for Viterbi)."""
    with np.errstate(divide="ignore"):
        return SoftModel(np.log(model.trans), np.log(model.emit), np.log(model.init),
                         model.cptr, model.cidx)


def normalise_transitions(counts, pseudo):
    """The transitions ``P(x'|x,u)`` of the expected counts ``counts`` (A, S, S) with the
    pseudocount ``pseudo`` per entry, computed in place (``counts`` is not kept)."""
    z = counts.sum(axis=2, keepdims=True) + pseudo * counts.shape[1]
    return np.divide(np.add(counts, pseudo, out=counts), z, out=counts)


def soft_estep(data: SoftData, model: SoftModel, clone_symbol, *, prune: float,
               read_share: float = 0.0):
    """One soft E-step on ``model``: the expected counts (:class:`SoftStats`) and the
    log-likelihood.  ``prune``: filtered probabilities dropped in the forward pass;
    ``read_share`` > 0 where candidates are dense (:data:`READ_DENSE`): the forward pass
    :func:`~topomap.core.refine.soft_kernels.soft_forward_read`."""
    A, S, n_ids = model.trans.shape[0], model.trans.shape[1], model.emit.shape[1]
    pos = soft_offsets(data, model)
    if read_share and pos[-1] >= READ_DENSE * S * data.read.size:
        alpha, log_c = soft_forward_read(data, model, pos, prune, clone_symbol,
                                         read_tables(model, clone_symbol, n_ids), read_share)
    else:
        alpha, log_c = soft_forward(data, model, pos, prune)
    stats = SoftStats(np.zeros((A, S, S)), np.zeros((S, n_ids)), np.zeros(S))
    soft_backward(data, model, pos, alpha, log_c, stats)
    return stats, float(log_c.sum())


def decode(data: SoftData, model: SoftModel):
    """``model``'s Viterbi path of the steps and its log-probability."""
    path, log_p = soft_viterbi(data, log_model(model), soft_offsets(data, model))
    return path, float(log_p)
