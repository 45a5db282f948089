"""The split's start: the observation models estimated beside the split's tables, the map's
counts read from those tables, the feature variance computed beside K-means -- each the same
numbers as the steps in turn give, on hand cases and random walks, on one to three threads."""

import numpy as np
import pytest

from topomap.core.data.trajectory import check_fit_data
from topomap.core.map.model import TopologicalMap
from topomap.core.map.observations import feature_variance, observation_models
from topomap.core.phase1.clustering import FixedClusters, cluster_observations
from topomap.core.phase1.start import phase1_labels, start_split, variance_beside
from topomap.core.split import threads
from topomap.core.split.criteria import EntropyCriterion
from topomap.core.split.engine import Splitter
from topomap.core.stats import count_tables, episode_masks


@pytest.fixture(params=[1, 2, 3])
def n_threads(request, monkeypatch):
    monkeypatch.setattr(threads, "n_threads", lambda: request.param)
    return request.param


def bits(a):
    return np.ascontiguousarray(a).view(np.int64)


def test_beside_returns_the_result_or_raises_its_error(n_threads):
    get = threads.beside(divmod, 17, 5)
    assert get() == (3, 2) and get() == (3, 2)
    get = threads.beside(divmod, 1, 0)
    with pytest.raises(ZeroDivisionError):
        get()


def test_beside_runs_on_another_thread_only_with_threads(n_threads):
    import threading

    caller = threading.get_ident()
    ran_on = threads.beside(threading.get_ident)()
    assert (ran_on == caller) == (n_threads == 1)


def test_beside_keeps_small_work_on_the_calling_thread(n_threads, monkeypatch):
    import threading

    monkeypatch.setattr(threads, "THREAD_STEPS", 100)
    caller = threading.get_ident()
    assert threads.beside(threading.get_ident, steps=99)() == caller
    assert (threads.beside(threading.get_ident, steps=100)() == caller) == (n_threads == 1)


def test_models_with_the_variance_given_by_hand():
    # model 0 holds rows 0, 1, 3, model 1 row 2; feature variances 14 and 0
    X = np.array([[0.0, 1.0], [2.0, 1.0], [10.0, 1.0], [4.0, 1.0]])
    model, lookup = np.array([0, 1, 2, 0]), np.array([0, 0, 1])
    assert feature_variance(X).tolist() == [14.0, 0.0]
    means, cov, n = observation_models(X, model, 2, reg_covar=1e-3, lookup=lookup,
                                       variance=np.array([14.0, 0.0]))
    assert n.tolist() == [3.0, 1.0] and means.tolist() == [[2.0, 1.0], [10.0, 1.0]]
    assert np.allclose(cov, [[8 / 3 + 0.007, 0.007], [0.007, 0.007]], rtol=0, atol=1e-15)
    # the variance given sets the regularisation, whatever the rows hold
    cov2 = observation_models(X, model, 2, reg_covar=1e-3, lookup=lookup,
                              variance=np.array([2.0, 0.0]))[1]
    assert np.allclose(cov2 - cov, -0.006, rtol=0, atol=1e-15)


@pytest.mark.parametrize("shape, covariance_type", [((700, 5), "diag"), ((300, 1), "diag"),
                                                    ((400, 3), "full")])
def test_models_with_the_variance_given_are_the_same_floats(shape, covariance_type):
    rng = np.random.default_rng(shape[0])
    X = rng.normal(size=shape) * 3 + 1
    model, lookup = rng.integers(0, 7, shape[0]), rng.integers(0, 4, 7)
    alone = observation_models(X, model, 4, covariance_type, 1e-3, lookup)
    given = observation_models(X, model, 4, covariance_type, 1e-3, lookup,
                               variance=feature_variance(X))
    for a, b in zip(alone, given):
        assert np.array_equal(bits(a), bits(b))


def test_phase1_labels_put_gds_states_after_the_symbols():
    symbols = np.array([1, 0, 1])  # the three steps without a GDS
    gds = np.array([-1, 7, -1, 3, 7, -1])
    labels, ids = phase1_labels(symbols, 2, gds)
    assert ids.tolist() == [3, 7]
    assert labels.tolist() == [1, 3, 0, 2, 3, 1] and labels.dtype == np.int64
    plain, ids = phase1_labels(symbols, 2, np.full(3, -1))
    assert plain.tolist() == [1, 0, 1] and ids.size == 0


def _walk(seed, T=3000, S=6, A=3, episodes=4):
    rng = np.random.default_rng(seed)
    centres = rng.normal(size=(S, 4)) * 2
    x = rng.integers(0, S, T)
    X = centres[x] + rng.normal(0, 0.1, size=(T, 4))
    gds = np.where(rng.random(T) < 0.05, rng.integers(0, 3, T), -1)
    lengths = np.diff(np.r_[0, np.sort(rng.choice(np.arange(1, T), episodes - 1,
                                                   replace=False)), T])
    return check_fit_data(X, rng.integers(0, A, T), gds, lengths, A, None, None), x, S


@pytest.mark.parametrize("seed", range(3))
def test_start_split_gives_the_models_and_tables_of_the_steps_in_turn(seed, n_threads,
                                                                     monkeypatch):
    monkeypatch.setattr(threads, "THREAD_STEPS", 0)  # on a thread, however few the steps
    data, x, S = _walk(seed)
    labels, ids = phase1_labels(x[data.gds < 0], S, data.gds)
    variance = variance_beside(data.X)
    splitter, models = start_split(data, labels, S, ids, variance, criterion=EntropyCriterion(),
                                   recompute_all=False, covariance_type="diag", reg_covar=1e-3)
    assert np.array_equal(bits(variance()), bits(feature_variance(data.X)))
    symbol, gds = list(range(S)) + [-1] * ids.size, [-1] * S + ids.tolist()
    alone = TopologicalMap.from_labels(data.X, data.u, labels, lengths=data.lengths,
                                       state_symbol=symbol, state_gds=gds,
                                       state_parent=[-1] * len(symbol), n_actions=data.n_actions)
    assert np.array_equal(bits(models[0]), bits(alone.means))
    assert np.array_equal(bits(models[1]), bits(alone.covariances))
    fresh = Splitter(labels, data.u, data.n_actions, *data.masks, symbol=symbol, gds=gds,
                     obs_entropy=np.zeros(0), criterion=EntropyCriterion())
    assert np.array_equal(splitter.labels, fresh.labels)
    assert [a.tolist() for t in splitter.engine.tables for a in t] == [
        a.tolist() for t in fresh.engine.tables for a in t]
    kept = splitter.count_tables()
    for a, b in zip(kept, (alone.state_counts, alone.action_counts, alone.transition_counts)):
        assert np.array_equal(a, b)


def test_the_engines_count_tables_by_hand():
    # one episode 0..3, one of 4..5; transitions inside episodes only
    x, u = np.array([0, 1, 1, 0, 1, 0]), np.array([1, 0, 1, 0, 1, 1])
    has_prev, has_next = episode_masks(6, [4, 2])
    splitter = Splitter(x, u, 2, has_prev, has_next, symbol=[0, 1], gds=[-1, -1],
                        obs_entropy=np.zeros(2), criterion=EntropyCriterion())
    state, action, trans = splitter.count_tables()
    assert state.tolist() == [3, 3] and action.tolist() == [[1, 2], [1, 2]]
    expected = np.zeros((2, 2, 2), dtype=np.int64)
    expected[0, 1, 1] = expected[1, 0, 1] = expected[1, 1, 0] = expected[1, 1, 0] = 1
    expected[1, 1, 0] = 2  # steps 2 -> 3 and 4 -> 5
    assert np.array_equal(trans, expected)
    assert all(np.array_equal(a, b) for a, b in zip((state, action, trans),
                                                    count_tables(x, u, 2, 2, has_next)))
    state[0] = 99  # new arrays: the engine's counts stay as they are
    assert splitter.count_tables()[0].tolist() == [3, 3]


class _Scaled:
    """A metric that doubles the rows and turns the value at row 90 into NaN."""

    name = "scaled"

    def fit_transform(self, X):
        Z = 2 * X
        Z[90, 0] = np.nan
        return Z


def test_checked_rows_skip_the_second_check_only_when_the_metric_keeps_them():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(2000, 3)) + np.repeat(np.eye(3) * 5, [700, 700, 600], axis=0)
    kw = dict(method="sample", sample_size=50, random_state=0, n_init=1)
    from topomap.core.phase1.clustering import Euclidean

    plain = cluster_observations(X, FixedClusters(3), Euclidean(), **kw)[0]
    checked = cluster_observations(X, FixedClusters(3), Euclidean(), checked=True, **kw)[0]
    assert np.array_equal(plain, checked)
    # the sample (50 of 2000 rows, seed 0) does not hold row 90: the NaN reaches the assignment
    rows = np.sort(np.random.default_rng(0).choice(2000, size=50, replace=False))
    assert 90 not in rows
    with pytest.raises(ValueError, match="NaN"):
        cluster_observations(X, FixedClusters(3), _Scaled(), checked=True, **kw)
