"""Learned states against ground-truth places: ARI, NMI, purity, compound states.

Public as :mod:`topomap.metrics`.

Every function takes ``(labels_true, labels_pred)``, in scikit-learn's order
(:func:`sklearn.metrics.adjusted_rand_score`): the true place of every step first, then the
learned state of every step (two int arrays of the same length); both may be given by keyword.
ARI and NMI are symmetric, but purity and the count of compound states are not: swapping the
arguments measures the places by the states instead::

    purity(labels_true=places, labels_pred=states)
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import adjusted_rand_score, normalized_mutual_info_score
from sklearn.metrics.cluster import contingency_matrix

from ..core.stats import majority_share

__all__ = ["adjusted_rand", "nmi", "purity", "compound_states", "evaluate"]


def _check(labels_true, labels_pred):
    t = np.asarray(labels_true)
    p = np.asarray(labels_pred)
    if t.ndim != 1 or p.ndim != 1 or t.shape != p.shape:
        raise ValueError("labels_true and labels_pred must be 1-D arrays of the same length, got "
                         f"{t.shape} and {p.shape}")
    if t.size == 0:
        raise ValueError("labels_true and labels_pred are empty")
    return t, p


def adjusted_rand(labels_true, labels_pred) -> float:
    """Adjusted Rand index (1 = the same partition of the steps, about 0 = chance)."""
    return float(adjusted_rand_score(*_check(labels_true, labels_pred)))


def nmi(labels_true, labels_pred) -> float:
    """Normalised mutual information (arithmetic normalisation, as scikit-learn's default)."""
    return float(normalized_mutual_info_score(*_check(labels_true, labels_pred)))


def purity(labels_true, labels_pred) -> float:
    """Share of steps whose state (``labels_pred``) has their own place (``labels_true``) as its
    most common place."""
    return majority_share(*_check(labels_true, labels_pred))


def compound_states(labels_true, labels_pred, min_share: float = 0.0) -> int:
    """Number of states (``labels_pred``) that hold steps of more than one place
    (``labels_true``).

    A place counts for a state only if it holds more than ``min_share`` of that state's steps
    (0: any single step makes a state compound, the strict reading).
    """
    if not 0 <= min_share < 1:
        raise ValueError(f"min_share must lie in [0, 1), got {min_share!r}")
    t, p = _check(labels_true, labels_pred)
    C = contingency_matrix(p, t).astype(float)  # rows: states
    share = C / C.sum(axis=1, keepdims=True)
    return int(np.sum((share > min_share).sum(axis=1) > 1))


def evaluate(labels_true, labels_pred) -> dict:
    """All of the above in one dict (also the number of states and of places)."""
    t, p = _check(labels_true, labels_pred)
    return {
        "ari": adjusted_rand(t, p),
        "nmi": nmi(t, p),
        "purity": purity(t, p),
        "compound_states": compound_states(t, p),
        "n_states": int(np.unique(p).size),
        "n_places": int(np.unique(t).size),
    }
