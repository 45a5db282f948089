"""Mapping while exploring: explorers see what the robot sees, the map is judged as it grows."""

import copy
import json
from types import SimpleNamespace

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap import MapLearner, TopologicalMap
from topomap.app.run.experiment import run
from topomap.worlds import (active_explorer, GridRoom, HistoryExplorer, NoNoise, PlanExplorer,
                            RandomExplorer, View)
from topomap.worlds.explorers.history import symbol_means
from topomap.worlds.explorers.plan import novelty_values
from topomap.worlds.mapping import heldout_judge, map_while_exploring, quality_curve


class Spy:
    """Records every call a world makes on its explorer; walks at random."""

    def __init__(self):
        self.views = []

    def see(self, view):
        self.views.append(view)

    def choose(self, executable, rng):
        idx = np.flatnonzero(executable)
        return int(idx[rng.integers(idx.size)])


def test_an_explorer_is_handed_a_view_without_the_place():
    room = GridRoom(5, 4, 3)
    spy = Spy()
    traj = room.simulate(50, spy, np.random.default_rng(0))
    assert len(spy.views) == 50
    assert all(type(v) is View for v in spy.views)
    assert View._fields == ("observation", "executable", "gds", "t")
    # the view is what the sensor gives at the step, not a copy of the world's state
    assert np.array_equal(np.array([v.observation for v in spy.views]), traj.observations)
    assert [v.t for v in spy.views] == list(range(50))


def relabelled(room, perm):
    """The same room with its places renamed: place p becomes perm[p]."""
    other = copy.deepcopy(room)
    inv = np.argsort(perm)
    succ = room.successors[inv]
    other.successors = np.where(succ >= 0, perm[np.maximum(succ, 0)], -1)
    other.place_symbols = room.place_symbols[inv]
    other.place_positions = room.place_positions[inv]
    other.cells = room.cells[inv]
    return other


def test_the_active_explorer_does_not_depend_on_the_names_of_places():
    # renaming the places (keeping the start) leaves every observation and mask the same: an
    # explorer that never reads the place takes the same actions
    room = GridRoom(5, 4, 3)
    start = int(np.random.default_rng(3).integers(room.successors.shape[0]))
    perm = np.random.default_rng(9).permutation(room.successors.shape[0])
    where = int(np.flatnonzero(perm == start)[0])
    perm[[start, where]] = perm[[where, start]]
    assert perm[start] == start
    other = relabelled(room, perm)
    runs = []
    for world in (room, other):
        learner = MapLearner(3, 20, refit_every=200)
        traj, _ = map_while_exploring(world, 600, active_explorer(update_every=100), learner,
                                      NoNoise(), np.random.default_rng(3),
                                      np.random.default_rng(4), update_every=100)
        runs.append(traj)
    assert not np.array_equal(runs[0].places, runs[1].places)  # the names did change
    assert np.array_equal(perm[runs[0].places], runs[1].places)
    assert np.array_equal(runs[0].actions, runs[1].actions)


@pytest.mark.parametrize("make", [HistoryExplorer, PlanExplorer])
def test_a_map_explorer_walks_at_random_until_a_map_exists(make):
    room = GridRoom(5, 4, 3)
    a = room.simulate(100, make(), np.random.default_rng(5))
    b = room.simulate(100, RandomExplorer(), np.random.default_rng(5))
    assert np.array_equal(a.actions, b.actions)


def test_explorer_active_is_the_history_policy_unless_the_route_is_plan():
    history = active_explorer(update_every=7, context=2, epsilon=0.25)
    assert type(history) is HistoryExplorer
    assert (history.update_every, history.context, history.epsilon) == (7, 2, 0.25)
    plan = active_explorer(update_every=7, route="plan", gamma=0.5, horizon=4, epsilon=0.25)
    assert type(plan) is PlanExplorer
    assert (plan.update_every, plan.gamma, plan.horizon, plan.epsilon) == (7, 0.5, 4, 0.25)


def fitted(n_symbols=3):
    room = GridRoom(4, 3, n_symbols)
    traj = room.simulate(400, RandomExplorer(), np.random.default_rng(0))
    return room, MapLearner(n_symbols, 12).fit(traj.observations, traj.actions, n_actions=4)


def test_a_history_state_reads_a_view_through_the_learners_symbols():
    # the symbols are the learner's: symbol k's mean is the mean of the steps phase 1 gave k, and
    # a place's view has the symbol the learner gave the steps at that place
    room, learner = fitted()
    traj = room.simulate(400, RandomExplorer(), np.random.default_rng(0))
    X, sym = traj.observations, learner.labels_phase1_
    means = symbol_means(learner.map_)
    assert np.allclose(means, [X[sym == k].mean(0) for k in range(3)])
    ex = HistoryExplorer()
    ex.update(learner)
    for p in np.unique(traj.places):
        view = View(room.observe(p), room.executable_mask(p), -1, 0)
        assert {ex.symbol_of(view)} == set(sym[traj.places == p].tolist())
    assert ex.symbol_of(View(room.observe(0), room.executable_mask(0), 4, 0)) == -5  # a GDS


def test_the_history_policy_balances_the_actions_taken_from_a_state():
    # context 0: the state is the current symbol alone.  Seen at the same symbol again and again
    # with two executable actions, the least-taken one is taken: after 2k choices, k each.
    room, learner = fitted()
    ex = HistoryExplorer(context=0)
    ex.update(learner)
    view = View(room.observe(0), np.array([True, True, False, False]), -1, 0)
    rng = np.random.default_rng(0)
    picks = []
    for t in range(10):
        ex.see(view._replace(t=t))
        picks.append(ex.choose(view.executable, rng))
        assert abs(picks.count(0) - picks.count(1)) <= 1
    assert picks.count(0) == picks.count(1) == 5


def test_the_history_policy_tells_states_apart_by_the_steps_before():
    # context 1: symbol B reached from A by action 0 (state X) and by action 1 (state Y) are two
    # states with their own counts.  Going A -0-> B, A -1-> B, A -0-> B, A -1-> B (the moves
    # out of A forced by the mask), the second choice in X differs from the first in X, and the
    # second in Y from the first in Y, whatever was chosen in the other state.
    room, learner = fitted()
    pa, pb = (int(np.flatnonzero(room.place_symbols == k)[0]) for k in (0, 1))
    ex = HistoryExplorer(context=1)
    ex.update(learner)
    both = np.array([True, True, False, False])
    rng = np.random.default_rng(2)
    picks = {0: [], 1: []}
    for t, forced in enumerate([0, 1, 0, 1]):
        only = np.zeros(4, bool)
        only[forced] = True
        ex.see(View(room.observe(pa), only, -1, 2 * t))
        assert ex.choose(only, rng) == forced
        ex.see(View(room.observe(pb), both, -1, 2 * t + 1))
        picks[forced].append(ex.choose(both, rng))
    assert picks[0][0] != picks[0][1]
    assert picks[1][0] != picks[1][1]


def ring_map():
    """The map of a ring of three places, 0 -> 1 -> 2 -> 0 by action 0 and back by action 1, each
    showing its own symbol: each action taken 40 times from places 0 and 1, twice from place 2
    (the least known)."""
    n = np.array([[40, 40], [40, 40], [2, 2]])
    ring = np.array([[1, 2], [2, 0], [0, 1]])
    trans = np.zeros((3, 2, 3), dtype=np.int64)
    for s in range(3):
        for a in range(2):
            trans[s, a, ring[s, a]] = n[s, a]
    return TopologicalMap(np.arange(3), np.full(3, -1), np.full(3, -1), np.eye(3),
                          np.full((3, 3), 0.01), n.sum(1), n, trans)


def test_novelty_values_carry_the_novelty_of_where_an_action_leads():
    # an action taken n times is worth 1/sqrt(n+1), plus gamma times the best worth where it
    # leads: from place 0, action 0 leads to place 1 (worth 1/sqrt(41)), action 1 to place 2
    # (worth 1/sqrt(3))
    m = ring_map()
    counts, opened = m.action_counts.astype(float), np.zeros((3, 2), bool)
    assert np.allclose(novelty_values(counts, opened, m.transition_probs, 0.5, 0),
                       1 / np.sqrt(counts + 1))
    q = novelty_values(counts, opened, m.transition_probs, 0.5, 1)
    assert q[0] == pytest.approx([1 / np.sqrt(41) + 0.5 / np.sqrt(41),
                                  1 / np.sqrt(41) + 0.5 / np.sqrt(3)])
    assert q[1] == pytest.approx([1 / np.sqrt(41) + 0.5 / np.sqrt(3),
                                  1 / np.sqrt(41) + 0.5 / np.sqrt(41)])


@pytest.mark.parametrize("place, towards", [(0, 1), (1, 0)])
def test_the_plan_policy_walks_towards_the_least_known_place(place, towards):
    # from places 0 and 1 both actions were taken as often: the plan takes the one leading to
    # place 2, whose actions were taken least (action 1 from place 0, action 0 from place 1)
    ex = PlanExplorer(horizon=1)
    ex.update(SimpleNamespace(map_=ring_map()))
    mask = np.ones(2, bool)
    ex.see(View(np.eye(3)[place], mask, -1, 0))
    assert ex.choose(mask, np.random.default_rng(0)) == towards


def test_the_plan_policy_goes_to_the_action_never_taken():
    # a room whose map has states where some actions were never taken: with the mask saying all
    # four are executable, the planner's one-step novelty picks a never-taken one
    room, learner = fitted(n_symbols=12)
    ex = PlanExplorer(horizon=1)
    ex.update(learner)
    mask = np.ones(4, bool)
    ex.see(View(room.observe(0), mask, -1, 0))
    s = int(np.argmax(ex._belief))
    never = np.flatnonzero(learner.map_.action_counts[s] == 0)
    pick = ex.choose(mask, np.random.default_rng(0))
    assert never.size and pick in never


def walk_with_a_map(ex, steps=40):
    """See and choose ``steps`` times in a 4 x 3 room with a map; the masks handed over are
    read-only (writing to one raises), and are returned with copies made before each choice."""
    room, learner = fitted()
    ex.update(learner)
    rng, p, handed = np.random.default_rng(1), 0, []
    for t in range(steps):
        mask = room.executable_mask(p)
        mask.flags.writeable = False
        ex.see(View(room.observe(p), mask, -1, t))
        before = mask.copy()
        a = ex.choose(mask, rng)
        handed.append((before, mask))
        p = room.step(p, a)
    return handed


@pytest.mark.parametrize("make", [HistoryExplorer, PlanExplorer])
def test_choosing_leaves_the_mask_as_it_was(make):
    for before, after in walk_with_a_map(make(epsilon=0.2)):
        assert np.array_equal(before, after)


@pytest.mark.parametrize("make", [HistoryExplorer, PlanExplorer])
def test_an_explorer_has_all_its_state_from_its_making(make):
    ex = make()
    born = set(vars(ex))
    walk_with_a_map(ex)
    assert set(vars(ex)) == born


def test_the_plan_policy_plans_once_a_step(monkeypatch):
    from topomap.worlds.explorers import plan

    calls = []

    def counted(*args):
        calls.append(1)
        return novelty_values(*args)

    monkeypatch.setattr(plan, "novelty_values", counted)
    walk_with_a_map(PlanExplorer(), steps=40)
    assert 0 < len(calls) <= 40


def test_a_map_judged_on_a_walk_it_never_learned_from():
    room = GridRoom(4, 3, 12)   # no aliasing: a map of 12 states is the room
    learned = room.simulate(2000, RandomExplorer(), np.random.default_rng(0))
    judging = room.simulate(500, RandomExplorer(), np.random.default_rng(1))
    m = MapLearner(12, 12).fit(learned.observations, learned.actions, n_actions=4).map_
    assert heldout_judge(judging)(m) == {"heldout_ari": 1.0}
    one = MapLearner(1, 1).fit(learned.observations, learned.actions, n_actions=4).map_
    assert heldout_judge(judging)(one)["heldout_ari"] == 0.0


def test_the_quality_curve_follows_the_walk():
    room = GridRoom(4, 3, 12)
    learner = MapLearner(12, 12, refit_every=100)
    judging = room.simulate(300, RandomExplorer(), np.random.default_rng(1))
    traj, walk = map_while_exploring(room, 1000, RandomExplorer(), learner, NoNoise(),
                                     np.random.default_rng(0), np.random.default_rng(1),
                                     update_every=250, judge=heldout_judge(judging))
    walk.flush()
    curve = quality_curve(walk, traj.places)
    assert [c["steps"] for c in curve] == [250, 500, 750, 1000]
    assert curve[-1]["ari"] == pytest.approx(adjusted_rand_score(traj.places, learner.labels_))
    assert curve[-1]["heldout_ari"] == 1.0
    assert all(c["n_states"] == 12 for c in curve)


def test_a_walk_maps_at_the_explorers_pace_unless_told_otherwise():
    room = GridRoom(4, 3, 12)
    args = (MapLearner(12, 12), NoNoise(), np.random.default_rng(0), np.random.default_rng(1))
    _, walk = map_while_exploring(room, 300, HistoryExplorer(update_every=120), *args)
    assert [c[0] for c in walk.checkpoints] == [120, 240]
    _, walk = map_while_exploring(room, 300, HistoryExplorer(update_every=120),
                                  MapLearner(12, 12), *args[1:], update_every=100)
    assert [c[0] for c in walk.checkpoints] == [100, 200, 300]
    with pytest.raises(ValueError, match="update_every"):  # a random walk has no pace of its own
        map_while_exploring(room, 300, RandomExplorer(), *args)


def test_explorer_active_from_the_command_line(tmp_path, make_cfg):
    cfg = make_cfg(["env=gridroom", "env.width=4", "env.height=3", "env.n_symbols=3",
                    "clusters.ns=3", "stop.n_states=12", "explorer=active",
                    "explorer.update_every=200", "data.n_steps=800", "output.progress=false"])
    results = run(cfg, tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    mapping = metrics["mapping"]
    assert [c["steps"] for c in mapping["curve"]] == [200, 400, 600, 800]
    assert all(0.0 <= c["heldout_ari"] <= 1.0 for c in mapping["curve"])
    assert mapping["batch_ari"] == pytest.approx(results["ground_truth"]["final"]["ari"])
    assert mapping["explorer"].startswith("HistoryExplorer(")
    assert (tmp_path / "fig_mapping.png").is_file()
    # the curve's last ARI is that of the online map's labels of the steps walked
    states = np.loadtxt(tmp_path / "states.csv", delimiter=",", skiprows=1, dtype=int)
    assert len(states) == 800


def test_a_random_run_without_a_curve_writes_no_mapping(tmp_path, make_cfg):
    cfg = make_cfg(["env=gridroom", "env.width=4", "env.height=3", "clusters.ns=3",
                    "stop.n_states=12", "data.n_steps=300", "output.progress=false"])
    run(cfg, tmp_path)
    assert json.loads((tmp_path / "metrics.json").read_text())["mapping"] is None
    assert not (tmp_path / "fig_mapping.png").exists()


@pytest.mark.parametrize("kw, key", [({"gamma": 1.5}, "gamma"), ({"epsilon": -0.1}, "epsilon"),
                                     ({"update_every": 0}, "update_every"), ({"horizon": 0}, "horizon"),
                                     ({"route": "greedy"}, "route"), ({"context": -1}, "context")])
def test_bad_explorer_settings_name_the_parameter(kw, key):
    with pytest.raises(ValueError, match=key):  # every setting, whichever the route
        active_explorer(**kw)
    with pytest.raises(ValueError, match=key):
        active_explorer(**kw, route="plan") if key != "route" else active_explorer(**kw)


@pytest.mark.parametrize("make, kw", [(HistoryExplorer, {"context": 1.5}),
                                      (HistoryExplorer, {"epsilon": 2}),
                                      (PlanExplorer, {"gamma": 0}), (PlanExplorer, {"horizon": -1}),
                                      (PlanExplorer, {"update_every": "often"})])
def test_bad_settings_of_either_policy_name_the_parameter(make, kw):
    with pytest.raises(ValueError, match=next(iter(kw))):
        make(**kw)


def test_data_curve_every_is_the_old_name_of_update_every(make_cfg):
    """``data.update_every`` is the explorer's name for the steps between map updates; the old
    key ``data.curve_every`` still composes and sets it, with a warning, and both at once are
    refused naming the old key."""
    from topomap.app.components.data import Simulate

    with pytest.warns(FutureWarning, match="data.curve_every was renamed data.update_every"):
        assert Simulate(n_steps=10, curve_every=5).update_every == 5
    with pytest.raises(ValueError, match="curve_every"):
        Simulate(n_steps=10, update_every=3, curve_every=5)
    assert Simulate(n_steps=10, update_every=7).update_every == 7
    cfg = make_cfg(["data.curve_every=250"])
    assert cfg.data.curve_every == 250 and cfg.data.update_every == 0
