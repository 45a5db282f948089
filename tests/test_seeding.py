"""k-means++ seeding with pruned distances: scikit-learn's choices, fewer distances."""

import numpy as np
import pytest
from sklearn.cluster import KMeans, kmeans_plusplus

from topomap.core.phase1.clustering import Euclidean, FixedClusters, cluster_observations
from topomap.core.phase1.seeding import (MIN_CLUSTERS, PRUNED_CLUSTERS, PrunedPlusPlus,
                                         _rows_within_reach)


def blobs(n_blobs, per_blob, dim, seed, spread=0.05):
    """``n_blobs`` random centres in the unit cube, ``per_blob`` noisy rows around each."""
    rng = np.random.default_rng(seed)
    centres = rng.random((n_blobs, dim))
    X = np.repeat(centres, per_blob, axis=0) + rng.normal(0, spread, (n_blobs * per_blob, dim))
    return X[rng.permutation(X.shape[0])]


def test_rows_within_reach_by_hand():
    # two centres; row 0 is owned by centre 0 at distance 1 (closest 1), row 1 by centre 1 at
    # distance 0.5 (closest 0.25), row 2 by centre 0 at distance 0 (closest 0)
    owner = np.array([0, 1, 0])
    closest = np.array([1.0, 0.25, 0.0])
    # one candidate: 2.5 from centre 0 (> 2 x 1 and > 0: rows 0 and 2 out of reach),
    # 0.9 from centre 1 (<= 2 x 0.5: row 1 may come closer)
    centre_dist = np.array([[2.5, 0.9]])
    assert _rows_within_reach(centre_dist, owner, closest, 0.0).tolist() == [1]
    # a second candidate at 2.0 from centre 0: exactly 2 x 1, so row 0 may tie and is kept
    centre_dist = np.array([[2.5, 1.5], [2.0, 3.0]])
    assert _rows_within_reach(centre_dist, owner, closest, 0.0).tolist() == [0]
    # a margin of 0.6 widens row 1's reach to 2 x 0.5 + 0.6 = 1.6 >= 1.5; row 2's (0.6) stays
    # below both candidates' 2.5 and 2.0 from centre 0
    assert _rows_within_reach(centre_dist, owner, closest, 0.6).tolist() == [0, 1]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_same_centres_as_scikit_learns_kmeans_plusplus(seed):
    X = blobs(60, 30, 8, seed)
    X -= X.mean(axis=0)
    theirs, _ = kmeans_plusplus(X, 80, random_state=np.random.RandomState(seed))
    ours = PrunedPlusPlus()(X, 80, np.random.RandomState(seed))
    assert np.array_equal(ours, theirs)


@pytest.mark.parametrize("all_rows", [0.0, 0.5, 1.01])
def test_the_same_centres_whichever_rows_are_computed(all_rows, monkeypatch):
    # every candidate's distances to all rows (0), to those within reach (1.01: never all), or
    # either by the share within reach (0.5): scikit-learn's centres each time
    import topomap.core.phase1.seeding as seeding

    shares = []
    within = seeding._rows_within_reach
    monkeypatch.setattr(seeding, "ALL_ROWS", all_rows)
    monkeypatch.setattr(seeding, "_rows_within_reach",
                        lambda *a: shares.append((r := within(*a)).size / a[1].size) or r)
    X = blobs(60, 30, 8, 6)
    theirs, _ = kmeans_plusplus(X, 80, random_state=np.random.RandomState(6))
    assert np.array_equal(PrunedPlusPlus()(X, 80, np.random.RandomState(6)), theirs)
    assert max(shares) > 0.5 > min(shares)  # both kinds of pick on this data


def test_the_same_centres_with_weights():
    X = blobs(40, 10, 5, 3)
    w = np.random.default_rng(4).integers(1, 20, X.shape[0]).astype(float)
    theirs, _ = kmeans_plusplus(X, 50, sample_weight=w, random_state=np.random.RandomState(5))
    ours = PrunedPlusPlus(w)(X, 50, np.random.RandomState(5))
    assert np.array_equal(ours, theirs)


def test_many_clusters_give_scikit_learns_labels():
    """From MIN_CLUSTERS clusters on phase 1 seeds with the pruned k-means++ and iterates with
    Elkan's algorithm: the labels of the plain KMeans, numbered by first appearance."""
    ns = MIN_CLUSTERS + 20
    X = blobs(ns, 12, 6, 7, spread=0.01)
    ours, details = cluster_observations(X, FixedClusters(ns), Euclidean(), n_init=2,
                                         random_state=0)
    plain = KMeans(n_clusters=ns, n_init=2, random_state=0).fit_predict(X)
    assert details["method"] == "full"
    _, first, inverse = np.unique(plain, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # cluster -> rank of its first appearance
    assert np.array_equal(ours, rank[inverse])


def pairs(n_pairs, dim, seed):
    """``n_pairs`` pairs of rows, each pair 0.01 apart and far from the others: once a centre
    is near every pair, the two rows of a pair drawn as candidates lower the sum of squared
    distances by the same amount, an exact tie that only the rounding of the distances breaks."""
    rng = np.random.default_rng(seed)
    centres = rng.random((n_pairs, dim)) * 10
    offset = rng.normal(0, 1, (n_pairs, dim))
    offset *= 0.005 / np.linalg.norm(offset, axis=1, keepdims=True)
    X = np.concatenate([centres + offset, centres - offset])
    return X[rng.permutation(X.shape[0])]


@pytest.mark.parametrize("seed", [0, 1])
def test_ties_are_broken_as_scikit_learn_breaks_them(seed):
    """Few rows are within reach of the candidates, but their distances are computed over at
    least PRODUCT_ROWS rows: with fewer, OpenBLAS's small-matrix kernels round them otherwise and
    ties fall the other way here."""
    X = pairs(300, 64, seed)
    X -= X.mean(axis=0)
    theirs, _ = kmeans_plusplus(X, 450, random_state=np.random.RandomState(seed))
    ours = PrunedPlusPlus()(X, 450, np.random.RandomState(seed))
    assert np.array_equal(ours, theirs)


def test_from_pruned_clusters_on_the_pruned_seeding_gives_scikit_learns_labels(monkeypatch):
    """Between PRUNED_CLUSTERS and MIN_CLUSTERS clusters phase 1 seeds with the pruned k-means++
    (and iterates by Lloyd's algorithm): the labels of the plain KMeans, numbered by first
    appearance -- and the pruned seeding is the one that ran."""
    import topomap.core.phase1.clustering as clustering

    ns = (PRUNED_CLUSTERS + MIN_CLUSTERS) // 2
    X = blobs(ns, 12, 6, 11, spread=0.01)
    calls = []
    real = clustering.PrunedPlusPlus

    class Counted(real):
        def __call__(self, *args, **kwargs):
            calls.append(args[1])
            return super().__call__(*args, **kwargs)

    monkeypatch.setattr(clustering, "PrunedPlusPlus", Counted)
    ours, details = cluster_observations(X, FixedClusters(ns), Euclidean(), n_init=2,
                                         random_state=0)
    plain = KMeans(n_clusters=ns, n_init=2, random_state=0).fit_predict(X)
    assert details["method"] == "full" and calls == [ns, ns]  # one seeding per start
    _, first, inverse = np.unique(plain, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))
    assert np.array_equal(ours, rank[inverse])


def test_below_pruned_clusters_scikit_learns_own_seeding_runs(monkeypatch):
    import topomap.core.phase1.clustering as clustering

    assert PRUNED_CLUSTERS > 10
    monkeypatch.setattr(clustering, "PrunedPlusPlus", None)  # calling it would fail
    X = blobs(10, 20, 3, 12, spread=0.01)  # ten tight blobs: ten clusters, one each
    labels, _ = cluster_observations(X, FixedClusters(10), Euclidean(), n_init=2,
                                     random_state=0)
    assert np.unique(labels).size == 10


def test_one_blas_thread_limits_every_blas_and_restores_it():
    from threadpoolctl import threadpool_info

    from topomap.core.phase1.clustering import one_blas_thread

    before = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
    with one_blas_thread():
        inside = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
    after = [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]
    assert inside and all(n == 1 for n in inside)
    assert after == before


def test_phase_1_fits_on_one_blas_and_one_openmp_thread(monkeypatch):
    from threadpoolctl import threadpool_info

    from topomap.core.phase1 import clustering

    seen = []

    def fitter(Z, ns, **kw):
        seen.append({lib["user_api"]: lib["num_threads"] for lib in threadpool_info()})
        return np.zeros(Z.shape[0], dtype=np.int64), None
    monkeypatch.setitem(clustering._FITTERS, "full", fitter)
    before = {lib["user_api"]: lib["num_threads"] for lib in threadpool_info()}
    clustering._run("full", np.zeros((4, 2)), 1)
    assert "openmp" in seen[0] and set(seen[0].values()) == {1}  # scikit-learn's OpenMP too
    assert {lib["user_api"]: lib["num_threads"] for lib in threadpool_info()} == before
