"""Compare learned states with ground-truth places.

All functions take the learned state of every step and the true place of every step (two int
arrays of the same length).
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import adjusted_rand_score, normalized_mutual_info_score
from sklearn.metrics.cluster import contingency_matrix

__all__ = ["adjusted_rand", "nmi", "purity", "compound_states", "evaluate"]


def _check(states, places):
    s = np.asarray(states)
    p = np.asarray(places)
    if s.ndim != 1 or p.ndim != 1 or s.shape != p.shape:
        raise ValueError(
            f"states and places must be 1-D arrays of the same length, got {s.shape} and {p.shape}"
        )
    if s.size == 0:
        raise ValueError("states and places are empty")
    return s, p


def adjusted_rand(states, places) -> float:
    """Adjusted Rand index (1 = the same partition of the steps, about 0 = chance)."""
    return float(adjusted_rand_score(*_check(places, states)))


def nmi(states, places) -> float:
    """Normalised mutual information (arithmetic normalisation, as scikit-learn's default)."""
    return float(normalized_mutual_info_score(*_check(places, states)))


def purity(states, places) -> float:
    """Share of steps whose state's most common place is their own place."""
    s, p = _check(states, places)
    C = contingency_matrix(s, p)
    return float(C.max(axis=1).sum() / s.size)


def compound_states(states, places, min_share: float = 0.0) -> int:
    """Number of states that hold steps of more than one place.

    A place counts for a state only if it holds more than ``min_share`` of that state's steps
    (0: any single step makes a state compound, the strict reading).
    """
    if not 0 <= min_share < 1:
        raise ValueError(f"min_share must lie in [0, 1), got {min_share!r}")
    s, p = _check(states, places)
    C = contingency_matrix(s, p).astype(float)
    share = C / C.sum(axis=1, keepdims=True)
    return int(np.sum((share > min_share).sum(axis=1) > 1))


def evaluate(states, places) -> dict:
    """All of the above in one dict (also the number of states and of places)."""
    s, p = _check(states, places)
    return {
        "ari": adjusted_rand(s, p),
        "nmi": nmi(s, p),
        "purity": purity(s, p),
        "compound_states": compound_states(s, p),
        "n_states": int(np.unique(s).size),
        "n_places": int(np.unique(p).size),
    }
