"""Phase 1 at data speed: the exact full K-means where it is cheap, fast methods that agree with it."""

import numpy as np
import pytest
from sklearn.cluster import KMeans
from sklearn.metrics import adjusted_rand_score

from topomap import MapLearner
from topomap.core.phase1.clustering import (Euclidean, FixedClusters, choose_method,
                                            cluster_observations)
from topomap.core.phase1.distinct import distinct_rows
from topomap.worlds import GaussianNoise, OfficeWorld, RandomExplorer


@pytest.fixture(scope="module")
def office():
    """The paper's observations (non-GDS steps of a 2,000-step walk, sensor noise 0.01)."""
    traj = OfficeWorld().simulate(2000, RandomExplorer(), np.random.default_rng(0))
    X = GaussianNoise(0.01).apply(traj.observations, np.random.default_rng(1))
    return X[traj.gds < 0]


def symbols(X, ns, **kw):
    return cluster_observations(X, FixedClusters(ns), Euclidean(), n_init=3, **kw)


def test_auto_is_the_exact_full_fit_on_the_papers_run(office):
    ours, details = symbols(office, 20)
    assert details["method"] == "full"
    plain = KMeans(n_clusters=20, n_init=3, random_state=0).fit_predict(office)
    assert adjusted_rand_score(ours, plain) == 1.0
    _, first = np.unique(ours, return_index=True)
    assert np.all(np.diff(first) > 0)  # symbols numbered by first appearance


@pytest.mark.parametrize("method", ["sample", "minibatch", "distinct"])
def test_fast_methods_agree_with_the_full_fit_on_the_office_world(office, method):
    """K-means has local optima (the full fit itself gives ARI 0.966 between seeds 0 and 1 here):
    a fast method must find one of the full fit's solutions."""
    fulls = [symbols(office, 20, method="full", random_state=seed)[0] for seed in range(3)]
    fast, details = symbols(office, 20, method=method, sample_size=500)
    assert details["method"] == method
    assert max(adjusted_rand_score(full, fast) for full in fulls) > 0.985


def test_distinct_is_exact_when_every_distinct_row_is_a_cluster():
    rng = np.random.default_rng(1)
    views = rng.integers(0, 2, (40, 30)).astype(float)
    X = views[rng.integers(0, 40, 20000)]
    n = distinct_rows(X)[0].size
    full, _ = symbols(X, n, method="full")
    fast, details = symbols(X, n)
    assert details["method"] == "distinct" and np.array_equal(full, fast)


def test_distinct_rows_are_numbered_by_first_appearance():
    rng = np.random.default_rng(0)
    Z = rng.integers(0, 3, (5000, 4)).astype(float)
    Z[rng.random(5000) < 0.1, 1] = -0.0  # -0.0 and 0.0 are the same row
    first, inverse, counts = distinct_rows(Z)
    uniq, inv_np = np.unique(Z, axis=0, return_inverse=True)
    assert first.size == uniq.shape[0] and counts.sum() == Z.shape[0]
    assert np.array_equal(Z[first][inverse], Z) and np.all(np.diff(first) > 0)
    assert adjusted_rand_score(inverse, inv_np.ravel()) == 1.0


def test_choose_method():
    assert choose_method(2000, False, 20, 15) == "full"
    assert choose_method(10**6, True, 450, 147) == "distinct"
    assert choose_method(10**6, False, 100, 15) == "sample"


def test_too_many_clusters_and_unknown_methods_are_errors():
    X = np.repeat(np.eye(3), 10, axis=0)
    with pytest.raises(ValueError, match="more than the 3 distinct observations"):
        symbols(X, 4)
    with pytest.raises(ValueError, match="^method='fast' is unknown"):
        symbols(X, 2, method="fast")


def test_the_learner_reports_the_method_that_ran(office):
    u = np.zeros(len(office), dtype=int)
    learner = MapLearner(n_clusters=20, n_states=20, phase1="sample", sample_size=600)
    assert learner.fit(office, u).phase1_method_ == "sample"
