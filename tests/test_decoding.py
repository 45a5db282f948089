"""hmmlearn's inference on a map: ``predict_proba``, ``score_samples`` and ``decode`` agree with
brute-force enumeration of every state path on maps small enough to enumerate, with hmmlearn
itself where a map is a plain HMM, and stay exact and bounded in memory on long sequences."""

import itertools
import re
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import reference_inference as ref
from sklearn.exceptions import NotFittedError
from worlds import ring

from topomap import MapLearner, TopologicalMap
from topomap.core.map import observations as stats
from topomap.core.map.sampling import executable_actions

EPS = 0.01  # smoothing large enough to matter


def small_map(seed, S=3, A=2, gds=False):
    """A random map: states 0 and 1 share a symbol's Gaussian; (state 0, the last action) never seen;
    with ``gds`` the last state is a GDS state."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 5, (S, A, S)) * (rng.random((S, A, S)) < 0.7)
    counts[0, A - 1] = 0
    symbol = np.r_[0, 0, np.arange(1, S - 1)]
    state_gds = -np.ones(S, int)
    if gds:
        symbol[-1], state_gds[-1] = -1, 0
    means = np.r_[[[0.0, 0.0]] * 2, rng.normal(0, 1.5, (S - 2, 2))]
    var = np.r_[[[1.0, 0.5]] * 2, rng.uniform(0.3, 1.5, (S - 2, 2))]
    return TopologicalMap(symbol, state_gds, [-1] * S, means, var, rng.integers(1, 9, S),
                          rng.integers(1, 5, (S, A)), counts)


def small_sequence(seed, m, T=6):
    rng = np.random.default_rng(100 + seed)
    X = m.means[rng.integers(0, m.n_states, T)] + 0.7 * rng.standard_normal((T, m.n_features))
    return X, rng.integers(0, m.n_actions, T), np.where(rng.random(T) < 0.3, 0, -1)


def brute_force(m, X, u, g=None, lengths=None):
    """Sum and maximum over every state path of every episode, with the smoothed tables:
    ``(log-likelihood, posteriors, best path, its joint log-probability)``."""
    emit, log_act, trans, init = ref.tables(m, X, u, g, EPS)
    emit = emit + log_act[:, u].T
    T, S = emit.shape
    loglik, best, post, path, start = 0.0, 0.0, np.zeros((T, S)), [], 0
    for n in [T] if lengths is None else lengths:
        steps = np.arange(start, start + n)
        joint = {}
        for xs in itertools.product(range(S), repeat=n):
            joint[xs] = init[xs[0]] + emit[start, xs[0]] + sum(
                trans[xs[k - 1], u[start + k - 1], xs[k]] + emit[start + k, xs[k]]
                for k in range(1, n))
        z = np.logaddexp.reduce(list(joint.values()))
        for xs, logp in joint.items():
            post[steps, list(xs)] += np.exp(logp - z)
        top = max(joint, key=joint.get)
        loglik, best, path, start = loglik + z, best + joint[top], path + list(top), start + n
    return loglik, post, np.array(path), best


CASES = [(seed, gds, lengths) for seed in range(4) for gds in (False, True)
         for lengths in (None, [2, 4], [1, 5])]


@pytest.mark.parametrize("seed, gds, lengths", CASES)
def test_score_samples_and_predict_proba_are_the_brute_force_sums(seed, gds, lengths):
    m = small_map(seed, gds=gds)
    X, u, g = small_sequence(seed, m)
    g = g if gds else None
    loglik, post, _, _ = brute_force(m, X, u, g, lengths)
    for prune in (True, False):
        log_prob, posteriors = m.score_samples(X, u, g, lengths, smoothing=EPS, prune=prune)
        assert log_prob == pytest.approx(loglik, rel=1e-12)
        assert np.allclose(posteriors, post, rtol=1e-10, atol=1e-13)
        assert np.array_equal(m.predict_proba(X, u, g, lengths, smoothing=EPS, prune=prune),
                              posteriors)
    assert np.allclose(posteriors.sum(axis=1), 1.0)
    assert log_prob == pytest.approx(m.score(X, u, g, lengths, smoothing=EPS) * len(u),
                                     rel=1e-12)


@pytest.mark.parametrize("seed, gds, lengths", CASES)
def test_decode_is_the_best_path_or_the_best_state_of_every_step(seed, gds, lengths):
    m = small_map(seed, gds=gds)
    X, u, g = small_sequence(seed, m)
    g = g if gds else None
    loglik, post, path, best = brute_force(m, X, u, g, lengths)
    log_prob, states = m.decode(X, u, g, lengths, smoothing=EPS)
    assert np.array_equal(states, path) and log_prob == pytest.approx(best, rel=1e-12)
    assert np.array_equal(states, m.predict(X, u, g, lengths, smoothing=EPS))
    log_prob, states = m.decode(X, u, g, lengths, algorithm="map", smoothing=EPS)
    assert np.array_equal(states, post.argmax(axis=1))
    assert log_prob == pytest.approx(loglik, rel=1e-12)


def test_the_two_decoders_differ_where_the_best_path_is_not_the_best_states():
    """Somewhere among these small cases the per-step best states are not the best path (the
    decoders are not the same function under two names), and the Viterbi path is never less
    probable jointly than the per-step choice."""
    differ = 0
    for seed in range(12):
        m = small_map(seed)
        X, u, _ = small_sequence(seed, m)
        _, viterbi = m.decode(X, u, smoothing=EPS)
        _, best_states = m.decode(X, u, algorithm="map", smoothing=EPS)
        differ += not np.array_equal(viterbi, best_states)
        emit, log_act, trans, init = ref.tables(m, X, u, None, EPS)

        def joint(xs):
            e = emit[np.arange(len(u)), xs] + log_act[xs, u]
            return init[xs[0]] + e.sum() + trans[xs[:-1], u[:-1], xs[1:]].sum()

        assert joint(viterbi) >= joint(best_states) - 1e-12
    assert differ > 0


def test_a_gds_step_has_all_its_posterior_on_its_gds_state():
    m = small_map(0, gds=True)
    X, u, g = small_sequence(0, m)
    post = m.predict_proba(X, u, g, smoothing=EPS)
    assert np.array_equal(post[g == 0, -1], np.ones((g == 0).sum()))
    assert np.all(post[g < 0, -1] == 0)


def test_decode_refuses_an_unknown_algorithm():
    m = small_map(0)
    X, u, _ = small_sequence(0, m)
    with pytest.raises(ValueError, match="algorithm must be 'viterbi' or 'map', got 'forward'"):
        m.decode(X, u, algorithm="forward")


@pytest.mark.parametrize("lengths", [None, [4, 2]])
def test_a_map_with_one_action_is_hmmlearns_gaussian_hmm(lengths):
    """With one action ``P(u|x) = 1`` and the map is a Gaussian HMM: hmmlearn's own results,
    but for ``decode(algorithm="map")``'s log_prob, which hmmlearn gives as a sum of posteriors
    (not a log-probability) and the map as the log-likelihood."""
    hmm = pytest.importorskip("hmmlearn.hmm")
    m = small_map(3, A=1)
    X, u, _ = small_sequence(3, m)
    S = m.n_states
    model = hmm.GaussianHMM(n_components=S, covariance_type="diag")
    model.n_features = m.n_features
    model.startprob_ = (1 - EPS) * m.state_probs + EPS / S
    model.transmat_ = (1 - EPS) * m.transition_probs[:, 0, :] + EPS / S
    model.means_, model.covars_ = m.means, m.covariances
    log_prob, post = m.score_samples(X, u, lengths=lengths, smoothing=EPS)
    their_log_prob, their_post = model.score_samples(X, lengths)
    assert log_prob == pytest.approx(their_log_prob, rel=1e-10)
    assert np.allclose(post, their_post, atol=1e-10)
    assert np.allclose(m.predict_proba(X, u, lengths=lengths, smoothing=EPS),
                       model.predict_proba(X, lengths), atol=1e-10)
    viterbi, their_viterbi = (m.decode(X, u, lengths=lengths, smoothing=EPS),
                              model.decode(X, lengths, algorithm="viterbi"))
    assert viterbi[0] == pytest.approx(their_viterbi[0], rel=1e-10)
    assert np.array_equal(viterbi[1], their_viterbi[1])
    by_map = m.decode(X, u, lengths=lengths, algorithm="map", smoothing=EPS)
    assert np.array_equal(by_map[1], model.decode(X, lengths, algorithm="map")[1])
    assert by_map[0] == pytest.approx(model.score(X, lengths), rel=1e-10)


def test_many_chunks_give_what_one_chunk_gives(monkeypatch):
    """The backward pass carries its state across chunk boundaries (and episode ends inside
    chunks): tiny chunks change nothing."""
    m = small_map(1, S=4, gds=True)
    X, u, g = small_sequence(1, m, T=500)
    L = [7, 200, 1, 292]
    whole = m.score_samples(X, u, g, L, smoothing=EPS)
    viterbi = m.decode(X, u, g, L, smoothing=EPS)
    monkeypatch.setattr(stats, "CHUNK_BYTES", 8 * 2 * 13)  # 13 rows a chunk
    parts = m.score_samples(X, u, g, L, smoothing=EPS)
    assert parts[0] == pytest.approx(whole[0], rel=1e-12)
    assert np.allclose(parts[1], whole[1], rtol=1e-10, atol=1e-14)
    chunked = m.decode(X, u, g, L, smoothing=EPS)
    assert np.array_equal(chunked[1], viterbi[1]) and chunked[0] == pytest.approx(viterbi[0],
                                                                                   rel=1e-12)


def test_a_million_steps_do_not_underflow():
    """Every step's posterior of a 10^6-step episode is a probability vector; its last steps'
    posteriors, as their own episode, are the brute-force ones."""
    m = small_map(2)
    rng = np.random.default_rng(7)
    T = 10**6
    X, u, _ = m.sample(T, random_state=rng)
    log_prob, post = m.score_samples(X, u, smoothing=EPS)
    assert np.isfinite(log_prob) and log_prob < -T  # far below what a float's exp can hold
    assert np.all(np.isfinite(post)) and np.allclose(post.sum(axis=1), 1.0)
    assert log_prob == pytest.approx(m.score(X, u, smoothing=EPS) * T, rel=1e-9)
    split = m.score_samples(X, u, lengths=[T - 6, 6], smoothing=EPS)
    loglik, tail, _, _ = brute_force(m, X[-6:], u[-6:])
    assert np.allclose(split[1][-6:], tail, rtol=1e-9, atol=1e-13)
    head = m.score_samples(X[:-6], u[:-6], smoothing=EPS)[0]
    assert split[0] == pytest.approx(head + loglik, rel=1e-12)
    assert m.decode(X, u, smoothing=EPS)[0] <= log_prob


def test_posterior_memory_does_not_grow_with_T_beyond_the_output(monkeypatch):
    monkeypatch.setattr(stats, "CHUNK_BYTES", 2**20)
    m = small_map(0, S=12)
    X, u, _ = m.sample(5000, random_state=0)
    peaks = []
    for reps in (4, 16):
        Xr, ur = np.tile(X, (reps, 1)), np.tile(u, reps)
        tracemalloc.start()
        m.score_samples(Xr, ur)
        m.decode(Xr, ur)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    per_step = (peaks[1] - peaks[0]) / ((16 - 4) * len(u)) - 8 * m.n_states  # less the output
    assert per_step < 40, peaks


def test_the_learner_answers_with_its_maps_methods():
    X, u, _ = ring(n_steps=300)
    learner = MapLearner(n_clusters=5, n_states=6)
    with pytest.raises(NotFittedError):
        learner.predict_proba(X, u)
    m = learner.fit(X, u).map_
    lengths = [100, 200]
    assert np.array_equal(learner.predict_proba(X, u, lengths=lengths),
                          m.predict_proba(X, u, lengths=lengths))
    log_prob, post = learner.score_samples(X, u)
    assert log_prob == m.score_samples(X, u)[0] and np.array_equal(post, m.predict_proba(X, u))
    for algorithm in ("viterbi", "map"):
        got, want = learner.decode(X, u, algorithm=algorithm), m.decode(X, u, algorithm=algorithm)
        assert got[0] == want[0] and np.array_equal(got[1], want[1])
    # a clean ring: every step's posterior is sure of the state the learner gave it
    assert np.array_equal(post.argmax(axis=1), learner.labels_) and post.max(axis=1).min() > 0.99


def test_the_example_of_the_navigating_page_runs_as_written():
    page = Path(__file__).resolve().parents[1] / "docs" / "navigating.md"
    (code,) = [b for b in re.findall(r"^```python\n(.*?)^```", page.read_text(), re.S | re.M)
               if "predict_proba" in b]
    ns = {}
    exec(compile(code, str(page), "exec"), ns)
    m, X, u, post = ns["m"], ns["X"], ns["u"], ns["post"]
    assert post.shape == (300, m.n_states) and np.allclose(post.sum(axis=1), 1.0)
    assert ns["log_prob"] == pytest.approx(m.score(X, u) * 300, rel=1e-12)
    assert np.array_equal(ns["path"], m.predict(X, u))
    assert np.array_equal(ns["states"], post.argmax(axis=1))
    first = [acts[0] for acts in executable_actions(m)]  # what the page's policy takes
    assert ns["xs"].shape == (500,) and np.array_equal(ns["us"], np.take(first, ns["xs"]))
    assert set(ns["route"]) <= set(m.action_names)
