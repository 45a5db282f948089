"""A map file's counts are those of one walk: a transition listed twice, or counted more often
than the states' own counts allow, is refused with one line naming the field; every map the
learner makes (fit, refined, sized, partial_fit) satisfies the same checks and loads."""

import json
import math

import numpy as np
import pytest
from worlds import ring

from topomap import MapLearner, TopologicalMap
from topomap.core.map.files import check_counts, finite_json
from topomap.worlds import GridRoom, RandomExplorer


def learned_map_dict() -> dict:
    """A map learned on two episodes of a ring, as the JSON object ``save`` writes."""
    X, u, _ = ring(n_steps=300)
    m = MapLearner(n_clusters=5, n_states=6).fit(X, u, lengths=[120, 180]).map_
    return json.loads(json.dumps(m.to_dict()))


def refused(tmp_path, d, match):
    """Loading ``d`` from a file fails with one line naming the file and matching ``match``."""
    path = tmp_path / "map.json"
    path.write_text(json.dumps(d))
    with pytest.raises(ValueError, match=match) as err:
        TopologicalMap.load(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_a_learned_map_passes_and_its_counts_are_tight():
    d = learned_map_dict()
    TopologicalMap.from_dict(d)
    # two episodes: their two last steps leave by no transition
    assert sum(st["count"] for st in d["states"]) - sum(t[3] for t in d["transitions"]) == 2


def test_every_transition_repeated_2000_times_is_refused(tmp_path):
    d = learned_map_dict()
    rows = d["transitions"]
    d["transitions"] = [row for row in rows for _ in range(2000)]
    x, a, y, _ = rows[0]
    refused(tmp_path, d, rf"transitions\[1\] repeats \(state, action, next_state\) = "
                         rf"\({x}, {a}, {y}\) of transitions\[0\]; each is listed once")
    d["transitions"] = rows * 2000  # the whole list again and again
    refused(tmp_path, d, rf"transitions\[{len(rows)}\] repeats .* of transitions\[0\]")


def test_a_duplicate_with_the_same_total_is_still_refused(tmp_path):
    """Splitting one entry's count over two entries keeps every sum: only the repeat shows."""
    d = learned_map_dict()
    x, a, y, n = d["transitions"][0]
    assert n >= 2
    d["transitions"][0] = [x, a, y, n - 1]
    d["transitions"].append([x, a, y, 1])
    refused(tmp_path, d, rf"transitions\[{len(d['transitions']) - 1}\] repeats")


def test_a_count_no_state_can_hold_is_refused(tmp_path):
    d = learned_map_dict()
    x, a, y, n = d["transitions"][2]
    d["transitions"][2] = [x, a, y, 10**15]
    held = d["states"][x]["action_counts"][a]
    leaving = 10**15 + sum(t[3] for t in d["transitions"] if t[:2] == [x, a] and t[2] != y)
    refused(tmp_path, d, rf"transitions leave state {x} by action {a} {leaving} times but "
                         rf"states\[{x}\]\.action_counts\[{a}\] is {held}: each leaves from a "
                         "step counted there")
    d["transitions"][2] = [x, a, y, 1e15]  # the same as a JSON float: not a count at all
    refused(tmp_path, d, r"transitions\[2\] must be \[state, action, next_state, count\]")


def test_counts_that_disagree_with_the_states_own_are_refused(tmp_path):
    d = learned_map_dict()
    d["states"][3]["count"] += 1
    n = d["states"][3]["count"]
    refused(tmp_path, d, rf"states\[3\]\.action_counts sum to {n - 1} but states\[3\]\.count "
                         rf"is {n}: every step takes one action")
    # more arrivals in y than y's steps, every state's own sums kept: x's action a (and so its
    # count) grows with the transition x -a-> y
    d = learned_map_dict()
    x, a, y, n = d["transitions"][0]
    extra = d["states"][y]["count"] + 1
    d["transitions"][0][3] += extra
    d["states"][x]["action_counts"][a] += extra
    d["states"][x]["count"] += extra
    arriving = sum(t[3] for t in d["transitions"] if t[2] == y)
    refused(tmp_path, d, rf"transitions arrive in state {y} {arriving} times but "
                         rf"states\[{y}\]\.count is {d['states'][y]['count']}")


def test_sums_beyond_int64_cannot_wrap_around():
    """1100 transitions of 2**53 each arrive in state 0: 1.07 * 2**63, which an int64 sum
    wraps to a negative number that every count would hold."""
    S = 1100
    trans = np.zeros((S, 1, S), dtype=np.int64)
    trans[:, 0, 0] = 2**53
    big = np.full(S, 2**53)
    m = TopologicalMap(np.arange(S), [-1] * S, [-1] * S, np.zeros((S, 1)), np.ones((S, 1)), big,
                       big[:, None], trans)
    with pytest.raises(ValueError, match="transitions arrive in state 0 .* but states"):
        check_counts(m)


def test_save_refuses_counts_load_would_refuse_and_writes_nothing(tmp_path):
    trans = np.zeros((2, 1, 2), dtype=int)
    trans[0, 0, 1] = 5  # five transitions out of a state seen twice
    m = TopologicalMap([0, 1], [-1, -1], [-1, -1], np.zeros((2, 1)), np.ones((2, 1)), [2, 5],
                       [[2], [5]], trans)
    with pytest.raises(ValueError, match=r"^map file .*map.json not written: transitions leave "
                                         r"state 0 by action 0 5 times"):
        m.save(tmp_path / "map.json")
    assert list(tmp_path.iterdir()) == []


def loads_as_saved(m, folder) -> bool:
    """``m`` saved, loaded and saved again gives the same bytes."""
    first = m.save(folder / "a.json")
    return TopologicalMap.load(first).save(folder / "b.json").read_bytes() == first.read_bytes()


def room_walk(n_steps, seed):
    room = GridRoom(width=4, height=3, n_symbols=3)
    return room.simulate(n_steps, RandomExplorer(), np.random.default_rng(seed))


@pytest.mark.parametrize("settings", [
    {}, {"refine": "em"}, {"refine": "cscg"}, {"n_states": "auto"},
], ids=["split", "em", "cscg", "auto"])
def test_every_map_the_learner_fits_passes_and_loads(settings, tmp_path):
    t = room_walk(1200, seed=1)
    gds = np.where(t.places == 0, 0, -1)  # a GDS at one cell
    learner = MapLearner(**{"n_clusters": 3, "n_states": 12, **settings}).fit(
        t.observations, t.actions, gds=gds, lengths=[500, 700], n_actions=t.n_actions)
    for m in (learner.map_, learner.map_phase1_, learner.map_split_):
        check_counts(m)
        assert loads_as_saved(m, tmp_path)


def test_every_map_partial_fit_makes_passes_and_loads(tmp_path):
    """Chunks decoded between passes, passes over a window shorter than the walk, episodes cut
    by new_episode, and GDS steps: after every call the map's counts are a walk's."""
    t = room_walk(2600, seed=2)
    gds = np.where(t.places == 5, 0, -1)
    learner = MapLearner(3, 12, window=900, refit_every=700)
    seen = 0
    for k, chunk in enumerate([250, 250, 300, 400, 150, 600, 650]):
        sl = slice(seen, seen + chunk)
        learner.partial_fit(t.observations[sl], t.actions[sl], gds[sl], new_episode=k == 4,
                            n_actions=t.n_actions)
        seen += chunk
        check_counts(learner.map_)
    assert learner.online_["n_passes"] >= 3
    assert loads_as_saved(learner.map_, tmp_path)


def test_a_map_file_is_strict_json_where_its_info_holds_a_number_that_is_not_finite(tmp_path):
    # a measured ratio that is infinite (no point reflection found) is written as null, so
    # strict JSON readers read the file; finite numbers keep their value
    from topomap.app.run.outputs import write_json

    assert finite_json({"a": [1.5, math.inf, {"b": -math.inf, "c": math.nan}], "d": "x"}) == \
        {"a": [1.5, None, {"b": None, "c": None}], "d": "x"}
    rng = np.random.default_rng(0)
    X, u = rng.normal(size=(60, 2)), rng.integers(0, 2, 60)
    m = TopologicalMap.from_labels(X, u, np.arange(60) % 3, state_symbol=np.arange(3),
                                   state_gds=np.full(3, -1), state_parent=np.full(3, -1),
                                   n_actions=2, info={"symmetry": {"ratio": math.inf}, "k": 2.5})
    text = m.save(tmp_path / "map.json").read_text()
    strict = json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert strict["info"]["symmetry"] == {"ratio": None} and strict["info"]["k"] == 2.5
    write_json(tmp_path / "metrics.json", {"ratio": np.float64(np.inf), "n": np.int64(3)})
    assert json.loads((tmp_path / "metrics.json").read_text()) == {"ratio": None, "n": 3}
