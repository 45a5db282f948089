"""Inference at scale: the chunked, pruned, compiled score / predict / filter agree with the dense
numpy reference (tests/reference_inference.py) and with brute-force enumeration, and their memory
does not grow with T."""

import itertools
import json
import tracemalloc

import numpy as np
import pytest
import reference_inference as ref

from topomap import MapLearner, TopologicalMap
from topomap.core.map import observations as stats
from topomap.core.map.observations import feature_variance
from topomap.core.data.trajectory import check_sequences


def random_map(rng, S=7, A=3, D=4, n_gds=1, cov="diag"):
    """A map with aliased states (two share a symbol), a GDS state and an unseen (state, action)."""
    counts = rng.integers(0, 6, (S, A, S)) * (rng.random((S, A, S)) < 0.5)
    counts[0, 1] = 0
    symbol = np.r_[np.arange(S - n_gds - 1), 0, -np.ones(n_gds, int)]
    gds = np.r_[-np.ones(S - n_gds, int), np.arange(n_gds)]
    means = rng.standard_normal((S, D))
    means[S - n_gds - 1] = means[0]  # the split state shares its symbol's model
    var = rng.uniform(0.3, 2, (S, D))
    var[S - n_gds - 1] = var[0]
    cov_arg = var if cov == "diag" else np.stack([np.diag(v) + 0.1 for v in var])
    return TopologicalMap(symbol, gds, -np.ones(S, int), means, cov_arg, rng.integers(1, 9, S),
                          rng.integers(1, 5, (S, A)), counts)


def random_sequence(rng, m, T):
    X = m.means[rng.integers(0, m.n_states, T)] + 0.5 * rng.standard_normal((T, m.n_features))
    u = rng.integers(0, m.n_actions, T)
    g = np.where(rng.random(T) < 0.1, 0, -1)
    return X, u, g


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("cov", ["diag", "full"])
@pytest.mark.parametrize("with_gds", [False, True])
def test_score_predict_filter_agree_with_the_dense_reference(seed, cov, with_gds):
    rng = np.random.default_rng(seed)
    m = random_map(rng, cov=cov)
    X, u, g = random_sequence(rng, m, 300)
    g = g if with_gds else None
    L = [120, 1, 179]
    for prune in (True, False):
        assert m.score(X, u, g, L, prune=prune) == pytest.approx(ref.score(m, X, u, g, L),
                                                                 rel=1e-10)
        assert np.array_equal(m.predict(X, u, g, L, prune=prune), ref.predict(m, X, u, g, L))
        assert np.allclose(m.filter(X, u, g, L, prune=prune), ref.filter_beliefs(m, X, u, g, L),
                           rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_score_and_predict_agree_with_brute_force_enumeration(seed):
    rng = np.random.default_rng(seed)
    m = random_map(rng, S=4, A=2, D=2, n_gds=0)
    X, u, _ = random_sequence(rng, m, 6)
    eps = 0.01
    emit, log_act, trans, init = ref.tables(m, X, u, None, eps)
    emit = emit + log_act[:, u].T
    scores = {}
    for path in itertools.product(range(m.n_states), repeat=len(u)):
        s = init[path[0]] + emit[0, path[0]]
        for t in range(1, len(u)):
            s += trans[path[t - 1], u[t - 1], path[t]] + emit[t, path[t]]
        scores[path] = s
    assert m.score(X, u, smoothing=eps) * len(u) == pytest.approx(
        np.logaddexp.reduce(list(scores.values())), rel=1e-12)
    assert tuple(m.predict(X, u, smoothing=eps)) == max(scores, key=scores.get)


def test_scoring_memory_does_not_grow_with_T(monkeypatch):
    """With ~1 MB chunks, 4x and 16x a walk differ in peak memory only by the per-step arrays
    (actions, GDS, episode marks, the path): a few dozen bytes per step."""
    monkeypatch.setattr(stats, "CHUNK_BYTES", 2**20)
    rng = np.random.default_rng(0)
    m = random_map(rng, S=40, A=3, D=15)
    X, u, _ = random_sequence(rng, m, 5000)
    peaks = []
    for reps in (4, 16):
        Xr, ur = np.tile(X, (reps, 1)), np.tile(u, reps)
        tracemalloc.start()
        m.score(Xr, ur)
        m.predict(Xr, ur)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    per_step = (peaks[1] - peaks[0]) / ((16 - 4) * len(u))
    assert per_step < 40, peaks


def test_check_sequences_does_not_copy_float64_observations():
    X = np.random.default_rng(0).standard_normal((50, 3))
    u = np.arange(50) % 3
    assert check_sequences(X, u)[0] is X
    assert check_sequences(np.asfortranarray(X), u)[0].flags.f_contiguous
    bad = X.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ValueError, match=r"1 row\(s\), first at step 7"):
        check_sequences(bad, u)


@pytest.mark.parametrize("shape", [(3000, 1), (3000, 2), (20000, 15), (5000, 147)])
def test_feature_variance_is_numpys_var(shape):
    X = np.random.default_rng(0).standard_normal(shape) * 7 + 100
    assert np.array_equal(feature_variance(X).view(np.int64), X.var(axis=0).view(np.int64))


@pytest.mark.parametrize("cov", ["diag", "full"])
def test_observation_models_are_the_plain_numpy_ones_bit_for_bit(cov):
    rng = np.random.default_rng(2)
    X = rng.standard_normal((3000, 5)) * 3 + 1
    model = rng.integers(0, 7, 3000)
    means, covs, _ = stats.observation_models(X, model, 7, cov, 1e-3)
    sums = np.zeros((7, 5))
    np.add.at(sums, model, X)
    n = np.bincount(model, minlength=7).astype(float)
    mean_ref = sums / n[:, None]
    reg = 1e-3 * float(np.mean(X.var(axis=0)))
    resid = X - mean_ref[model]
    if cov == "diag":
        sq = np.zeros((7, 5))
        np.add.at(sq, model, resid**2)
        cov_ref = sq / n[:, None] + reg
    else:
        rows = [resid[model == k] for k in range(7)]  # r.T @ r of one buffer, as the plain code
        cov_ref = np.stack([r.T @ r / n[k] + reg * np.eye(5) for k, r in enumerate(rows)])
    assert np.array_equal(means.view(np.int64), mean_ref.view(np.int64))
    assert np.array_equal(covs.view(np.int64), cov_ref.view(np.int64))


def test_a_saved_map_scores_and_decodes_as_the_original():
    rng = np.random.default_rng(5)
    X = np.eye(4)[rng.integers(0, 4, 800)] + 0.01 * rng.standard_normal((800, 4))
    u = rng.integers(0, 2, 800)
    m = MapLearner(n_clusters=4, n_states=6).fit(X, u).map_
    twin = TopologicalMap.from_dict(json.loads(json.dumps(m.to_dict())))
    assert twin.score(X, u) == m.score(X, u)
    assert np.array_equal(twin.predict(X, u), m.predict(X, u))
