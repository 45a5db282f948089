"""How surely phase 1 reads the symbol of a step: the share of steps its observation model
leaves ambiguous between two symbols.

Phase 1 models every K-means symbol ``k`` by a Gaussian ``N(o; mu_k, Sigma_k)`` (the phase-1
map's ``means`` and ``covariances``) and its share ``w_k`` of the steps.  Under that model the
symbol of an observation ``o`` is ``k`` with posterior ``P(k | o) ∝ w_k N(o; mu_k, Sigma_k)``,
and ``1 - max_k P(k | o)`` is the chance that the symbol read, the most probable one, is not the
one that made ``o``.  Its mean over the steps, :func:`symbol_ambiguity`, estimates the share of
misread symbols (the Bayes error of reading them): 0 where every observation lies far nearer
one symbol's model than any other's (exact readings, also of aliased places), about the overlap
of two symbols' Gaussians where noise carries observations across the boundary between them.
"""

from __future__ import annotations

import numpy as np

from ..map.observations import log_density_chunks

__all__ = ["SAMPLE", "symbol_ambiguity"]

#: the steps :func:`symbol_ambiguity` averages over at most (a seeded sample): its error is about
#: ``sqrt(a / SAMPLE)`` for an ambiguity ``a`` (0.0007 at a = 1 %), and 10^7 steps cost no more
SAMPLE = 20_000


def symbol_ambiguity(X, symbols, means, covariances, random_state: int = 0,
                     sample: int = SAMPLE) -> float:
    """The mean over (a sample of) the steps of ``1 - max_k P(k | o)`` (module docstring).

    ``X``: the observations of the steps; ``symbols``: their phase-1 states, the symbols in
    ``[0, M)`` (steps with a state ``>= M``, the GDS ones, are left out); ``means`` (M, D) and
    ``covariances`` ((M, D) diagonal or (M, D, D) full): the symbols' Gaussians; the priors
    ``w_k`` are the symbols' shares of the steps.  Where there are more than ``sample`` steps,
    ``sample`` of them drawn with ``random_state`` (with replacement) stand for all.  0.0 with
    fewer than two symbols or no steps."""
    symbols = np.asarray(symbols)
    M = means.shape[0]
    counts = np.bincount(symbols, minlength=M)[:M]
    if counts.sum() == 0 or M < 2:
        return 0.0
    rows = np.arange(symbols.size)
    if symbols.size > sample:
        rows = np.sort(np.random.default_rng(random_state).integers(0, symbols.size, sample))
    rows = rows[symbols[rows] < M]
    if not rows.size:
        return 0.0
    with np.errstate(divide="ignore"):
        log_w = np.log(counts / counts.sum())
    total = 0.0
    for _, logp in log_density_chunks(np.asarray(X[rows], dtype=np.float64), means, covariances):
        joint = logp + log_w
        top = joint.max(axis=1, keepdims=True)
        total += float(np.sum(1.0 - 1.0 / np.exp(joint - top).sum(axis=1)))
    return total / rows.size
