"""Every row's nearest K-means centre by pruned search: the labels of ``KMeans.predict``."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.cluster import KMeans

from topomap.core.phase1 import assign
from topomap.core.phase1.assign import margin


def nearest_centres(km, X, probe_rows=64):
    """The search on every size of input (the module searches from ``SEARCH_ROWS`` rows on)."""
    return assign.nearest_centres(km, X, search_rows=0, probe_rows=probe_rows)
from topomap.core.phase1.clustering import cluster_observations, predict_rows


def _kmeans_with(centres):
    """A fitted KMeans whose centres are exactly ``centres``."""
    centres = np.asarray(centres, dtype=np.float64)
    km = KMeans(n_clusters=len(centres), n_init=1, random_state=0).fit(centres)
    km.cluster_centers_ = centres.copy()
    return km


def test_hand_case_one_feature():
    # centres 0 and 10 on a line: 1 and 4.9 are nearer 0, 9 and 5.1 nearer 10
    km = _kmeans_with([[0.0], [10.0]])
    X = np.array([[1.0], [9.0], [4.9], [5.1], [-3.0], [30.0]])
    assert nearest_centres(km, X).tolist() == [0, 1, 0, 1, 0, 1]


def test_exact_tie_takes_the_first_centre_as_predict_does():
    # (1, 0) lies as far from (0, 0) as from (2, 0); (1, 7) as far from (2, 5) as from (0, 5)
    km = _kmeans_with([[0.0, 0.0], [2.0, 0.0], [2.0, 5.0], [0.0, 5.0]])
    X = np.array([[1.0, 0.0], [1.0, -3.0], [1.0, 7.0], [0.2, 4.9]])
    labels = nearest_centres(km, X)
    assert labels.tolist() == [0, 0, 2, 3]
    assert labels.tolist() == km.predict(X).tolist()


def test_one_centre_labels_every_row_zero():
    km = _kmeans_with([[1.0, 2.0, 3.0]])
    X = np.random.default_rng(0).normal(size=(50, 3))
    assert nearest_centres(km, X).tolist() == [0] * 50


def test_rows_around_one_point_go_to_predict(monkeypatch):
    # 30 centres of rows scattered around one point in 40 features: a row visits most
    # centres, so after the probe the rest are labelled by ``predict`` -- the same labels
    rng = np.random.default_rng(5)
    X = rng.normal(0, 1, size=(4000, 40))
    km = KMeans(n_clusters=30, n_init=1, random_state=0).fit(X[:1000])
    calls = []
    monkeypatch.setattr(assign, "predict_chunked",
                        lambda km, Z: calls.append(len(Z)) or km.predict(Z).astype(np.int64))
    assert np.array_equal(nearest_centres(km, X, probe_rows=500), km.predict(X))
    assert calls == [3500]


def test_separate_clusters_are_searched(monkeypatch):
    # 50 centres far apart: a row visits almost none besides its own, no ``predict`` call
    rng = np.random.default_rng(6)
    centres = rng.uniform(0, 10, size=(50, 8))
    X = centres[rng.integers(0, 50, 5000)] + rng.normal(0, 0.01, size=(5000, 8))
    km = _kmeans_with(centres)
    monkeypatch.setattr(assign, "predict_chunked", lambda km, Z: 1 / 0)
    assert np.array_equal(nearest_centres(km, X, probe_rows=500), km.predict(X))


def test_more_centres_than_searched_go_to_predict(monkeypatch):
    rng = np.random.default_rng(7)
    X = rng.uniform(0, 1, size=(2000, 3))
    km = KMeans(n_clusters=12, n_init=1, random_state=0).fit(X)
    monkeypatch.setattr(assign, "SEARCH_CENTRES", 11)
    monkeypatch.setattr(assign, "_search", lambda *a: 1 / 0)
    assert np.array_equal(nearest_centres(km, X), km.predict(X))


def test_margin_grows_with_features_and_precision():
    assert margin(np.float32, 15) > margin(np.float64, 15) > 0
    assert margin(np.float64, 30) == pytest.approx(margin(np.float64, 15) * 31 / 16)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), D=st.integers(1, 20), k=st.integers(1, 40),
       spread=st.sampled_from([0.0, 0.01, 0.3, 3.0]), f32=st.booleans(),
       snap=st.booleans())
def test_same_labels_as_predict(seed, D, k, spread, f32, snap):
    # clusters well apart, touching or on top of one another; with ``snap`` every value rounded
    # to a coarse grid, so that rows sit at exactly equal distances from two centres
    rng = np.random.default_rng(seed)
    centres = rng.uniform(0, 1, size=(k, D))
    X = centres[rng.integers(0, k, 3000)] + rng.normal(0, spread + 1e-3, size=(3000, D))
    if snap:
        X = np.round(X * 4) / 4
    X = X.astype(np.float32 if f32 else np.float64)
    n = min(k, len(np.unique(X, axis=0)))
    km = KMeans(n_clusters=n, n_init=1, random_state=0).fit(X[:500])
    assert np.array_equal(nearest_centres(km, X), km.predict(X))


def test_sample_method_gives_predicts_labels():
    rng = np.random.default_rng(3)
    centres = rng.uniform(0, 1, size=(60, 6))
    X = centres[rng.integers(0, 60, 50_000)] + rng.normal(0, 0.05, size=(50_000, 6))
    km = KMeans(n_clusters=60, n_init=1, random_state=0).fit(X[:5000])
    assert np.array_equal(predict_rows(km, X), km.predict(X))
    labels, details = cluster_observations(X, _Fixed(60), _Same(), method="sample",
                                           sample_size=5000)
    assert details["method"] == "sample" and labels.shape == (50_000,)


def test_predict_rows_names_non_finite_rows():
    km = _kmeans_with([[0.0], [1.0]])
    with pytest.raises(ValueError, match="X"):
        predict_rows(km, np.array([[0.5], [np.nan]]))


class _Fixed:
    def __init__(self, ns):
        self.ns = ns

    def choose(self, Z, random_state):
        return self.ns


class _Same:
    def fit_transform(self, X):
        return X
