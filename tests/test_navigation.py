"""Using a map: forward filtering, planning and navigation, on models small enough to check by hand."""

import itertools
from dataclasses import replace

import numpy as np
import pytest
from worlds import ring

from topomap import MapLearner, TopologicalMap
from topomap.worlds.navigation import Navigation, PlaceGraph, state_places

SMOOTH = 1e-3


def tiny_map():
    """3 states, 2 actions, 1-D Gaussian observations (states 0 and 1 look alike)."""
    trans = np.zeros((3, 2, 3), dtype=int)
    trans[0, 0] = [0, 6, 2]
    trans[0, 1] = [3, 0, 1]
    trans[1, 0] = [1, 0, 7]
    trans[1, 1] = [4, 4, 0]
    trans[2, 0] = [5, 1, 0]
    trans[2, 1] = [0, 2, 2]
    return TopologicalMap(
        state_symbol=[0, 0, 1], state_gds=[-1, -1, -1], state_parent=[-1, 0, -1],
        means=[[0.0], [0.0], [2.0]], covariances=[[1.0], [1.0], [0.5]], state_counts=[10, 8, 6],
        action_counts=[[8, 4], [8, 8], [6, 4]], transition_counts=trans)


def brute_force_beliefs(m, X, u):
    """P(x_t | o_1..t, u_1..t-1) by summing over every state path (smoothed tables)."""
    S, A = m.n_states, m.n_actions
    P0 = (1 - SMOOTH) * m.state_probs + SMOOTH / S
    PU = (1 - SMOOTH) * m.action_probs + SMOOTH / A
    PT = (1 - SMOOTH) * m.transition_probs + SMOOTH / S
    var, mean = m.covariances[:, 0], m.means[:, 0]
    dens = np.exp(-0.5 * (X[:, :1] - mean) ** 2 / var) / np.sqrt(2 * np.pi * var)  # (T, S)
    out = []
    for t in range(len(X)):
        weight = np.zeros(S)
        for path in itertools.product(range(S), repeat=t + 1):
            w = P0[path[0]] * dens[0, path[0]]
            for k in range(1, t + 1):
                w *= PU[path[k - 1], u[k - 1]] * PT[path[k - 1], u[k - 1], path[k]] * dens[k, path[k]]
            weight[path[-1]] += w
        out.append(weight / weight.sum())
    return np.array(out)


def test_filter_agrees_with_brute_force_enumeration():
    m = tiny_map()
    X = np.array([[0.1], [2.2], [-0.3], [0.4], [1.9]])
    u = np.array([0, 1, 0, 0, 1])
    beliefs = m.filter(X, u, smoothing=SMOOTH)
    assert np.allclose(beliefs, brute_force_beliefs(m, X, u), rtol=1e-10, atol=1e-12)
    assert np.allclose(beliefs.sum(axis=1), 1.0)


def test_filter_restarts_at_every_episode_and_step_belief_is_one_step_of_it():
    m = tiny_map()
    X = np.array([[0.1], [2.2], [-0.3], [0.4], [1.9]])
    u = np.array([0, 1, 0, 0, 1])
    both = m.filter(X, u, lengths=[2, 3], smoothing=SMOOTH)
    assert np.allclose(both[2:], m.filter(X[2:], u[2:], smoothing=SMOOTH))
    belief = None
    for t in range(len(X)):
        belief = m.step_belief(belief, u[t - 1] if t else 0, X[t], smoothing=SMOOTH)
        assert np.allclose(belief, both[t] if t < 2 else m.filter(X[:t + 1], u[:t + 1],
                                                                    smoothing=SMOOTH)[t])


def test_plan_follows_the_most_probable_path():
    m = tiny_map()
    # arcs: 0->1 by action 0 (6/8), 1->2 by action 0 (7/8), 0->2 by action 0 (2/8) or 1 (1/4)
    assert m.plan(0, 1) == [0]
    assert m.plan(0, 2) == [0, 0]  # 0.75 * 0.875 = 0.66 beats the direct 0.25
    assert m.plan(2, 2) == []
    assert m.plan(2, {1, 2}) == []
    # 1 -> 0 directly: best by action 1 (4/8); via 2: 7/8 * 5/6 = 0.73 is more probable
    assert m.plan(1, [0]) == [0, 0]
    assert m.plan(1, [0], min_prob=0.8) == [0, 0]


def test_plan_gives_action_names_when_asked():
    m = tiny_map()
    named = replace(m, action_names=["fwd", "turn"])
    assert named.plan(0, 2) == [0, 0]  # ids unless asked
    assert named.plan(0, 2, names=True) == ["fwd", "fwd"]
    assert m.plan(0, 2, names=True) == ["0", "0"]  # no names: the ids as to_networkx labels
    assert named.plan(2, 2, names=True) == []
    trans = np.zeros((3, 2, 3), dtype=int)
    trans[0, 1, 1] = trans[1, 0, 2] = 2  # 0 -> 1 by action 1, 1 -> 2 by action 0
    line = TopologicalMap([0, 1, 2], [-1] * 3, [-1] * 3, np.zeros((3, 1)), np.ones((3, 1)),
                          [2, 2, 1], [[0, 2], [2, 0], [1, 0]], trans, action_names=["a", "b"])
    assert line.plan(0, 2) == [1, 0] and line.plan(0, 2, names=True) == ["b", "a"]


def test_plan_refuses_unreachable_goals_and_unknown_states():
    trans = np.zeros((3, 1, 3), dtype=int)
    trans[0, 0, 1] = 3  # 0 -> 1 only; nothing leads to 2
    m = TopologicalMap([0, 1, 2], [-1] * 3, [-1] * 3, np.zeros((3, 1)), np.ones((3, 1)),
                       [3, 3, 1], [[3], [0], [0]], trans)
    with pytest.raises(ValueError, match=r"no goal state of \[2\] can be reached from state 0"):
        m.plan(0, 2)
    with pytest.raises(ValueError, match="state 7 is not a state of this map"):
        m.plan(0, 7)
    with pytest.raises(ValueError, match="at least one state"):
        m.plan(0, [])


class RingWorld:
    """Six places on a ring, forward / back; places 1 and 4 look alike."""

    def __init__(self):
        n = 6
        self.successors = np.array([[(p + 1) % n, (p - 1) % n] for p in range(n)])
        symbol = np.array([0, 1, 2, 3, 1, 4])
        self.observations = np.eye(5)[symbol]

    def place_graph(self):
        return PlaceGraph(self.successors, self.observations, np.full(6, -1), np.arange(6))


def test_navigation_on_a_ring_succeeds_every_time_by_the_shortest_way():
    X, u, places = ring(n_steps=600)
    learner = MapLearner(n_clusters=5, n_states=6).fit(X, u)
    nav = Navigation(episodes=30, localise_steps=6, seed=1)
    result = nav.evaluate(learner.map_, learner.labels_, places, RingWorld())
    assert result["success_rate"] == 1.0 and result["episodes"] == 30
    assert result["path_ratio"] == 1.0  # every episode took the shortest way
    assert result["goals_missing_from_map"] == 0


def test_navigation_on_an_aliased_map_fails_where_it_cannot_tell_places_apart():
    """Phase 1 alone merges places 1 and 4: the robot then confuses them, and some episodes
    take longer than the shortest path or fail; the measure must show it."""
    X, u, places = ring(n_steps=600)
    learner = MapLearner(n_clusters=5, n_states=5).fit(X, u)
    result = Navigation(episodes=40, localise_steps=0, seed=2).evaluate(
        learner.map_, learner.labels_, places, RingWorld())
    assert result["goals_missing_from_map"] > 0 or result["success_rate"] < 1.0 \
        or result["path_ratio"] > 1.0


def test_state_places_is_each_states_most_common_place():
    assert state_places([0, 0, 1, 1, 1, 2], [5, 5, 3, 4, 4, 9], 4).tolist() == [5, 4, 9, -1]


# ---------------------------------------------------------------- the app: evaluate=navigation, task=localize
SMALL = ["data.n_steps=600", "data.heldout_steps=0", "output.figures=false",
         "output.progress=false"]


def test_evaluate_navigation_reports_success_and_path_length(make_cfg, tmp_path):
    import json

    from topomap.app.run.experiment import run

    results = run(make_cfg([*SMALL, "evaluate=navigation", "evaluate.episodes=20"]), tmp_path)
    nav = json.loads((tmp_path / "metrics.json").read_text())["navigation"]
    assert nav == results["navigation"] and nav["episodes"] == 20
    assert 0 <= nav["success_rate"] <= 1 and nav["path_ratio"] >= 1.0
    assert "navigation" not in run(make_cfg(SMALL), tmp_path / "plain")


def test_task_localize_applies_a_saved_map_to_a_recording(make_cfg, tmp_path):
    from topomap import TopologicalMap, load_trajectory
    from topomap.app.run.experiment import run

    run(make_cfg(SMALL), tmp_path / "learn")
    rec = tmp_path / "learn" / "trajectory.npz"
    results = run(make_cfg(["task=localize", f"map={tmp_path / 'learn' / 'map.json'}",
                            "data=file", f"data.path={rec}"]), tmp_path / "loc")
    traj, m = load_trajectory(rec), TopologicalMap.load(tmp_path / "learn" / "map.json")
    with np.load(tmp_path / "loc" / "beliefs.npz", allow_pickle=False) as f:
        beliefs = f["beliefs"]
    assert beliefs.shape == (600, m.n_states) and np.allclose(beliefs.sum(axis=1), 1)
    states = np.loadtxt(tmp_path / "loc" / "states.csv", delimiter=",", skiprows=1, dtype=int)
    assert np.array_equal(states[:, 1], beliefs.argmax(axis=1))
    assert np.array_equal(states[:, 2], m.predict(traj.observations, traj.actions, gds=traj.gds))
    assert np.array_equal(states[:, 3], traj.places)
    assert results["loglik"] == pytest.approx(m.score(traj.observations, traj.actions,
                                                      gds=traj.gds))
    assert results["ground_truth"]["viterbi"]["ari"] > 0.9
    with pytest.raises(ValueError, match="task=localize needs the map"):
        run(make_cfg(["task=localize", "data=file", f"data.path={rec}"]), tmp_path / "x")
