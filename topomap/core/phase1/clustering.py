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

How K-means runs (``method`` of :func:`cluster_observations`, ``MapLearner(phase1=...)``):

``"full"``
    scikit-learn ``KMeans`` on every row: the paper's method, exactly.
``"distinct"``
    ``KMeans`` on the distinct rows with their counts as ``sample_weight``.  The objective is the
    full one (a repeated row contributes count x its squared distance), so it is exact for data
    that repeat (MiniGrid views, noise-free worlds).
``"sample"``
    ``KMeans`` on ``sample_size`` rows drawn without replacement (default ``64 * ns``, at least
    20,000), then every row assigned to its nearest centre (the labels of scikit-learn's ``predict``,
    by :mod:`~topomap.core.phase1.assign`'s pruned search);
    when the sample would hold every row this is ``"full"``.
``"minibatch"``
    scikit-learn ``MiniBatchKMeans`` over all rows.
``"auto"`` (default)
    ``"full"`` while ``T * ns * D <= 1e7`` (the paper's run: T = 2000, ns = 20, D = 15), else
    ``"distinct"`` when the rows repeat (at most half of them distinct; above 65,536 rows judged
    on a seeded sample of that size), else ``"sample"``.  So every run of up to 20,000 steps
    whose rows do not repeat gets the exact full fit.

All methods run with single-threaded BLAS (see :func:`_run`).  From ``PRUNED_CLUSTERS`` (50)
clusters on, ``KMeans`` is seeded by :class:`~topomap.core.phase1.seeding.PrunedPlusPlus`, and
from ``MIN_CLUSTERS`` (100) on also iterated by Elkan's algorithm: scikit-learn's own k-means++
and Lloyd iterations with the distances the triangle inequality rules out left uncomputed.  From that many clusters on, the
``"full"``, ``"distinct"`` and ``"sample"`` fits are also checked for a view cut in two
(:mod:`topomap.core.phase1.repair`): two centres closer than half their clusters' rms spread are
joined and K-means runs again, kept only when its inertia falls by at least 1 %; what was found
is ``details["cut_views"]`` (``MapLearner.cluster_choice_``).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from sklearn import config_context
from sklearn.cluster import KMeans, MiniBatchKMeans
from sklearn.mixture import GaussianMixture
from sklearn.utils import assert_all_finite
from threadpoolctl import ThreadpoolController

from ..checks import ParameterError, check_count
from ..progress import report
from .assign import nearest_centres
from .distinct import distinct_rows
from .repair import repair_cut_views
from .seeding import MIN_CLUSTERS, PRUNED_CLUSTERS, PrunedPlusPlus

__all__ = [
    "Euclidean",
    "Standardized",
    "Cosine",
    "FixedClusters",
    "BICClusters",
    "METRICS",
    "make_metric",
    "cluster_observations",
    "view_clusters",
    "METHODS",
    "choose_method",
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
            raise ParameterError(
                "metric", f"{metric!r} is unknown; choose one of {', '.join(sorted(METRICS))}"
            ) from None
    if not hasattr(metric, "fit_transform"):
        raise ParameterError("metric", f"{metric!r} has no fit_transform(X) method")
    return metric


class FixedClusters:
    """Use exactly ``ns`` clusters (the paper's setting)."""

    name = "fixed"

    def __init__(self, ns: int = 20):
        self.ns = check_count(ns, "ns")

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
        self.min_ns, self.max_ns = check_count(min_ns, "min_ns"), check_count(max_ns, "max_ns")
        self.step, self.n_init = check_count(step, "step"), check_count(n_init, "n_init")
        if max_ns < min_ns:
            raise ParameterError("max_ns", f"({max_ns}) is below min_ns ({min_ns})")
        if covariance_type not in ("full", "diag", "tied", "spherical"):
            raise ParameterError("covariance_type", "must be full, diag, tied or spherical, "
                                                    f"got {covariance_type!r}")
        self.covariance_type = covariance_type

    @property
    def min_clusters(self) -> int:
        """The fewest clusters this policy can choose (known before any data is seen)."""
        return self.min_ns

    def choose(self, Z: np.ndarray, random_state: int):
        n_distinct = np.unique(Z, axis=0).shape[0]
        candidates = [k for k in range(self.min_ns, self.max_ns + 1, self.step) if k <= n_distinct]
        if not candidates:
            raise ParameterError(
                "min_ns", f"={self.min_ns} exceeds the {n_distinct} distinct observations")
        bic = {}
        report("BIC", 0, len(candidates))
        for i, k in enumerate(candidates):
            gm = GaussianMixture(k, covariance_type=self.covariance_type, n_init=self.n_init,
                                 random_state=random_state, reg_covar=1e-6)
            bic[k] = float(gm.fit(Z).bic(Z))
            report("BIC", i + 1, len(candidates))
        return min(bic, key=lambda k: (bic[k], k)), {"bic": bic}

    def __repr__(self) -> str:
        return f"BICClusters(min_ns={self.min_ns}, max_ns={self.max_ns}, step={self.step})"


METHODS = ("auto", "full", "distinct", "sample", "minibatch")
#: ``T * ns * D`` up to which ``method="auto"`` runs the exact full K-means
FULL_BUDGET = 10_000_000
_MIN_SAMPLE = 20_000


#: above this many rows, whether the rows repeat is judged on a seeded sample of this size
PROBE_ROWS = 65_536


def choose_method(n_rows: int, repeats: bool, n_clusters: int, n_features: int,
                  full_budget: int = FULL_BUDGET) -> str:
    """The method ``"auto"`` stands for (see the module docstring)."""
    if n_rows * n_clusters * n_features <= full_budget:
        return "full"
    return "distinct" if repeats else "sample"


def probe_distinct(Z: np.ndarray, n_clusters: int, random_state: int):
    """``(repeats, distinct)``: whether at most half of the rows are distinct, and the exact
    :func:`topomap.core.phase1.distinct.distinct_rows` of ``Z`` or None when they are not needed.

    Above :data:`PROBE_ROWS` rows a seeded sample of that size is looked at first; when more than
    half of its rows are distinct and they are at least ``n_clusters``, the rows are taken not to
    repeat and the full count is skipped (it can only be larger).
    """
    T = Z.shape[0]
    if T > PROBE_ROWS:
        rows = np.sort(np.random.default_rng(random_state).choice(T, PROBE_ROWS, replace=False))
        n_probe = distinct_rows(Z[rows])[0].size
        if 2 * n_probe > PROBE_ROWS and n_probe >= n_clusters:
            return False, None
    distinct = distinct_rows(Z)
    return 2 * distinct[0].size <= T, distinct


@njit(cache=True)
def first_appearance_order(labels, k):
    """``rename`` with ``rename[label]`` = rank of the label's first appearance (labels that never
    appear get -1) and the number of labels that appear."""
    rename = np.full(k, -1, dtype=np.int64)
    n = 0
    for t in range(labels.size):
        if rename[labels[t]] < 0:
            rename[labels[t]] = n
            n += 1
    return rename, n


def view_clusters(Z, k: int, n_init: int, random_state) -> np.ndarray:
    """(T,) K-means on the views ``Z`` (T, D), ``k`` clusters numbered by first appearance:
    scikit-learn's ``KMeans`` on every row, ``n_init`` k-means++ starts (BLAS on one thread).
    The one clustering of the views into as many clusters as a map has states: the view
    clusters a continuous log's map falls back to (:mod:`topomap.core.motion`) and the
    yardstick "K-means on the views" (:func:`topomap.evaluation.metres.kmeans_view_scores`)."""
    with one_blas_thread():
        labels = KMeans(int(k), n_init=int(n_init), random_state=random_state).fit(Z).labels_
    labels = np.asarray(labels, dtype=np.int64)
    rename, _ = first_appearance_order(labels, int(k))
    return rename[labels]


def _kmeans(ns, n_init, random_state, sample_weight=None):
    """scikit-learn's ``KMeans``; from :data:`PRUNED_CLUSTERS` clusters on seeded by
    :class:`PrunedPlusPlus` (its k-means++ with fewer distances computed, the same centres), from
    :data:`MIN_CLUSTERS` on also run by Elkan's algorithm (Lloyd's iterations with the distances
    the triangle inequality rules out skipped: FourRooms' 450 clusters in 0.6 of Lloyd's time,
    the same labels)."""
    if ns < PRUNED_CLUSTERS:
        return KMeans(n_clusters=ns, n_init=n_init, random_state=random_state)
    if ns < MIN_CLUSTERS:
        return KMeans(n_clusters=ns, init=PrunedPlusPlus(sample_weight), n_init=n_init,
                      random_state=random_state)
    return KMeans(n_clusters=ns, init=PrunedPlusPlus(sample_weight), n_init=n_init,
                  random_state=random_state, algorithm="elkan")


def _fitted(Z, ns, n_init, random_state, repair, weight=None):
    """``(KMeans fitted on Z, what the repair found)``; from :data:`MIN_CLUSTERS` clusters on,
    when ``repair``, with the views it cut in two repaired
    (:func:`~topomap.core.phase1.repair.repair_cut_views`)."""
    km = _kmeans(ns, n_init, random_state, weight).fit(Z, sample_weight=weight)
    if ns < MIN_CLUSTERS or not repair:
        return km, None
    return repair_cut_views(km, Z, weight, random_state)


def _fit_full(Z, ns, n_init, random_state, repair=True, **_):
    km, info = _fitted(Z, ns, n_init, random_state, repair)
    return km.labels_, info


def _fit_distinct(Z, ns, n_init, random_state, distinct, repair=True, **_):
    first, inverse, counts = distinct
    km, info = _fitted(Z[first], ns, n_init, random_state, repair, counts.astype(np.float64))
    return km.labels_[inverse], info


def sample_rows(n_clusters: int, sample_size: int | None = None) -> int:
    """Rows ``"sample"`` fits K-means on."""
    return sample_size or max(_MIN_SAMPLE, 64 * n_clusters)


def predict_rows(km, Z, finite=False) -> np.ndarray:
    """``km.predict(Z)`` as int64, found by :func:`~topomap.core.phase1.assign.nearest_centres`
    (the same labels, most distances never computed; ``finite``: the rows are known to be
    finite, not checked again)."""
    if not finite:
        assert_all_finite(Z, input_name="X")
    with config_context(assume_finite=True):  # checked once, here or by the caller
        return nearest_centres(km, np.ascontiguousarray(Z))


def _fit_sample(Z, ns, n_init, random_state, sample_size=None, repair=True, finite=False, **_):
    T, m = Z.shape[0], sample_rows(ns, sample_size)
    rows = np.sort(np.random.default_rng(random_state).choice(T, size=m, replace=False))
    km, info = _fitted(Z[rows], ns, n_init, random_state, repair)
    return predict_rows(km, Z, finite), info  # rows checked already: not checked again


def _fit_minibatch(Z, ns, n_init, random_state, **_):
    km = MiniBatchKMeans(n_clusters=ns, n_init=n_init, random_state=random_state,
                         batch_size=max(1024, 8 * ns))
    return km.fit(Z).labels_, None


_FITTERS = {"full": _fit_full, "distinct": _fit_distinct, "sample": _fit_sample,
            "minibatch": _fit_minibatch}


_BLAS = []


def one_blas_thread():
    """``threadpoolctl``'s limit of every BLAS to one thread, from one controller made at the
    first call (a ``threadpool_limits`` looks up every loaded library anew: about 5 ms)."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


def one_thread():
    """:func:`one_blas_thread`'s limit of every BLAS and of every OpenMP runtime to one thread."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1)


def _run(method, Z, ns, **kw):
    """Run a fitter with single-threaded BLAS and OpenMP.  k-means++ multiplies many small
    matrices, which multithreaded OpenBLAS makes 3-15x slower on a busy 2-core machine
    (scikit-learn already limits BLAS inside its Lloyd and assignment loops).  Each product's
    entries are computed the same way whatever the thread count: the full fit's labels were
    checked identical with and without the limit (12 data sets, and every configuration of the
    identity tests).  Lloyd's iterations run on OpenMP threads, which on a busy 2-core machine
    wait for each other: gridroom 8x6's 10,000 steps took 0.14-0.59 s of phase 1 on two threads
    and 0.009-0.019 s on one, with the same labels on 9 walks at 0-18 % misreads (load 2.7-3.5,
    2026-12-03)."""
    with one_thread():
        return _FITTERS[method](Z, ns, **kw)


def cluster_observations(X: np.ndarray, policy, metric, *, n_init: int = 10,
                         random_state: int = 0, method: str = "auto",
                         sample_size: int | None = None, repair: bool = True,
                         checked: bool = False) -> tuple[np.ndarray, dict]:
    """K-means symbols for the rows of ``X`` (GDS steps already removed).

    Returns ``(symbols, details)``: int64 symbols in ``[0, ns)`` numbered by first appearance in
    time (a cluster left empty by ``"sample"`` or ``"minibatch"`` is dropped, so ``ns`` may
    shrink) and what the cluster-count policy reported plus ``"method"``, the phase-1 method that
    ran (``"auto"`` resolved; see :data:`METHODS`).  Raises a
    :class:`~topomap.core.checks.ParameterError` naming ``ns`` (the count the policy chose) when
    more clusters are asked for than there are distinct observations.  ``repair=False`` leaves
    views K-means cut in two as they are (:mod:`topomap.core.phase1.repair`).  ``checked=True``
    says that every value of ``X`` is known to be finite: where the metric passes ``X`` through
    unchanged, scikit-learn's assignment of every row does not check it again (the same labels).
    """
    if method not in METHODS:
        raise ParameterError("method", f"={method!r} is unknown; choose one of {', '.join(METHODS)}")
    Z = metric.fit_transform(X)  # float32 stays float32: scikit-learn's K-means computes in it
    Z = np.ascontiguousarray(Z, dtype=np.float32 if Z.dtype == np.float32 else np.float64)
    choice = policy.choose(Z, random_state)
    ns, details = choice if isinstance(choice, tuple) else (choice, {})
    ns = int(ns)
    repeats, distinct = probe_distinct(Z, ns, random_state)
    n_distinct = distinct[0].size if distinct is not None else None
    if n_distinct is not None and ns > n_distinct:
        raise ParameterError("ns", f"={ns} is more than the {n_distinct} distinct observations "
                                   "(GDS steps excluded); lower the cluster count")
    if method == "auto":
        method = choose_method(Z.shape[0], repeats, ns, Z.shape[1])
    if method == "distinct" and distinct is None:
        distinct = distinct_rows(Z)
    if method == "sample" and sample_rows(ns, sample_size) >= Z.shape[0]:
        method = "full"  # the sample would hold every row
    labels, cut = _run(method, Z, ns, n_init=n_init, random_state=random_state,
                       distinct=distinct, sample_size=sample_size, repair=repair,
                       finite=checked and Z is X)
    if cut is not None:
        details = dict(details, cut_views=cut)
    labels = np.asarray(labels)  # scikit-learn's int32: renaming gives int64 without a copy
    rename, _ = first_appearance_order(labels, ns)
    if labels.dtype == np.int64:  # the sample's own array: renamed in place
        return _renamed(labels, rename), dict(details, method=method)
    return rename[labels], dict(details, method=method)


@njit(cache=True)
def _renamed(labels, rename):
    for t in range(labels.size):
        labels[t] = rename[labels[t]]
    return labels
