"""The confusion matrix of the soft rounds (:mod:`topomap.core.refine.soft`): a clone of symbol
``k`` reads ``r`` with probability ``C[k, r]``; where it starts, how EM learns it, and the share of
steps it and EM's counts explain as misread.  GDS ids are never confused."""

from __future__ import annotations

import numpy as np

__all__ = ["initial_confusion", "co_successors", "confusion_mstep", "misread_rate",
           "misread_share"]


def initial_confusion(n_ids: int, n_symbols: int, error: float, allowed=None) -> np.ndarray:
    """``1 - error`` on the diagonal, ``error`` spread evenly over the other K-means symbols;
    identity on GDS ids.  With ``allowed`` (n_symbols, n_symbols) bool, only the allowed pairs
    get their share ``error / (n_symbols - 1)`` and the diagonal the rest of the row: symbols
    never confused with another start without its clones as candidates."""
    C = np.eye(n_ids)
    if n_symbols > 1:
        k = np.arange(n_symbols)
        off = np.full((n_symbols, n_symbols), error / (n_symbols - 1))
        off[k, k] = 0.0
        if allowed is not None:
            off = np.where(allowed, off, 0.0)
        C[:n_symbols, :n_symbols] = off
        C[k, k] = 1.0 - error if allowed is None else 1.0 - off.sum(axis=1)
    return C


def co_successors(seq, labels) -> np.ndarray:
    """(n_symbols, n_symbols) bool: the pairs of K-means symbols that follow one (state, action)
    of the labelling (each, at some step): the readings a misread can swap.  Where every
    (state, action) is followed by one symbol, no pair is."""
    t = np.flatnonzero(seq.masks()[1])
    key = labels[t] * seq.n_actions + seq.u[t]
    nxt = seq.sym[t + 1]
    plain = nxt < seq.n_symbols
    pairs = np.unique(key[plain] * seq.n_symbols + nxt[plain])
    key, nxt = pairs // seq.n_symbols, pairs % seq.n_symbols
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    size = np.diff(np.r_[first, key.size])
    allowed = np.zeros((seq.n_symbols, seq.n_symbols), dtype=bool)
    for f, n in zip(first[size > 1].tolist(), size[size > 1].tolist()):
        group = nxt[f:f + n]
        allowed[np.ix_(group, group)] = True
    return allowed


def confusion_mstep(N: np.ndarray, n_symbols: int, s) -> np.ndarray:
    """Confusion matrix from the expected (true symbol x read symbol) counts ``N``, with the
    diagonal-favouring Dirichlet prior (``s.conf_diag``, ``s.conf_off`` of the reading settings
    ``s``, :class:`~topomap.core.refine.settings.Reading`); GDS rows/columns stay the
    identity."""
    C = np.eye(N.shape[0])
    k = n_symbols
    M = N[:k, :k] + s.conf_off + np.eye(k) * (s.conf_diag - s.conf_off)
    C[:k, :k] = M / M.sum(axis=1, keepdims=True)
    return C


def misread_rate(conf, n_symbols: int) -> float:
    """The share of steps read as another symbol: the mean off-diagonal mass of the K-means rows
    of the confusion matrix ``conf`` (``conf_offdiag`` in a soft round's record of map.json)."""
    return float(1.0 - np.mean(np.diag(conf)[:n_symbols]))


def misread_share(N, n_symbols: int) -> float:
    """The share of the K-means steps EM explains as misread: the off-diagonal part of the
    expected (true symbol x read symbol) counts ``N`` of its last E-step.  Unlike
    :func:`misread_rate` it holds no prior (whose ``conf_off`` pseudo-counts outweigh a symbol
    seen a few dozen times: FourRooms' 450 symbols at 10,000 steps read 40 % from it alone)."""
    k = n_symbols
    total = float(N[:k, :k].sum())
    return 0.0 if total == 0 else float(1.0 - np.trace(N[:k, :k]) / total)
