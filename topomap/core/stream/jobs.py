"""The work a streamed fit does on one log, wherever it runs: plain functions of the log set,
the log's index and small arguments, returning small results (what a worker sends back).

* :func:`sample_job` -- the observation rows of a log that phase 1's K-means is fitted on (its
  non-GDS rows at given positions), after the metric;
* :func:`assign_job` -- every step's K-means symbol (raw: as the fitted K-means numbers its
  clusters; -1 for GDS steps), the log's actions and GDS steps, and the moments of its
  observations per symbol, per GDS id and over all rows (:mod:`.moments`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn import config_context
from threadpoolctl import threadpool_limits

from .moments import Moments, chunk_moments, combine, keyed_combine

__all__ = ["Codebook", "LogResult", "sample_job", "assign_job", "PREDICT_ROWS"]

#: rows assigned to their nearest centre at once: a multiple of scikit-learn's own blocks of 256
#: rows, so that every row's symbol is the one a single ``predict`` over all rows gives
PREDICT_ROWS = 256 * 256


@dataclass
class Codebook:
    """Phase 1's fitted K-means (``kmeans``) with its ``metric``; ``fixed``: the symbol of every
    non-GDS row in order (the exact ``"full"`` fit, whose labels are K-means' own) with each
    log's first row in it (``offsets``), else None (every row goes to its nearest centre)."""

    kmeans: object
    metric: object
    fixed: np.ndarray | None = None
    offsets: np.ndarray | None = None


@dataclass
class LogResult:
    """What :func:`assign_job` returns for one log."""

    raw: np.ndarray          # (T_i,) int16/int32 raw K-means label, -1 at GDS steps
    actions: np.ndarray      # (T_i,) ids as the logs were made consistent
    gds_steps: np.ndarray    # positions of the GDS steps in the log
    gds_ids: np.ndarray      # their GDS ids
    plain: Moments           # per raw label (K of the codebook)
    gds: tuple               # (sorted GDS ids, Moments)
    whole: Moments           # over all rows (K = 1)


def sample_job(logs, i: int, steps: int, picks: np.ndarray) -> np.ndarray:
    """The rows ``picks`` (sorted positions among log ``i``'s non-GDS rows) after ``metric``
    is applied later by the caller: raw float64 observation rows."""
    out, seen = [], 0
    for start, stop in logs.chunks(i, steps):
        X, _, g = logs.rows(i, start, stop)
        plain = X[g < 0]
        lo, hi = np.searchsorted(picks, [seen, seen + plain.shape[0]])
        out.append(plain[picks[lo:hi] - seen])
        seen += plain.shape[0]
    return np.concatenate(out) if out else np.empty((0, 0))


def _symbols(codebook: Codebook, i: int, X: np.ndarray, seen: int) -> np.ndarray:
    """The raw symbols of the non-GDS rows ``X`` of log ``i`` (``seen`` of its non-GDS rows
    before them)."""
    if codebook.fixed is not None:
        first = int(codebook.offsets[i]) + seen
        return codebook.fixed[first:first + X.shape[0]]
    Z = np.ascontiguousarray(codebook.metric.fit_transform(X), dtype=np.float64)
    out = np.empty(Z.shape[0], dtype=np.int64)
    with threadpool_limits(limits=1, user_api="blas"), config_context(assume_finite=True):
        for a in range(0, Z.shape[0], PREDICT_ROWS):
            out[a:a + PREDICT_ROWS] = codebook.kmeans.predict(Z[a:a + PREDICT_ROWS])
    return out


def assign_job(logs, i: int, steps: int, codebook: Codebook, full: bool,
               action_dtype=np.int64) -> LogResult:
    """Log ``i``'s symbols, actions (as ``action_dtype``), GDS steps and moments, chunk by
    chunk (``full``: (D, D) scatter matrices for full covariances)."""
    k = codebook.kmeans.cluster_centers_.shape[0]
    raw = np.empty(steps, dtype=np.int16 if k < 2**15 else np.int32)
    actions = np.empty(steps, dtype=action_dtype)
    plain_m = whole = gds_m = None
    gds_steps, gds_ids, seen = [], [], 0
    for start, stop in logs.chunks(i, steps):
        X, u, g = logs.rows(i, start, stop)
        actions[start:stop] = u
        plain = g < 0
        sym = _symbols(codebook, i, X[plain] if not plain.all() else X, seen)
        seen += sym.size
        raw[start:stop][plain] = sym
        raw[start:stop][~plain] = -1
        cm = chunk_moments(X[plain], sym, k, full)
        plain_m = cm if plain_m is None else combine(plain_m, cm)
        cw = chunk_moments(X, np.zeros(X.shape[0], dtype=np.int64), 1, False)
        whole = cw if whole is None else combine(whole, cw)
        if not plain.all():
            where = np.flatnonzero(~plain)
            keys, group = np.unique(g[where], return_inverse=True)
            cg = (keys, chunk_moments(X[where], group, keys.size, full))
            gds_m = cg if gds_m is None else keyed_combine(gds_m, cg)
            gds_steps.append(where + start)
            gds_ids.append(g[where])
    if gds_m is None:
        gds_m = (np.empty(0, dtype=np.int64), Moments.empty(0, whole.mean.shape[1], full))
    cat = (lambda parts: np.concatenate(parts) if parts else np.empty(0, dtype=np.int64))
    return LogResult(raw, actions, cat(gds_steps), cat(gds_ids), plain_m, gds_m, whole)
