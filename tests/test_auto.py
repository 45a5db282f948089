"""Choosing the number of states (stop=auto): the scores worked out by hand, and the size picked
on a world whose number of places is known."""

import json

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap import MapLearner
from topomap.app.run.experiment import run
from topomap.core.size import AutoStates, SizeScores, UpTo, bic, parameter_count, split_holdout

from worlds import ring


def test_parameter_count_by_hand():
    # rows (x, u): (0,0) (0,1) (1,0) (1,0) -> 3 rows over 2 states: 1 free P(u|x) parameter;
    # every row followed by one next state only: no free P(x'|x,u) parameter
    assert parameter_count([0, 0, 1, 1], [0, 1, 0, 0], 2, np.array([1, 1, 1, 0], bool)) == 1
    # one action: no free P(u|x) parameter; state 0 is followed by 0 and by 1 (one free
    # transition parameter), state 1 by 0 only
    labels, actions = [0, 0, 1, 0, 1], [0, 0, 0, 0, 0]
    assert parameter_count(labels, actions, 1, np.array([1, 1, 1, 1, 0], bool)) == 1
    # an episode boundary after step 0 hides 0 -> 0: state 0 is only ever followed by 1
    assert parameter_count(labels, actions, 1, np.array([0, 1, 1, 1, 0], bool)) == 0


def test_bic_by_hand():
    # H(u|x) = 1 bit over 8 steps, H(x'|x,u) = 0.5 bits over 7 transitions, 3 parameters
    loglik = -np.log(2) * (8 * 1.0 + 7 * 0.5)
    assert bic({"H_u": 1.0, "H_x": 0.5}, 3, 8, 7) == pytest.approx(-2 * loglik + 3 * np.log(8))


def test_split_holdout_cuts_the_last_steps_across_episodes():
    train, held, cut = split_holdout(20, [12, 8], 0.2)
    assert cut == 16 and train.tolist() == [12, 4] and held.tolist() == [4]
    train, held, cut = split_holdout(10, [5, 5], 0.5)
    assert cut == 5 and train.tolist() == [5] and held.tolist() == [5]
    # at least three steps on either side
    assert split_holdout(10, [10], 0.01)[2] == 7 and split_holdout(10, [10], 0.99)[2] == 3


def test_best_size_is_the_highest_score_and_the_smallest_on_ties():
    scores = SizeScores("bic", (np.zeros((4, 1)), np.zeros(4, int), [4], 1))
    scores.scores = {5: 1.0, 6: 3.0, 7: 3.0, 8: 2.0}
    assert scores.best() == 6


def test_probe_rule_stops_at_its_limit_or_when_nothing_gains():
    rule = UpTo(2.5)
    rule.check(10)
    assert not rule.should_stop(24, 0.1)
    assert rule.should_stop(25, 0.1) and rule.should_stop(12, 0.0)


@pytest.mark.parametrize("kwargs, field", [({"criterion": "aic"}, "^criterion"),
                                           ({"max_factor": 0.5}, "^max_factor"),
                                           ({"holdout": 1.0}, "^holdout"),
                                           ({"patience": 0}, "^patience")])
def test_bad_settings_name_their_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        AutoStates(**kwargs)


@pytest.mark.parametrize("seed", range(3))
def test_heldout_picks_the_number_of_places_of_an_aliased_ring(seed):
    """Six places, five symbols (places 1 and 4 look alike): one split disambiguates them, every
    later split only fits the noise of the random actions, which the held-out steps punish."""
    X, u, places = ring(n_steps=2000, seed=seed, aliased=((1, 4),), n_places=6)
    # heading="off": on a ring, moving on is a turn that comes back after six steps, and the
    # heading integrated from it would tell the places apart in phase 1 (6 states, no split)
    learner = MapLearner(n_clusters=5, n_states="auto", heading="off", random_state=seed).fit(X, u)
    choice = learner.size_choice_
    assert choice["criterion"] == "heldout" and choice["chosen"] == 6 == learner.map_.n_states
    assert adjusted_rand_score(places, learner.labels_) == 1.0
    # every size of the probe was scored, from phase 1 (5 states) until 10 splits (the default
    # patience: at least 10) brought no better score than 6 states
    assert sorted(choice["scores"]) == list(range(5, 17))
    assert max(choice["scores"], key=choice["scores"].get) == 6
    assert learner.map_.info["size_choice"] == {"criterion": "heldout", "chosen": 6}


def test_patience_only_shortens_the_probe():
    X, u, _ = ring(n_steps=2000, seed=1, aliased=((1, 4),), n_places=6)
    full = MapLearner(n_clusters=5, stop=AutoStates(patience=1000), heading="off",
                      random_state=1).fit(X, u)
    short = MapLearner(n_clusters=5, stop=AutoStates(patience=3), heading="off",
                       random_state=1).fit(X, u)
    assert sorted(full.size_choice_["scores"]) == list(range(5, 51))  # up to 10 x 5 states
    assert sorted(short.size_choice_["scores"]) == list(range(5, 10))
    assert {n: full.size_choice_["scores"][n] for n in range(5, 10)} == short.size_choice_["scores"]
    assert full.size_choice_["chosen"] == short.size_choice_["chosen"] == 6


def test_bic_scores_every_size_and_picks_its_best():
    X, u, places = ring(n_steps=2000, seed=0, aliased=((1, 4),), n_places=6)
    learner = MapLearner(n_clusters=5, stop=AutoStates("bic", max_factor=3, patience=100),
                         heading="off", random_state=0).fit(X, u)
    scores = learner.size_choice_["scores"]
    assert sorted(scores) == list(range(5, 16))
    assert learner.map_.n_states == max(scores, key=scores.get)
    # the split that disambiguates the aliased place is worth far more than its parameters
    assert scores[6] - scores[5] > 100


def test_auto_leaves_the_parameter_and_a_later_fixed_fit_alone():
    X, u, _ = ring(n_steps=600, seed=0, aliased=((1, 4),), n_places=6)
    learner = MapLearner(n_clusters=5, n_states="auto", random_state=0).fit(X, u)
    assert learner.n_states == "auto"
    learner.set_params(n_states=5).fit(X, u)
    assert learner.map_.n_states == 5 and not hasattr(learner, "size_choice_")


def test_stop_auto_from_the_command_line_config(tmp_path, make_cfg):
    cfg = make_cfg(["stop=auto", "stop.max_factor=2", "data.n_steps=400", "clusters.ns=8",
                    "output.figures=false", "output.progress=false"])
    results = run(cfg, tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    choice = metrics["size_choice"]
    assert choice["criterion"] == "heldout" and set(map(int, choice["scores"])) == set(
        range(10, 21))
    assert results["n_states"]["final"] == choice["chosen"]
    assert json.loads((tmp_path / "map.json").read_text())["info"]["size_choice"]["chosen"] == \
        choice["chosen"]
