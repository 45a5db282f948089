"""Phase 1's repair of a view K-means cut in two (topomap.core.phase1.repair)."""

import numpy as np
import pytest
from sklearn.cluster import KMeans

from topomap.metrics import adjusted_rand
from topomap.core.phase1.clustering import (Euclidean, FixedClusters, _kmeans,
                                            cluster_observations, first_appearance_order)
from topomap.core.phase1.repair import cut_pairs, repair_cut_views, rms_spreads

DIM, PER_BLOB, SIGMA = 40, 300, 0.1


def three_blobs(seed=0):
    """Blobs A at 0, B and C 20 along axis 1 and 5 either side along axis 2 (A's rows first).

    Each blob's rms spread is about SIGMA * sqrt(DIM) = 0.63; a cut of A in two halves puts
    their centres about 2 * 0.8 * SIGMA = 0.16 apart along the cut, under half the spread."""
    rng = np.random.default_rng(seed)
    means = np.zeros((3, DIM))
    means[1, 1], means[1, 2] = 20.0, 5.0
    means[2, 1], means[2, 2] = 20.0, -5.0
    X = np.repeat(means, PER_BLOB, axis=0) + rng.normal(0, SIGMA, (3 * PER_BLOB, DIM))
    return X, np.repeat(np.arange(3), PER_BLOB)


def cut_fit(X):
    """K-means from two centres either side of A's mean along axis 0 and one between B and C:
    Lloyd keeps A cut in two and B and C in one cluster (each of B's rows is 5 from their
    shared centre and over 20 from A's)."""
    start = np.zeros((3, DIM))
    start[0, 0], start[1, 0] = 0.05, -0.05
    start[2, 1] = 20.0
    return KMeans(3, init=start, n_init=1).fit(X)


def test_spreads_and_pairs_by_hand():
    # cluster 0: rows at distance 1 and 3 from its centre (rms sqrt(5)); cluster 1: one row on it
    Z = np.array([[1.0, 0.0], [-3.0, 0.0], [10.0, 0.0]])
    centres = np.array([[0.0, 0.0], [10.0, 0.0]])
    spread = rms_spreads(Z, np.array([0, 0, 1]), centres)
    assert spread == pytest.approx([np.sqrt(5.0), 0.0])
    # weights 3 and 1: (3 * 1 + 1 * 9) / 4 = 3
    assert rms_spreads(Z, np.array([0, 0, 1]), centres, [3.0, 1.0, 1.0])[0] == pytest.approx(
        np.sqrt(3.0))
    # three centres: 0 and 1 are 0.4 apart, under half the smaller spread (0.5 x 1.0); 1 and 2
    # are 0.6 apart, over half of 1.0; a spread of 0 never pairs
    centres = np.array([[0.0], [0.4], [1.0]])
    assert cut_pairs(centres, np.array([2.0, 1.0, 1.0])).tolist() == [[0, 1]]
    # spreads 2, 1.4, 2: 0.4 and 0.6 under 0.7, but 0 and 2 are 1.0 apart, not under 0.5 x 2
    assert cut_pairs(centres, np.array([2.0, 1.4, 2.0])).tolist() == [[0, 1], [1, 2]]
    assert cut_pairs(centres, np.array([0.0, 1.4, 2.0])).tolist() == [[1, 2]]


def test_a_cut_blob_is_joined_and_the_shared_cluster_split():
    X, truth = three_blobs()
    km = cut_fit(X)
    assert adjusted_rand(truth, km.labels_) < 0.9  # the cut: A in two, B and C together
    repaired, info = repair_cut_views(km, X)
    assert info["pairs"] == 1 and info["kept"]
    # B and C apart: their 600 rows come 5 nearer their centres, 600 x 25 of the inertia
    assert info["start"] < info["inertia"] - 0.9 * 600 * 25
    assert info["repaired"] <= info["start"]
    assert adjusted_rand(truth, repaired.labels_) == 1.0
    assert repaired.inertia_ == pytest.approx(info["repaired"])


def test_weighted_rows():
    X, truth = three_blobs(1)
    weight = np.r_[np.full(PER_BLOB, 2.0), np.ones(2 * PER_BLOB)]  # A's rows count twice
    km = KMeans(3, init=cut_fit(X).cluster_centers_, n_init=1).fit(X, sample_weight=weight)
    repaired, info = repair_cut_views(km, X, weight)
    assert info["kept"] and adjusted_rand(truth, repaired.labels_) == 1.0


def test_true_blobs_are_left_alone():
    X, _ = three_blobs(2)
    km = KMeans(3, n_init=3, random_state=0).fit(X)
    assert repair_cut_views(km, X) == (km, None)


def test_a_gain_under_the_gate_changes_nothing():
    X, _ = three_blobs(3)
    km = cut_fit(X)
    labels = km.labels_.copy()
    _, info = repair_cut_views(km, X)
    gain = 1.0 - info["start"] / info["inertia"]  # the parted rows' gain, before K-means again
    kept, info = repair_cut_views(km, X, min_gain=gain * 0.999)
    assert info["kept"] and kept is not km and info["repaired"] <= info["start"]
    same, info = repair_cut_views(km, X, min_gain=gain * 1.001)
    assert not info["kept"] and info["repaired"] is None
    assert same is km and np.array_equal(same.labels_, labels)
    # one blob in two clusters: joined and cut again, no gain
    A = X[:PER_BLOB]
    km = KMeans(2, n_init=1, random_state=0).fit(A)
    same, info = repair_cut_views(km, A)
    assert info["pairs"] == 1 and not info["kept"] and same is km


@pytest.mark.parametrize("n_clusters", [99, 100])
def test_phase1_with_more_clusters_than_blobs(n_clusters):
    # 99 tight blobs of 100 rows in 40 dimensions: 100 clusters must cut one blob in two
    # (halves' centres about 1.6 x 0.01 apart, under half their spread of about 0.01 x sqrt(40))
    # and the repair can only cut it again: a gain far under 1 %, so the labels are K-means'
    # own; below 100 clusters the repair never looks
    rng = np.random.default_rng(0)
    X = np.repeat(rng.random((99, 40)) * 10, 100, axis=0) + rng.normal(0, 0.01, (9900, 40))
    symbols, details = cluster_observations(X, FixedClusters(n_clusters), Euclidean(),
                                            n_init=1, method="full")
    plain = _kmeans(n_clusters, 1, 0).fit(X).labels_
    assert np.array_equal(symbols, first_appearance_order(plain, n_clusters)[0][plain])
    if n_clusters == 99:
        assert "cut_views" not in details
    else:
        assert details["cut_views"]["pairs"] == 1 and not details["cut_views"]["kept"]
        same, details = cluster_observations(X, FixedClusters(n_clusters), Euclidean(),
                                             n_init=1, method="full", repair=False)
        assert np.array_equal(same, symbols) and "cut_views" not in details
