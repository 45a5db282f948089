"""A refit learns from scratch: nothing of the previous fit survives it."""

import numpy as np
import pytest

from test_resize import _ring_observations, ring_walk

from topomap import MapLearner


def _ring_walk():
    """The aliased ring of the resizing tests: six places, three symbols, walked at random."""
    places, acts = ring_walk()
    return _ring_observations(places), acts, places


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
