"""A refit learns from scratch: nothing of the previous fit survives it."""

import numpy as np
import pytest

from topomap import MapLearner


def _ring_walk(n_places=6, T=600, seed=0):
    """A ring of places showing 3 symbols twice (aliased pairs), walked forward/backward at random."""
    rng = np.random.default_rng(seed)
    centres = np.eye(3)
    x, places, acts = 0, [], []
    for _ in range(T):
        a = int(rng.integers(2))
        places.append(x)
        acts.append(a)
        x = (x + (1 if a == 0 else -1)) % n_places
    places = np.array(places)
    obs = centres[places % 3] + 0.01 * rng.standard_normal((T, 3))
    return obs, np.array(acts), places


@pytest.fixture(scope="module")
def walk():
    return _ring_walk()


def test_refit_without_refinement_forgets_the_refinement(walk):
    obs, acts, _ = walk
    learner = MapLearner(n_clusters=3, n_states=6, refine="em", random_state=0)
    learner.fit(obs, acts)
    assert hasattr(learner, "refine_info_")
    first_split = learner.map_split_
    learner.set_params(refine=None, n_states=4)
    learner.fit(obs, acts)
    assert not hasattr(learner, "refine_info_")
    assert learner.map_split_ is not first_split
    assert learner.map_split_.n_states == 4
    assert learner.map_ is learner.map_split_
    assert np.array_equal(learner.labels_, learner.labels_split_)


def test_refit_forgets_the_size_choice(walk):
    obs, acts, _ = walk
    learner = MapLearner(n_clusters=3, n_states="auto", random_state=0).fit(obs, acts)
    assert hasattr(learner, "size_choice_")
    learner.set_params(n_states=5).fit(obs, acts)
    assert not hasattr(learner, "size_choice_")
    assert learner.map_.n_states == 5


def test_a_failed_refit_keeps_the_previous_fit(walk):
    obs, acts, _ = walk
    learner = MapLearner(n_clusters=3, n_states=5, random_state=0).fit(obs, acts)
    labels = learner.labels_.copy()
    with pytest.raises(ValueError):
        learner.fit(obs[:10], acts[:9])
    assert np.array_equal(learner.labels_, labels)
