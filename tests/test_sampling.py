"""Walks drawn from a map (``sample``): their frequencies are the map's tables, the actions given
or chosen by a policy are the ones taken, and a seed gives the same walk again."""

import numpy as np
import pytest
from worlds import ring

from topomap import MapLearner, TopologicalMap


def hand_map(cov="diag"):
    """3 states, 2 actions; (state 0, action 1) was taken but never led anywhere (uniform)."""
    trans = np.zeros((3, 2, 3), dtype=int)
    trans[0, 0] = [0, 3, 1]
    trans[1, 0] = [2, 0, 2]
    trans[1, 1] = [0, 1, 3]
    trans[2, 0] = [1, 1, 0]
    trans[2, 1] = [0, 0, 5]
    var = np.array([[1.0, 0.25], [0.5, 0.5], [2.0, 1.0]])
    covariances = var if cov == "diag" else np.stack([np.diag(v) + 0.2 for v in var])
    return TopologicalMap([0, 1, 2], [-1] * 3, [-1] * 3, [[0.0, 0.0], [3.0, 0.0], [0.0, -3.0]],
                          covariances, [6, 8, 8], [[4, 2], [3, 5], [2, 6]], trans)


def within(freq, p, n, sigmas=5.0):
    """``freq`` (of ``n`` draws) is within ``sigmas`` binomial standard deviations of ``p``."""
    return np.all(np.abs(freq - p) <= sigmas * np.sqrt(p * (1 - p) / np.maximum(n, 1)) + 1e-9)


@pytest.mark.parametrize("cov", ["diag", "full"])
def test_a_long_walk_has_the_maps_frequencies(cov):
    m = hand_map(cov)
    n = 60_000
    X, u, x = m.sample(n, random_state=3)
    assert X.shape == (n, 2) and u.shape == x.shape == (n,)
    seen = np.zeros((3, 2, 3))
    np.add.at(seen, (x[:-1], u[:-1], x[1:]), 1)
    per_pair = seen.sum(axis=2, keepdims=True)
    assert per_pair.min() > 500
    assert within(seen / per_pair, m.transition_probs, per_pair)
    # the pair never seen moves uniformly
    assert within(seen[0, 1] / per_pair[0, 1], np.full(3, 1 / 3), per_pair[0, 1])
    taken = np.zeros((3, 2))
    np.add.at(taken, (x, u), 1)
    per_state = taken.sum(axis=1, keepdims=True)
    assert within(taken / per_state, m.action_probs, per_state)
    for s in range(3):
        steps = X[x == s]
        assert np.allclose(steps.mean(axis=0), m.means[s], atol=5 * np.sqrt(2.2 / len(steps)))
        want = np.diag(m.covariances[s]) if cov == "diag" else m.covariances[s]
        assert np.allclose(np.cov(steps.T), want, atol=0.06)


def test_the_first_state_follows_the_state_frequencies_or_currstate():
    m = hand_map()
    first = np.array([m.sample(1, random_state=seed)[2][0] for seed in range(3000)])
    assert within(np.bincount(first, minlength=3) / 3000, m.state_probs, 3000)
    assert {int(m.sample(4, currstate=2, random_state=s)[2][0]) for s in range(20)} == {2}


def test_the_same_seed_draws_the_same_walk():
    m = hand_map()
    a, b, c = m.sample(200, random_state=11), m.sample(200, random_state=11), m.sample(
        200, random_state=12)
    assert all(np.array_equal(p, q) for p, q in zip(a, b))
    assert not np.array_equal(a[2], c[2])
    gen = np.random.default_rng(11)
    assert all(np.array_equal(p, q) for p, q in zip(a, m.sample(200, random_state=gen)))


def test_actions_given_are_followed():
    m = hand_map()
    u = np.array([0, 0, 1, 1, 1, 0, 1])
    _, got, x = m.sample(len(u), u, random_state=0, currstate=1)
    assert np.array_equal(got, u) and x[0] == 1
    # every move is one the map allows with that action (state 0 takes action 0 here)
    assert all(m.transition_probs[x[t], u[t], x[t + 1]] > 0 for t in range(len(u) - 1))
    # state 2 under action 1 stays in state 2 (5 of 5)
    _, _, x = m.sample(6, [1] * 6, currstate=2, random_state=0)
    assert x.tolist() == [2] * 6


def test_a_policy_is_asked_with_the_state_and_its_executable_actions():
    m = hand_map()
    asked = []

    def policy(state, executable):  # the last action offered, but action 0 in state 2
        asked.append((state, executable.tolist()))
        return 0 if state == 2 else executable[-1]

    _, u, x = m.sample(50, policy, random_state=5)
    assert [s for s, _ in asked] == x.tolist()
    assert set(x.tolist()) == {0, 1, 2}
    # state 0 has seen only action 0 lead anywhere; states 1 and 2 both actions
    for s, acts in asked:
        assert acts == ([0] if s == 0 else [0, 1])
    assert np.array_equal(u, np.where(x == 1, 1, 0))


def test_a_policy_choosing_an_action_it_was_not_offered_is_refused():
    m = hand_map()
    with pytest.raises(ValueError, match=r"the policy chose action 1 in state 0, whose "
                                         r"executable actions are \[0\]"):
        m.sample(10, lambda state, executable: 1, currstate=0, random_state=0)


@pytest.mark.parametrize("call, match", [
    (lambda m: m.sample(0), "n_samples must be a positive integer, got 0"),
    (lambda m: m.sample(3, [0, 1]), r"actions must be None, a policy or 3 action ids"),
    (lambda m: m.sample(3, [0.5, 1, 1]), r"actions must be None, a policy or 3 action ids"),
    (lambda m: m.sample(3, [0, 2, 1]), r"actions use id 2 but the map knows actions 0..1"),
    (lambda m: m.sample(3, currstate=3), r"currstate must be a state of this map \(0..2\)"),
    (lambda m: m.sample(3, random_state="seed"), "random_state must be an int, None or"),
])
def test_bad_arguments_are_named(call, match):
    with pytest.raises(ValueError, match=match):
        call(hand_map())


def test_the_learner_samples_its_map_with_its_own_seed_by_default():
    X, u, _ = ring(n_steps=300)
    learner = MapLearner(n_clusters=5, n_states=6, random_state=4).fit(X, u)
    a, b = learner.sample(30), learner.map_.sample(30, random_state=4)
    assert all(np.array_equal(p, q) for p, q in zip(a, b))
    c = learner.sample(30, random_state=5)
    assert not np.array_equal(a[2], c[2])
    # a walk on the learned ring moves as the ring does: forward is one state on, back one back
    _, u, x = learner.sample(40, random_state=0)
    m = learner.map_
    assert all(m.transition_probs[x[t], u[t], x[t + 1]] > 0.9 for t in range(39))
