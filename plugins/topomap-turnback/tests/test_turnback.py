import numpy as np

from topomap.worlds.office import OfficeWorld
from topomap.worlds.explorers import RandomExplorer
from topomap_turnback import TurnBack, topomap_world_actions


def test_hook_adds_the_action_to_the_office_only():
    (action,) = topomap_world_actions(world="office", params={})
    assert isinstance(action, TurnBack)
    assert topomap_world_actions(world="gridroom", params={}) == []


def test_turn_back_returns_to_the_previous_place_when_nothing_is_in_the_way():
    w = OfficeWorld(extra_actions=[TurnBack()], view_range=10.0)
    assert w.action_names[-1] == "turn back"
    traj = w.simulate(600, RandomExplorer(), np.random.default_rng(0))
    a = w.action_names.index("turn back")
    used = np.flatnonzero(traj.actions[:-1] == a)
    assert used.size > 10
    # it is only chosen where the previous place differs from the current one
    assert np.all(traj.places[used - 1] != traj.places[used])
    # and mostly (unless an object on the way stops it first) it arrives back there
    back = traj.places[used + 1] == traj.places[used - 1]
    assert back.mean() > 0.5
    first = TurnBack().is_executable(w, w.pose_at(*w.standing_point(0)))
    assert first is False  # no previous place at the start
