"""Observations in float32: ``fit`` keeps them as they are (half the memory of float64), and a
contiguous float64 array is never copied."""

import tracemalloc

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core import check_sequences
from topomap.core.data.trajectory import check_fit_data
from topomap.metrics import adjusted_rand

#: the view seen at each of six places: four views, places 4 and 5 alias views 0 and 1
VIEW_OF_PLACE = np.array([0, 1, 2, 3, 0, 1])
#: place after place p under action a: p + 1, p + 2 and p + 5 around a ring of six
MOVES = np.array([1, 2, 5])


def ring_walk(T=3000, seed=0):
    """A walk over the six places: views 5 units apart along the axes, noise 0.1 (a view's
    nearest centre is always its own), so K-means' four clusters are the four views."""
    rng = np.random.default_rng(seed)
    u = rng.integers(0, 3, T)
    places = np.empty(T, dtype=np.int64)
    p = 0
    for t in range(T):
        places[t] = p
        p = (p + MOVES[u[t]]) % 6
    X = 5.0 * np.eye(4)[VIEW_OF_PLACE[places]] + rng.normal(0, 0.1, (T, 4))
    return X, u, places


def fit_data(X, u):
    return check_fit_data(X, u, None, None, None, None, None)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_fit_uses_contiguous_float64_and_float32_observations_without_a_copy(dtype):
    X, u, _ = ring_walk(50)
    X = X.astype(dtype)
    got = fit_data(X, u).X
    assert got is X and np.shares_memory(got, X)
    F = np.asfortranarray(X)
    assert fit_data(F, u).X is F  # Fortran order is used as it is too


def test_other_inputs_become_float64():
    X, u, _ = ring_walk(50)
    for other in (X.astype(np.float16), np.round(X).astype(np.int32), X.astype(np.float32)[::2]):
        got = fit_data(other, u[:other.shape[0]]).X
        assert got.dtype == np.float64 and not np.shares_memory(got, other)
    # outside fit (scoring, partial_fit, trajectories) float32 is widened as before
    X32 = X.astype(np.float32)
    assert check_sequences(X32, u)[0].dtype == np.float64


@pytest.mark.parametrize("refine", [None, "em"])
def test_float32_observations_give_the_float64_labels_on_separated_views(refine):
    X, u, places = ring_walk()
    a = MapLearner(n_clusters=4, n_states=6, refine=refine).fit(X, u)
    b = MapLearner(n_clusters=4, n_states=6, refine=refine).fit(X.astype(np.float32), u)
    assert adjusted_rand(VIEW_OF_PLACE[places], b.labels_phase1_) == 1.0
    assert np.array_equal(a.labels_phase1_, b.labels_phase1_)
    assert np.array_equal(a.labels_, b.labels_)
    # the models are those of the float32-rounded values: within float32's rounding of 5.0
    assert b.map_.means.dtype == np.float64
    assert np.abs(a.map_.means - b.map_.means).max() < 5 * np.finfo(np.float32).eps
    assert np.array_equal(a.map_.transition_counts, b.map_.transition_counts)
    f = MapLearner(n_clusters=4, n_states=6, refine=refine).fit(
        np.asfortranarray(X, dtype=np.float32), u)  # Fortran order: summed the other way
    assert np.array_equal(f.labels_, b.labels_)
    assert np.allclose(f.map_.covariances, b.map_.covariances, rtol=1e-12, atol=0)


def test_float32_fit_makes_no_float64_copy_of_the_observations():
    """The fit's traced allocations stay below one float64 copy of the observations: at
    200,000 x 15 that is 24 MB, where the fit's own arrays (labels, K-means on a sample,
    the split's tables) take a few MB."""
    rng = np.random.default_rng(0)
    T, D = 200_000, 15
    centres = rng.uniform(0, 1, (20, D))
    X = (centres[rng.integers(0, 20, T)] + rng.normal(0, 0.02, (T, D))).astype(np.float32)
    u = rng.integers(0, 4, T)
    MapLearner(n_clusters=20, n_states=25).fit(X[:2000], u[:2000])  # compile, fill caches
    tracemalloc.start()
    try:
        MapLearner(n_clusters=20, n_states=25).fit(X, u)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < T * D * 8


def test_float32_observations_too_large_to_square_in_float32_are_refused():
    """K-means sums squares in float32 (max 3.4e38): for 300 x 3 values every |x| must stay
    below sqrt(3.4e38 / 900) / 2 = 3.1e17; the same value in float64 is far below its bound."""
    X, u, _ = ring_walk(300)
    X = X[:, :3].copy()
    X[5, 1] = 1e18
    with pytest.raises(ValueError, match=r"^observations hold 1e\+18 \(step 5, column 1\), too "
                       r"large: .* would overflow float32 \(\|x\| must stay below 3.1e\+17\)"):
        MapLearner(n_clusters=3, n_states=4).fit(X.astype(np.float32), u)
    assert fit_data(X, u).X.dtype == np.float64  # accepted as float64


@pytest.mark.parametrize("covariance_type", ["diag", "full"])
def test_models_of_float32_observations_are_summed_in_float64(covariance_type):
    """float32 -> float64 is exact, and the models' sums run in float64 in step order either
    way: the same means and covariances, bit for bit, as from the values widened first."""
    from topomap import TopologicalMap

    X, u, places = ring_walk(500)
    X32 = X.astype(np.float32)
    labels = VIEW_OF_PLACE[places]
    kw = dict(state_symbol=np.arange(4), state_gds=np.full(4, -1), state_parent=np.full(4, -1),
              n_actions=3, covariance_type=covariance_type)
    a = TopologicalMap.from_labels(X32, u, labels, **kw)
    b = TopologicalMap.from_labels(X32.astype(np.float64), u, labels, **kw)
    assert np.array_equal(a.means, b.means) and np.array_equal(a.covariances, b.covariances)
