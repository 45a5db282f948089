"""Scores in metres, and what they share with the learner, on cases whose answers are worked
out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from topomap import TopologicalMap, Trajectory
from topomap.core.phase1.clustering import view_clusters
from topomap.core.stats import label_means, majority_share
from topomap.evaluation.metres import (ceiling_scores, kmeans_position_scores,
                                       kmeans_view_scores, map_scores, placement_scores,
                                       split_places, true_places)
from topomap.metrics import purity


def test_placement_scores_by_hand():
    truth = np.zeros((5, 2))
    placed = np.array([[3, 4], [0, 1], [0, 2], [np.nan, np.nan], [0, 3]], dtype=float)
    s = placement_scores(placed, truth, wrong=np.array([1, 0, 0, 0, 1], dtype=bool))
    # distances 5, 1, 2, 3 (the NaN row left out): median 2.5; numpy's 90th percentile 4.4
    assert s == {"median_error": 2.5, "p90_error": pytest.approx(4.4), "wrong_region": 0.4,
                 "steps": 5, "unplaced": 1}


@pytest.mark.parametrize("counts, n, expected", [
    ([50, 30, 20], 10, [5, 3, 2]),
    ([50, 30, 20], 7, [4, 2, 1]),   # quotas 3.5, 2.1, 1.4: the largest remainder gets the 7th
    ([98, 1, 1], 4, [2, 1, 1]),     # every region gets a place
    ([3, 0, 5], 8, [3, 0, 5]),      # never more places than steps; none where no step is
])
def test_places_are_shared_by_the_regions_shares(counts, n, expected):
    assert split_places(counts, n).tolist() == expected


def test_too_few_places_for_the_regions_is_an_error():
    with pytest.raises(ValueError, match="n_places=1 must lie between the 2 regions"):
        split_places([5, 5], 1)


# Two rooms on a line, split at x = 1.  The walk goes 0.1 -> 0.9 -> 1.1 -> 1.7, stays, and comes
# back (each point twice per cycle), one action; each point shows its own view.  Two places:
# K-means within the rooms makes {0.1, 0.9} (mean 0.5) and {1.1, 1.7} (mean 1.4): every step is
# placed 0.4 m or 0.3 m off (median 0.35, 90th percentile 0.4), always in its own room.  K-means
# on all positions instead makes {0.1} and {0.9, 1.1, 1.7} (inertia 0.347 against 0.5 and 0.56
# for the other cuts), a place straddling the wall, mean 3.7 / 3: errors 0, 1/3, 2/15, 7/15,
# median (2/15 + 1/3) / 2 = 7/30.
CYCLE = np.array([0, 1, 2, 3, 3, 2, 1, 0])
XS = np.array([0.1, 0.9, 1.1, 1.7])


def line_walk(n_cycles: int, noise_seed: int) -> Trajectory:
    points = np.tile(CYCLE, n_cycles)
    rng = np.random.default_rng(noise_seed)
    obs = points[:, None] + rng.normal(0, 0.01, (points.size, 1))
    return Trajectory(obs, np.zeros(points.size, dtype=int),
                      positions=np.column_stack([XS[points], np.zeros(points.size)]))


def room_of(positions):
    return (np.asarray(positions)[:, 0] > 1).astype(int)


def truth_map(train: Trajectory) -> tuple[TopologicalMap, np.ndarray]:
    """A map whose 2 states are the rooms, its steps' symbols the 4 views (as a learner's)."""
    rooms = room_of(train.positions)
    tmap = TopologicalMap.from_labels(train.observations, train.actions, rooms,
                                      state_symbol=[0, 2], state_gds=[-1, -1],
                                      state_parent=[-1, -1], n_actions=1)
    return tmap, rooms


def test_the_ceiling_cuts_places_within_rooms():
    train, held = line_walk(20, 0), line_walk(5, 1)
    tmap, rooms = truth_map(train)
    symbols = np.rint(train.observations[:, 0]).astype(int)
    s = ceiling_scores(tmap, rooms, train, held, regions=room_of, train_symbols=symbols)
    assert s["median_error"] == pytest.approx(0.35) and s["p90_error"] == pytest.approx(0.4)
    assert s["wrong_region"] == 0.0
    places = true_places(train.positions, 2, room_of(train.positions))
    assert {tuple(np.unique(train.positions[places == p, 0])) for p in (0, 1)} == {
        (0.1, 0.9), (1.1, 1.7)}


def test_without_regions_the_ceiling_may_straddle_the_wall():
    train, held = line_walk(20, 0), line_walk(5, 1)
    tmap, rooms = truth_map(train)
    symbols = np.rint(train.observations[:, 0]).astype(int)
    s = ceiling_scores(tmap, rooms, train, held, train_symbols=symbols)
    assert s["median_error"] == pytest.approx(7 / 30) and s["wrong_region"] is None


def test_map_and_kmeans_on_views_by_hand():
    train, held = line_walk(20, 0), line_walk(5, 1)
    tmap, rooms = truth_map(train)
    s = map_scores(tmap, rooms, train, held, regions=room_of)
    assert s["median_error"] == pytest.approx(0.35) and s["wrong_region"] == 0.0
    k = kmeans_view_scores(4, train, held, regions=room_of)  # one cluster per view: exact
    assert k["median_error"] == pytest.approx(0.0) and k["wrong_region"] == 0.0
    k2 = kmeans_view_scores(4, train, held, regions=(room_of(train.positions),
                                                     1 - room_of(held.positions)))
    assert k2["wrong_region"] == 1.0  # labels given as a pair are used as given


def test_kmeans_on_true_positions_by_hand():
    """Two cells on all positions are {0.1} and {0.9, 1.1, 1.7} (the cut of least inertia, as
    for the ceiling without regions): each held-out step goes to the cell nearest its true
    position, 0.1 -> 0.1 (0 m off), 0.9 -> 3.7 / 3 (1/3), 1.1 (2/15), 1.7 (7/15): median 7/30.
    The second cell's steps lie mostly east of x = 1, so the 0.9 steps, a quarter, are placed in
    the wrong room.  Four cells are the four points: every step exactly placed."""
    train, held = line_walk(20, 0), line_walk(5, 1)
    s = kmeans_position_scores(2, train, held, regions=room_of)
    assert s["median_error"] == pytest.approx(7 / 30) and s["wrong_region"] == pytest.approx(0.25)
    exact = kmeans_position_scores(4, train, held, regions=room_of)
    assert exact["median_error"] == pytest.approx(0.0) and exact["wrong_region"] == 0.0


def test_scores_need_positions():
    train = line_walk(3, 0)
    held = Trajectory(train.observations, train.actions)
    with pytest.raises(ValueError, match="held-out trajectory has no positions"):
        kmeans_view_scores(2, train, held)


# ---------------------------------------------------------------- what the scores share with the learner
def test_label_means_by_hand():
    means = label_means([0, 1, 0, 2], np.array([[1.0, 10], [5, 50], [3, 30], [7, 70]]), 4)
    assert means[:3].tolist() == [[2.0, 20.0], [5.0, 50.0], [7.0, 70.0]]
    assert np.isnan(means[3]).all()  # no step carries label 3


def test_purity_is_the_majority_share():
    """Label 0 holds places 0, 0, 1 (2 in its majority), label 1 places 1, 1 (2): 4 of 5."""
    places, states = [0, 0, 1, 1, 1], [0, 0, 0, 1, 1]
    assert majority_share(places, states) == 0.8 == purity(places, states)


def test_view_clusters_are_numbered_by_first_appearance():
    """Three groups of views far apart, met in the order c, a, b: clusters 0, 1, 2."""
    a, b, c = [0.0, 0.0], [10.0, 0.0], [0.0, 10.0]
    Z = np.array([c, c, a, a, b, b, a, c]) + 0.01 * np.arange(8)[:, None]
    assert view_clusters(Z, 3, 4, 0).tolist() == [0, 0, 1, 1, 2, 2, 1, 0]


def test_the_old_name_of_the_scores_in_metres_warns_and_gives_the_same_functions():
    import importlib

    from topomap.evaluation import metres

    old = importlib.import_module("topomap.core.position_scores")
    with pytest.warns(FutureWarning, match="topomap.core.position_scores is now "
                                           "topomap.evaluation.metres"):
        assert old.position_scores is metres.position_scores
