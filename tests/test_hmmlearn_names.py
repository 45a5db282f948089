"""hmmlearn's and scikit-learn's habits on a learned map: a sequence without actions is decoded
with the actions summed out (``predict(X)``, ``score(X)``), and a fitted learner shows the map
under hmmlearn's names (``n_components``, ``startprob_``, ``transmat_``, ``means_``,
``covars_``), read only."""

import itertools

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError
from worlds import ring

from topomap import MapLearner, TopologicalMap

from test_decoding import small_map, small_sequence

EPS = 0.01  # smoothing large enough to matter


def two_states(transitions):
    """States 0 and 1 of one feature, N(0, 1) and N(1, 1), 4 steps each; state 0 took action 0
    three times and action 1 once, state 1 each action twice; ``transitions`` (2, 2, 2)."""
    return TopologicalMap([0, 1], [-1, -1], [-1, -1], [[0.0], [1.0]], [[1.0], [1.0]], [4, 4],
                          [[3, 1], [2, 2]], transitions)


def test_the_transitions_with_the_action_summed_out_by_hand():
    """From state 0: action 0 (3/4) stays, action 1 (1/4) moves: P(x'|0) = (3/4, 1/4).  From
    state 1 each action is taken half the time, action 0 to state 0; action 1 has no counted
    transition (taken only at an episode's end), so it goes anywhere: P(x'|1) = 1/2 (1, 0) +
    1/2 (1/2, 1/2) = (3/4, 1/4)."""
    m = two_states([[[3, 0], [0, 1]], [[2, 0], [0, 0]]])
    assert np.allclose(m.marginal_transition_probs, [[3 / 4, 1 / 4], [3 / 4, 1 / 4]])


def test_the_likelihood_without_actions_by_hand():
    """Two steps seeing 0 and 0, ``a = N(0 | 0, 1)``, ``b = N(0 | 1, 1)``, both states a half to
    start from, P(x'|0) = (3/4, 1/4), P(x'|1) = (1/2, 1/2):
    P(o) = 1/2 a (3/4 a + 1/4 b) + 1/2 b (1/2 a + 1/2 b)."""
    m = two_states([[[3, 0], [0, 1]], [[2, 0], [0, 2]]])
    a, b = 1 / np.sqrt(2 * np.pi), np.exp(-0.5) / np.sqrt(2 * np.pi)
    by_hand = 0.5 * a * (0.75 * a + 0.25 * b) + 0.5 * b * (0.5 * a + 0.5 * b)
    X = np.zeros((2, 1))
    assert 2 * m.score(X, smoothing=1e-12) == pytest.approx(np.log(by_hand), rel=1e-10)
    # the most probable path: (0, 0), a (3/4 a) against (1, 1)'s b (1/2 b) and the rest
    assert m.predict(X, smoothing=1e-12).tolist() == [0, 0]
    assert m.decode(X, smoothing=1e-12)[0] == pytest.approx(np.log(0.5 * a * 0.75 * a), rel=1e-10)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_without_actions_is_the_sum_over_every_action_sequence(seed):
    """log P(o) = log of the sum over all A^T action sequences u of P(o, u) (the map's own
    likelihood with actions), on a map with an (x, u) never seen; and it is at least the
    likelihood with the sequence's own actions."""
    m = small_map(seed)
    X, u, _ = small_sequence(seed, m, T=5)
    summed = np.logaddexp.reduce([m.score_samples(X, list(us), smoothing=1e-12)[0]
                                  for us in itertools.product(range(m.n_actions), repeat=5)])
    log_prob = m.score_samples(X, smoothing=1e-12)[0]
    assert log_prob == pytest.approx(summed, rel=1e-9)
    assert 5 * m.score(X, smoothing=1e-12) == pytest.approx(log_prob, rel=1e-12)
    assert log_prob >= m.score_samples(X, u, smoothing=1e-12)[0]


@pytest.mark.parametrize("lengths", [None, [4, 2]])
def test_without_actions_the_map_is_hmmlearns_hmm_on_its_marginal_transitions(lengths):
    """hmmlearn's GaussianHMM given the map's start probabilities and its transitions with the
    action summed out (both smoothed as the map smooths them) gives the same likelihood,
    posteriors and Viterbi path."""
    hmm = pytest.importorskip("hmmlearn.hmm")
    m = small_map(3)
    X, _, _ = small_sequence(3, m)
    S = m.n_states
    model = hmm.GaussianHMM(n_components=S, covariance_type="diag")
    model.n_features = m.n_features
    model.startprob_ = (1 - EPS) * m.state_probs + EPS / S
    model.transmat_ = (1 - EPS) * m.marginal_transition_probs + EPS / S
    model.means_, model.covars_ = m.means, m.covariances
    log_prob, post = m.score_samples(X, lengths=lengths, smoothing=EPS)
    assert log_prob == pytest.approx(model.score(X, lengths), rel=1e-10)
    assert np.allclose(post, model.predict_proba(X, lengths), atol=1e-10)
    viterbi, theirs = m.decode(X, lengths=lengths, smoothing=EPS), model.decode(X, lengths)
    assert viterbi[0] == pytest.approx(theirs[0], rel=1e-10)
    assert np.array_equal(viterbi[1], theirs[1])
    assert np.array_equal(m.predict(X, lengths=lengths, smoothing=EPS), theirs[1])


def test_a_learner_decodes_a_walk_without_its_actions():
    """On a ring whose places 1 and 4 look alike, a held-out walk's states are its places with
    or without its actions (the neighbours tell the two apart either way); predict(X) and
    score(X) raise no TypeError, and an observation of the wrong width is refused by name."""
    X, u, _ = ring(400, seed=0)
    learner = MapLearner(n_clusters=5, n_states=6, random_state=0).fit(X, u)
    X2, u2, places = ring(300, seed=1)
    by_place = {}
    for state, place in zip(learner.predict(X2), places):
        by_place.setdefault(place, set()).add(int(state))
    assert all(len(states) == 1 for states in by_place.values()) and len(by_place) == 6
    assert np.array_equal(learner.predict(X2), learner.predict(X2, u2))
    assert learner.score(X2) >= learner.score(X2, u2)
    with pytest.raises(ValueError, match="observations have 4 features but the map was learned"):
        learner.predict(X2[:, :4])


def test_a_fitted_learner_shows_its_map_under_hmmlearns_names():
    X, u, _ = ring(400, seed=0)
    learner = MapLearner(n_clusters=5, n_states=6, random_state=0)
    for name in ("n_components", "startprob_", "transmat_", "means_", "covars_"):
        with pytest.raises(NotFittedError):
            getattr(learner, name)
        assert not hasattr(learner, name)
    learner.fit(X, u)
    m = learner.map_
    S, A, D = m.n_states, m.n_actions, m.n_features
    assert learner.n_components == S == 6
    assert learner.transmat_.shape == (A, S, S) and np.allclose(learner.transmat_.sum(axis=2), 1)
    for a in range(A):
        assert np.array_equal(learner.transmat_[a], m.transition_probs[:, a, :])
    assert np.allclose(np.einsum("xa,axy->xy", m.action_probs, learner.transmat_),
                       m.marginal_transition_probs)
    assert np.array_equal(learner.startprob_, m.state_probs) and learner.startprob_.sum() == 1
    assert np.array_equal(learner.means_, m.means) and learner.means_.shape == (S, D)
    assert learner.covars_.shape == (S, D, D)
    assert np.array_equal(np.diagonal(learner.covars_, axis1=1, axis2=2), m.covariances)
    assert np.count_nonzero(learner.covars_) == S * D  # nothing off the diagonals of "diag"
    for name in ("startprob_", "transmat_", "means_", "covars_"):
        with pytest.raises(ValueError, match="read-only"):
            getattr(learner, name)[0] = 0
    with pytest.raises(AttributeError):
        learner.transmat_ = np.eye(S)
    params = learner.get_params()
    assert not {"criterion", "stopping", "n_components"} & set(params)
