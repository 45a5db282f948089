"""Tests of the table-driven worlds (their base, gridroom, random_graph) and minigrid: moves
respect walls and edges, ground truth agrees with the noise-free observations, and a seed fixes
the trajectory."""

import importlib.util
import sys

import networkx as nx
import numpy as np
import pytest

from topomap.worlds.table import TableWorld
from topomap.worlds.table.gridroom import MOVES, GridRoom
from topomap.worlds.minigrid import (
    CHECKED_ENVS,
    MiniGridWorld,
    MissingDependencyError,
    encode_view,
)
from topomap.worlds.table.random_graph import RandomGraphWorld, random_strong_digraph
from topomap.app.run.experiment import run
from topomap.app.results import FIGURE_FILES, OUTPUT_FILES
from topomap.worlds.explorers import RandomExplorer
from topomap.core.data.trajectory import Trajectory


def walk(world, n, seed=0):
    return world.simulate(n, RandomExplorer(), np.random.default_rng(seed))


class Recorder:
    """A random explorer that keeps every mask it was shown."""

    def __init__(self):
        self.masks = []

    def choose(self, mask, rng):
        self.masks.append(np.array(mask))
        return RandomExplorer().choose(mask, rng)


# ------------------------------------------------------------------ the table-driven base


class Line(TableWorld):
    """Three places in a row, 0 - 1 - 2: action 0 goes right, action 1 left; places 0 and 2 show
    symbol 0, place 1 symbol 1.  ``one_way``: nothing leads back from place 2."""

    def __init__(self, one_way=False):
        self.successors = np.array([[1, -1], [2, 0], [-1, -1 if one_way else 1]])
        self.place_symbols = np.array([0, 1, 0])
        self.embedding = np.array([[1.0, 0.0], [0.0, 1.0]])
        self.place_positions = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
        self.action_names = ["right", "left"]

    def meta(self):
        return {"world": "line"}


class Rightmost:
    """Takes the lowest executable action: right while it can."""

    def choose(self, mask, rng):
        return int(np.flatnonzero(mask)[0])


def test_a_table_world_walks_observes_and_draws_its_graph_from_its_tables():
    line = Line()
    start = int(np.random.default_rng(4).integers(3))  # the walk's first draw is its start
    tr = line.simulate(6, Rightmost(), np.random.default_rng(4))
    # right to place 2, then left (its only action) and right again, as the table says
    expected = {0: [0, 1, 2, 1, 2, 1], 1: [1, 2, 1, 2, 1, 2], 2: [2, 1, 2, 1, 2, 1]}[start]
    assert tr.places.tolist() == expected
    assert tr.actions.tolist() == [0 if p < 2 else 1 for p in expected]
    assert np.array_equal(tr.observations, np.eye(2)[[0, 1, 0]][expected])
    assert np.array_equal(tr.positions[:, 0], expected)
    assert tr.action_names == ["right", "left"] and tr.meta == {"world": "line"}
    assert line.n_actions == 2
    assert line.executable_mask(0).tolist() == [True, False]
    assert np.array_equal(line.observe(2), [1.0, 0.0])
    graph = line.place_graph()
    assert graph.places.tolist() == [0, 1, 2]
    assert graph.distances_to(2).tolist() == [2, 1, 0]
    assert np.array_equal(graph.observations, np.eye(2)[[0, 1, 0]])
    # from place 2 nothing leads back: the places a robot can go between are 0 and 1
    assert Line(one_way=True).place_graph().places.tolist() == [0, 1]


# ------------------------------------------------------------------ gridroom


@pytest.fixture(scope="module")
def room():
    return GridRoom(width=8, height=6, n_symbols=4, seed=3)


def test_gridroom_moves_one_cell_and_never_through_a_wall(room):
    rec = Recorder()
    tr = room.simulate(3000, rec, np.random.default_rng(0))
    assert len(rec.masks) == 3000  # the explorer is asked exactly once per step
    cells = room.cells[tr.places]
    assert np.all((cells >= 0) & (cells < [room.width, room.height]))
    step = cells[1:] - cells[:-1]
    assert np.array_equal(step, MOVES[tr.actions[:-1]])
    for t in range(3000):  # the mask offered is exactly "the move stays inside"
        target = cells[t] + MOVES
        inside = np.all((target >= 0) & (target < [room.width, room.height]), axis=1)
        assert np.array_equal(rec.masks[t], inside)
        assert rec.masks[t][tr.actions[t]]
    assert len(np.unique(tr.places)) == room.n_places


def test_gridroom_corner_masks_by_hand():
    r = GridRoom(width=3, height=2, n_symbols=2)
    # north, east, south, west
    assert r.executable_mask(r.place_of(0, 0)).tolist() == [True, True, False, False]
    assert r.executable_mask(r.place_of(2, 1)).tolist() == [False, False, True, True]
    assert r.executable_mask(r.place_of(1, 1)).tolist() == [False, True, True, True]
    assert r.step(r.place_of(1, 0), 0) == r.place_of(1, 1)
    with pytest.raises(ValueError, match="wall"):
        r.step(r.place_of(0, 0), 3)


def test_gridroom_two_cells_alternate():
    r = GridRoom(width=2, height=1, n_symbols=1)
    tr = walk(r, 10)
    assert tr.places.tolist() == [tr.places[0], 1 - tr.places[0]] * 5
    assert set(tr.actions.tolist()) <= {1, 3} and np.all(tr.actions[tr.places == 0] == 1)
    assert np.all(tr.observations == 1.0)  # one symbol, one-hot


def test_gridroom_ground_truth_matches_observations(room):
    tr = walk(room, 2000)
    assert isinstance(tr, Trajectory) and tr.gds is None
    assert tr.observations.shape == (2000, 4) and tr.action_names == ["north", "east", "south", "west"]
    onehot = np.eye(4)[room.place_symbols[tr.places]]
    assert np.array_equal(tr.observations, onehot)
    assert np.array_equal(tr.positions, room.cells[tr.places] + 0.5)
    # every symbol shows somewhere and many cells share one (aliasing)
    assert np.array_equal(np.sort(np.unique(room.place_symbols)), np.arange(4))
    assert np.bincount(room.place_symbols).max() >= 48 // 4


def test_gridroom_random_embedding_is_nonnegative_and_per_symbol():
    r = GridRoom(width=5, height=5, n_symbols=6, obs_dim=10, seed=1)
    tr = walk(r, 500)
    assert tr.observations.shape == (500, 10) and tr.observations.min() >= 0
    assert len(np.unique(r.embedding, axis=0)) == 6
    for p in np.unique(tr.places):
        assert np.allclose(tr.observations[tr.places == p], r.embedding[r.place_symbols[p]])


def test_gridroom_same_seed_same_trajectory(room):
    a, b, c = walk(room, 500, 7), walk(room, 500, 7), walk(room, 500, 8)
    assert np.array_equal(a.places, b.places) and np.array_equal(a.actions, b.actions)
    assert np.array_equal(a.observations, b.observations)
    assert not np.array_equal(a.actions, c.actions)
    assert np.array_equal(GridRoom(seed=3).place_symbols, room.place_symbols)
    assert not np.array_equal(GridRoom(seed=4).place_symbols, room.place_symbols)


@pytest.mark.parametrize("kwargs, word", [
    (dict(width=0), "width"), (dict(height=-2), "height"), (dict(width=1, height=1), "two cells"),
    (dict(n_symbols=0), "n_symbols"), (dict(width=2, height=2, n_symbols=5), "n_symbols"),
    (dict(obs_dim=-1), "obs_dim"), (dict(width=2.5), "width"),
    (dict(extra_actions=["jump"]), "extra actions"),
])
def test_gridroom_bad_arguments(kwargs, word):
    with pytest.raises(ValueError, match=word):
        GridRoom(**kwargs)


# ------------------------------------------------------------------ random_graph


@pytest.mark.parametrize("n, k", [(2, 1), (5, 1), (12, 2), (30, 4), (9, 8)])
def test_random_digraph_is_strongly_connected_with_distinct_out_edges(n, k):
    for seed in range(5):
        succ = random_strong_digraph(n, k, np.random.default_rng(seed))
        assert succ.shape == (n, k)
        for p in range(n):
            assert len(set(succ[p].tolist())) == k and p not in succ[p]
        G = nx.DiGraph((p, int(q)) for p in range(n) for q in succ[p])
        assert G.number_of_nodes() == n and nx.is_strongly_connected(G)


def test_random_graph_walk_follows_edges_and_observations_follow_places():
    w = RandomGraphWorld(n_places=25, out_degree=3, n_symbols=8, seed=2)
    tr = walk(w, 3000)
    assert np.array_equal(tr.places[1:], w.successors[tr.places[:-1], tr.actions[:-1]])
    assert np.array_equal(tr.observations, np.eye(8)[w.place_symbols[tr.places]])
    assert np.array_equal(tr.positions, w.place_positions[tr.places])
    assert set(np.unique(tr.places).tolist()) == set(range(25))
    assert tr.action_names == ["edge 0", "edge 1", "edge 2"]
    assert np.array_equal(np.unique(w.place_symbols), np.arange(8))
    G = w.to_networkx()
    assert all(G.edges[p, int(w.successors[p, a])]["action"] == a for p in range(25) for a in range(3))


def test_random_graph_with_one_out_edge_is_a_single_cycle():
    w = RandomGraphWorld(n_places=7, out_degree=1, n_symbols=3, seed=5)
    tr = walk(w, 15)
    assert sorted(tr.places[:7].tolist()) == list(range(7))  # every place once per lap
    assert np.array_equal(tr.places[7:14], tr.places[:7])


def test_random_graph_same_seed_same_world_and_trajectory():
    a, b, c = RandomGraphWorld(seed=4), RandomGraphWorld(seed=4), RandomGraphWorld(seed=5)
    assert np.array_equal(a.successors, b.successors) and np.array_equal(a.place_positions, b.place_positions)
    assert not np.array_equal(a.successors, c.successors)
    ta, tb, tc = walk(a, 400, 1), walk(b, 400, 1), walk(a, 400, 2)
    assert np.array_equal(ta.places, tb.places) and np.array_equal(ta.actions, tb.actions)
    assert not np.array_equal(ta.places, tc.places)


def test_random_graph_circular_layout_is_a_circle():
    w = RandomGraphWorld(n_places=10, out_degree=2, n_symbols=4, layout="circular")
    P = w.place_positions
    r = np.linalg.norm(P - P.mean(axis=0), axis=1)
    assert np.allclose(r, r[0], rtol=1e-6)


@pytest.mark.parametrize("kwargs, word", [
    (dict(n_places=1), "n_places"), (dict(n_places=5, out_degree=5), "out_degree"),
    (dict(out_degree=0), "out_degree"), (dict(n_places=5, n_symbols=6), "n_symbols"),
    (dict(layout="grid"), "layout"), (dict(obs_dim=-3), "obs_dim"),
    (dict(extra_actions=["x"]), "extra actions"),
])
def test_random_graph_bad_arguments(kwargs, word):
    with pytest.raises(ValueError, match=word):
        RandomGraphWorld(**kwargs)


def test_simulate_rejects_bad_input():
    for w in (GridRoom(), RandomGraphWorld()):
        with pytest.raises(ValueError, match="n_steps"):
            walk(w, 0)

        class Bad:
            def choose(self, mask, rng):
                return len(mask)

        with pytest.raises(ValueError, match="not executable"):
            w.simulate(5, Bad(), np.random.default_rng(0))
        with pytest.raises(ValueError, match="got NoneType; topomap.worlds.RandomExplorer"):
            w.simulate(5, None, np.random.default_rng(0))


# ------------------------------------------------------------------ minigrid

needs_minigrid = pytest.mark.skipif(importlib.util.find_spec("minigrid") is None,
                                    reason='needs the optional minigrid package')
DIR_VEC = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])


@pytest.fixture(scope="module")
def empty8():
    return MiniGridWorld("MiniGrid-Empty-8x8-v0", seed=0)


@pytest.fixture(scope="module")
def empty8_walk(empty8):
    return walk(empty8, 3000)


@needs_minigrid
def test_minigrid_empty_has_the_places_worked_out_by_hand(empty8):
    # 6 x 6 free cells inside the wall, minus the goal cell (never entered), times 4 headings
    assert empty8.width == empty8.height == 8
    assert empty8.start_pose == (1, 1, 0)
    places = empty8.reachable_places()
    assert places.size == (36 - 1) * 4
    x, y, d = empty8.pose_of(places)
    assert x.min() == y.min() == 1 and x.max() == y.max() == 6
    assert not np.any((x == 6) & (y == 6))


@needs_minigrid
def test_minigrid_moves_follow_minigrid_rules_and_respect_walls(empty8, empty8_walk):
    tr = empty8_walk
    x, y, d = empty8.pose_of(tr.places)
    kinds = empty8.grid_encoding[x, y, 0]
    assert np.all(kinds == 1)  # always on an empty cell (1 = empty; walls are 2, the goal 8)
    a = tr.actions[:-1]
    dx, dy, dd = np.diff(x), np.diff(y), np.diff(d)
    turn = a < 2
    assert np.all((dx[turn] == 0) & (dy[turn] == 0))
    assert np.all(dd[a == 0] % 4 == 3) and np.all(dd[a == 1] % 4 == 1)
    fwd = a == 2
    assert fwd.sum() > 500
    assert np.array_equal(np.column_stack([dx, dy])[fwd], DIR_VEC[d[:-1][fwd]])
    assert np.all(dd[fwd] == 0)
    assert set(np.unique(tr.places)) <= set(empty8.reachable_places().tolist())
    assert tr.lengths is None and tr.action_names == ["left", "right", "forward"]


@needs_minigrid
def test_minigrid_forward_offered_exactly_when_the_cell_ahead_is_free(empty8):
    rec = Recorder()
    tr = empty8.simulate(1500, rec, np.random.default_rng(3))
    assert len(rec.masks) == 1500
    x, y, d = empty8.pose_of(tr.places)
    ahead = empty8.grid_encoding[x + DIR_VEC[d, 0], y + DIR_VEC[d, 1], 0]
    masks = np.array(rec.masks)
    assert np.all(masks[:, :2])
    assert np.array_equal(masks[:, 2], ahead == 1)
    # the view agrees: the cell just ahead of the agent is view cell (3, 5)
    view = tr.observations.reshape(-1, 7, 7, 3)
    assert np.array_equal(view[:, 3, 5, 1] == 1, ahead == 2)
    assert np.all(view[:, 3, 6, 0] == 1)  # the agent's own cell is seen as open


@needs_minigrid
def test_minigrid_observation_is_a_function_of_the_pose(empty8, empty8_walk):
    tr = empty8_walk
    X = tr.observations
    assert X.shape == (3000, 147) and set(np.unique(X)) <= {0.0, 1.0}
    assert np.all(X.reshape(-1, 49, 3).sum(axis=2) <= 1)  # at most one channel per view cell
    for p in np.unique(tr.places):
        rows = X[tr.places == p]
        assert np.array_equal(rows, np.broadcast_to(rows[0], rows.shape))
    for p in np.unique(tr.places)[::7]:  # and it is MiniGrid's own view of that pose
        assert np.array_equal(empty8.observe(p), X[np.argmax(tr.places == p)])
    # aliasing: fewer distinct views than poses
    assert len(np.unique(X, axis=0)) < len(np.unique(tr.places))
    x, y, d = empty8.pose_of(tr.places)
    assert np.allclose(tr.positions, np.column_stack([
        x + 0.5 + 0.25 * DIR_VEC[d, 0], 8 - y - 0.5 - 0.25 * DIR_VEC[d, 1]]))


def test_encode_view_by_hand():
    img = np.zeros((1, 7, 7, 3), dtype=np.uint8)  # all unseen
    img[0, 0, 0, 0] = 2   # wall
    img[0, 1, 0, 0] = 1   # empty
    img[0, 2, 0, 0] = 3   # floor
    img[0, 3, 0, 0] = 8   # goal
    img[0, 4, 0, 0] = 4   # door
    v = encode_view(img).reshape(7, 7, 3)
    assert v[0, 0].tolist() == [0, 1, 0] and v[1, 0].tolist() == [1, 0, 0]
    assert v[2, 0].tolist() == [1, 0, 0] and v[3, 0].tolist() == [0, 0, 1]
    assert v[4, 0].tolist() == [0, 0, 1] and v.sum() == 5


@needs_minigrid
def test_minigrid_same_seed_same_trajectory(empty8, empty8_walk):
    again = walk(empty8, 3000)
    assert np.array_equal(again.places, empty8_walk.places)
    assert np.array_equal(again.observations, empty8_walk.observations)
    other = walk(empty8, 300, seed=1)
    assert not np.array_equal(other.actions, again.actions[:300])


@needs_minigrid
def test_minigrid_fourrooms_seed_fixes_the_layout():
    a = MiniGridWorld("MiniGrid-FourRooms-v0", seed=2)
    b = MiniGridWorld("MiniGrid-FourRooms-v0", seed=2)
    c = MiniGridWorld("MiniGrid-FourRooms-v0", seed=3)
    assert np.array_equal(a.grid_encoding, b.grid_encoding) and a.start_pose == b.start_pose
    assert not (np.array_equal(a.grid_encoding, c.grid_encoding) and a.start_pose == c.start_pose)
    ta, tb = walk(a, 2000), walk(b, 2000)
    assert np.array_equal(ta.places, tb.places)
    x, y, _ = a.pose_of(ta.places)
    assert np.all(a.grid_encoding[x, y, 0] == 1)  # never in a wall or on the goal
    # every free cell of the four rooms can be reached, facing any way
    free = int(np.sum(a.grid_encoding[:, :, 0] == 1))
    assert a.reachable_places().size == 4 * free


@needs_minigrid
def test_minigrid_bad_ids():
    with pytest.raises(ValueError, match="MiniGrid-Nope-v0"):
        MiniGridWorld("MiniGrid-Nope-v0")
    with pytest.raises(ValueError, match="not a MiniGrid environment"):
        MiniGridWorld("CartPole-v1")


def test_minigrid_refuses_extra_actions_and_names_the_missing_package(monkeypatch):
    with pytest.raises(ValueError, match="extra actions"):
        MiniGridWorld(extra_actions=["x"])
    monkeypatch.setitem(sys.modules, "minigrid", None)
    with pytest.raises(MissingDependencyError, match=r"pip install \"topomap\[minigrid\]\""):
        MiniGridWorld()


# ------------------------------------------------------------------ the app, end to end




@pytest.mark.parametrize("overrides, n_places", [
    (["env=gridroom", "env.width=4", "env.height=3", "clusters.ns=3", "stop.n_states=12"], 12),
    (["env=random_graph", "env.n_places=12", "env.n_symbols=6", "clusters.ns=6",
      "stop.n_states=12"], 12),
    pytest.param(["env=minigrid", "env.name=MiniGrid-Empty-5x5-v0", "clusters.ns=10",
                  "stop.n_states=20"], None, marks=needs_minigrid),
])
def test_every_world_runs_end_to_end(tmp_path, overrides, n_places, make_cfg):
    cfg = make_cfg(["data.n_steps=400", "output.progress=false", *overrides])
    results = run(cfg, tmp_path)
    for name in [*OUTPUT_FILES, *FIGURE_FILES]:
        assert (tmp_path / name).is_file(), name
    gt = results["ground_truth"]
    assert set(gt["final"]) >= {"ari", "nmi", "purity"} and set(gt["phase1"]) >= {"ari", "nmi"}
    assert results["n_states"]["final"] == cfg.stop.n_states
    states = np.loadtxt(tmp_path / "states.csv", delimiter=",", skiprows=1, dtype=int)
    if n_places is not None:
        assert set(states[:, 3].tolist()) <= set(range(n_places))




@needs_minigrid
@pytest.mark.parametrize("env_id", CHECKED_ENVS)
def test_minigrid_checked_environments(env_id):
    w = MiniGridWorld(env_id, seed=0)
    tr = walk(w, 800)
    x, y, d = w.pose_of(tr.places)
    kind, state = w.grid_encoding[x, y, 0], w.grid_encoding[x, y, 2]
    # only on empty or floor cells, or in an open door (door = 4, state 0 = open)
    assert np.all((kind == 1) | (kind == 3) | ((kind == 4) & (state == 0)))
    a = tr.actions[:-1]
    fwd = a == 2
    step = np.column_stack([np.diff(x), np.diff(y)])
    assert np.all(step[~fwd] == 0) and np.array_equal(step[fwd], DIR_VEC[d[:-1][fwd]])
    assert np.all(np.diff(d)[a == 0] % 4 == 3) and np.all(np.diff(d)[a == 1] % 4 == 1)
    assert tr.lengths is None  # no episode ended
    assert set(np.unique(tr.places).tolist()) <= set(w.reachable_places().tolist())
    for p in np.unique(tr.places)[::5]:
        rows = tr.observations[tr.places == p]
        assert np.array_equal(rows, np.broadcast_to(w.observe(p), rows.shape))
