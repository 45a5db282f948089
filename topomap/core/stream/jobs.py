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
from threadpoolctl import threadpool_limits

from ..phase1.clustering import predict_rows
from .moments import Moments, chunk_moments, combine, keyed_combine

__all__ = ["Codebook", "LogResult", "sample_job", "assign_job"]

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
    direct = logs.plain_rows(i, picks)
    if direct is not None:
        return direct
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
    return predict_rows(codebook.kmeans, Z, finite=True)  # the rows were checked when read


class _Gathered:
    """What :func:`assign_job` gathers over a log's chunks."""

    def __init__(self, steps: int, k: int, action_dtype):
        self.raw = np.empty(steps, dtype=np.int16 if k < 2**15 else np.int32)
        self.actions = np.empty(steps, dtype=action_dtype)
        self.plain = self.gds = None
        self.gds_steps, self.gds_ids, self.seen = [], [], 0

    def add(self, codebook: Codebook, i: int, start: int, rows, full: bool) -> None:
        """Chunk ``[start, ...)`` of log ``i`` (its ``rows``: observations, actions, GDS):
        its symbols and actions written, its moments combined."""
        X, u, g = rows
        k = codebook.kmeans.cluster_centers_.shape[0]
        stop = start + u.size
        self.actions[start:stop] = u
        plain = g < 0
        everything = bool(plain.all())
        sym = _symbols(codebook, i, X if everything else X[plain], self.seen)
        self.raw[start:stop][plain] = sym
        self.raw[start:stop][~plain] = -1
        self.seen += sym.size
        cm = chunk_moments(X if everything else X[plain], sym, k, full)
        self.plain = cm if self.plain is None else combine(self.plain, cm)
        if not everything:
            where = np.flatnonzero(~plain)
            keys, group = np.unique(g[where], return_inverse=True)
            cg = (keys, chunk_moments(X[where], group, keys.size, full))
            self.gds = cg if self.gds is None else keyed_combine(self.gds, cg)
            self.gds_steps.append(where + start)
            self.gds_ids.append(g[where])


def assign_job(logs, i: int, steps: int, codebook: Codebook, full: bool,
               action_dtype=np.int64) -> LogResult:
    """Log ``i``'s symbols, actions (as ``action_dtype``), GDS steps and moments, chunk by
    chunk (``full``: (D, D) scatter matrices for full covariances)."""
    got = _Gathered(steps, codebook.kmeans.cluster_centers_.shape[0], action_dtype)
    with threadpool_limits(limits=1, user_api="blas"):  # as the in-memory fit assigns them
        for start, stop in logs.chunks(i, steps):
            got.add(codebook, i, start, logs.rows(i, start, stop), full)
    D = got.plain.mean.shape[1]
    gds = got.gds or (np.empty(0, dtype=np.int64), Moments.empty(0, D, full))
    cat = (lambda parts: np.concatenate(parts) if parts else np.empty(0, dtype=np.int64))
    return LogResult(got.raw, got.actions, cat(got.gds_steps), cat(got.gds_ids), got.plain,
                     gds, _whole(got.plain, gds[1], D))


def _whole(plain: Moments, gds: Moments, D: int) -> Moments:
    """The per-feature moments of all rows, from the groups' (in group order)."""
    out = Moments.empty(1, D, False)
    for m in (plain, gds):
        for g in np.flatnonzero(m.n):
            m2 = np.diagonal(m.m2[g]) if m.m2.ndim == 3 else m.m2[g]
            out = combine(out, Moments(m.n[g:g + 1], m.mean[g:g + 1], m2[None]))
    return out
