"""Phase 1 (paper Section 3.2): discretise the observation space with K-means.

Two kinds of swappable pieces live here, each a small object with one method:

* distance metrics -- ``fit_transform(X)`` maps observations into a space where the Euclidean
  distance is the wanted one (K-means then runs there): :class:`Euclidean`, :class:`Standardized`,
  :class:`Cosine`;
* cluster-count policies -- ``choose(Z, random_state)`` decides ``ns`` and returns it, or
  ``(ns, details)`` with a dict of what it measured (kept as ``MapLearner.cluster_choice_``):
  :class:`FixedClusters` and :class:`BICClusters` (Gaussian mixture BIC over a range of counts,
  the paper's suggested remedy for having to fix ``ns`` in advance).

Policies and metrics are not changed by use: everything a fit learns is returned.
"""

from __future__ import annotations

import numpy as np
from sklearn.cluster import KMeans
from sklearn.mixture import GaussianMixture

__all__ = [
    "Euclidean",
    "Standardized",
    "Cosine",
    "FixedClusters",
    "BICClusters",
    "METRICS",
    "make_metric",
    "cluster_observations",
]


class Euclidean:
    """The ordinary Euclidean norm, as in the paper."""

    name = "euclidean"

    def fit_transform(self, X: np.ndarray) -> np.ndarray:
        return X


class Standardized:
    """Euclidean distance after scaling every feature to unit variance (a diagonal Mahalanobis
    distance).  Features that never vary are left unscaled."""

    name = "standardized"

    def fit_transform(self, X: np.ndarray) -> np.ndarray:
        std = X.std(axis=0)
        std[std == 0] = 1.0
        return (X - X.mean(axis=0)) / std


class Cosine:
    """Cosine distance: observations are scaled to unit length, so K-means compares directions
    (the pattern of what is seen) rather than magnitudes.  All-zero observations stay zero."""

    name = "cosine"

    def fit_transform(self, X: np.ndarray) -> np.ndarray:
        norm = np.linalg.norm(X, axis=1, keepdims=True)
        norm[norm == 0] = 1.0
        return X / norm


METRICS = {cls.name: cls for cls in (Euclidean, Standardized, Cosine)}


def make_metric(metric):
    """Return a metric object for a name in :data:`METRICS` or pass an object through."""
    if isinstance(metric, str):
        try:
            return METRICS[metric]()
        except KeyError:
            raise ValueError(
                f"metric {metric!r} is unknown; choose one of {', '.join(sorted(METRICS))}"
            ) from None
    if not hasattr(metric, "fit_transform"):
        raise ValueError(f"metric {metric!r} has no fit_transform(X) method")
    return metric


class FixedClusters:
    """Use exactly ``ns`` clusters (the paper's setting)."""

    name = "fixed"

    def __init__(self, ns: int = 20):
        if isinstance(ns, bool) or not isinstance(ns, (int, np.integer)) or ns < 1:
            raise ValueError(f"clusters.ns must be a positive integer, got {ns!r}")
        self.ns = int(ns)

    @property
    def min_clusters(self) -> int:
        """The fewest clusters this policy can choose (known before any data is seen)."""
        return self.ns

    def choose(self, Z: np.ndarray, random_state: int) -> int:
        return self.ns

    def __repr__(self) -> str:
        return f"FixedClusters(ns={self.ns})"


class BICClusters:
    """Choose ``ns`` in ``[min_ns, max_ns]`` (every ``step``-th value) as the component count of the
    scikit-learn ``GaussianMixture`` with the lowest BIC.

    ``covariance_type`` is passed to the mixture ("diag" by default: 15-dimensional full covariances
    need far more data per cluster than a topological map provides).  ``choose`` returns the
    chosen count and ``{"bic": {count: BIC}}``.
    """

    name = "bic"

    def __init__(self, min_ns: int = 5, max_ns: int = 40, step: int = 1,
                 covariance_type: str = "diag", n_init: int = 1):
        for key, value in (("min_ns", min_ns), ("max_ns", max_ns), ("step", step), ("n_init", n_init)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"clusters.{key} must be a positive integer, got {value!r}")
        if max_ns < min_ns:
            raise ValueError(f"clusters.max_ns ({max_ns}) is below clusters.min_ns ({min_ns})")
        if covariance_type not in ("full", "diag", "tied", "spherical"):
            raise ValueError(
                f"clusters.covariance_type must be full, diag, tied or spherical, got {covariance_type!r}"
            )
        self.min_ns, self.max_ns, self.step = int(min_ns), int(max_ns), int(step)
        self.covariance_type, self.n_init = covariance_type, int(n_init)

    @property
    def min_clusters(self) -> int:
        """The fewest clusters this policy can choose (known before any data is seen)."""
        return self.min_ns

    def choose(self, Z: np.ndarray, random_state: int):
        n_distinct = np.unique(Z, axis=0).shape[0]
        candidates = [k for k in range(self.min_ns, self.max_ns + 1, self.step) if k <= n_distinct]
        if not candidates:
            raise ValueError(
                f"clusters.min_ns={self.min_ns} exceeds the {n_distinct} distinct observations"
            )
        bic = {}
        for k in candidates:
            gm = GaussianMixture(k, covariance_type=self.covariance_type, n_init=self.n_init,
                                 random_state=random_state, reg_covar=1e-6)
            bic[k] = float(gm.fit(Z).bic(Z))
        return min(bic, key=lambda k: (bic[k], k)), {"bic": bic}

    def __repr__(self) -> str:
        return f"BICClusters(min_ns={self.min_ns}, max_ns={self.max_ns}, step={self.step})"


def cluster_observations(X: np.ndarray, policy, metric, *, n_init: int = 10,
                         random_state: int = 0) -> tuple[np.ndarray, dict]:
    """K-means symbols for the rows of ``X`` (GDS steps already removed).

    Returns ``(symbols, details)``: an int array of symbols in ``[0, ns)`` and what the
    cluster-count policy reported.  Raises ValueError when more clusters are asked for than there
    are distinct observations.
    """
    Z = np.ascontiguousarray(metric.fit_transform(X), dtype=np.float64)
    choice = policy.choose(Z, random_state)
    ns, details = choice if isinstance(choice, tuple) else (choice, {})
    ns = int(ns)
    n_distinct = np.unique(Z, axis=0).shape[0]
    if ns > n_distinct:
        raise ValueError(
            f"clusters.ns={ns} is more than the {n_distinct} distinct observations "
            "(GDS steps excluded); lower the cluster count"
        )
    km = KMeans(n_clusters=ns, n_init=n_init, random_state=random_state)
    labels = km.fit_predict(Z)
    # Name symbols by first appearance in time so the numbering does not depend on K-means'
    # internal order (and reads naturally along the trajectory).
    _, first = np.unique(labels, return_index=True)
    order = np.argsort(first, kind="stable")
    rename = np.empty(ns, dtype=np.int64)
    rename[order] = np.arange(ns)
    return rename[labels], dict(details)
