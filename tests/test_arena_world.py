"""The arena world: seeds, motion, actions read off the motion, recorded paths, sensors."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest

pytest.importorskip("ratinabox")

from topomap.core.data.rosbag import twist_action  # noqa: E402
from topomap.worlds.arena import (ArenaWorld, BoundaryVectorCells, CompassActions,  # noqa: E402
                                  ObjectVectorCells, RangeFinder, TurnActions, floorplan_from_dict)
from topomap.worlds.arena.kinematics import Motion  # noqa: E402
from topomap.worlds.explorers import active_explorer, RandomExplorer  # noqa: E402


def test_same_seed_same_trajectory_bytes_and_the_global_state_is_left_alone():
    def walk(seed):
        world = ArenaWorld(layout="two_rooms", sensor=RangeFinder(n_beams=8, max_range=3.0))
        return world.simulate(300, RandomExplorer(), np.random.default_rng(seed))

    np.random.seed(123)
    expected = np.random.random(3)
    np.random.seed(123)
    a, b, c = walk(7), walk(7), walk(8)
    assert np.array_equal(np.random.random(3), expected)  # as if no world had run
    for key in ("observations", "actions", "positions"):
        assert getattr(a, key).tobytes() == getattr(b, key).tobytes()
    assert not np.array_equal(a.positions, c.positions)
    assert a.observations.shape == (300, 8) and a.positions.shape == (300, 2)
    assert a.action_names == CompassActions.action_names


def test_two_worlds_interleaved_give_what_each_gives_alone():
    alone = ArenaWorld(layout="open").simulate(100, None, np.random.default_rng(1))
    w1, w2 = ArenaWorld(layout="open"), ArenaWorld(layout="four_rooms")
    w2.simulate(50, None, np.random.default_rng(5))
    again = w1.simulate(100, None, np.random.default_rng(1))
    assert np.array_equal(alone.positions, again.positions)


def test_motion_from_samples_on_a_square_by_hand():
    P = [[0, 0], [1, 0], [1, 0], [1, 1], [0, 1]]  # east, stand still, north, west
    m = Motion.from_samples(P, dt=0.5)
    assert np.allclose(m.velocity, [[2, 0], [0, 0], [0, 2], [-2, 0]])
    assert np.allclose(m.heading, [0, 0, 0, np.pi / 2])  # standing keeps the heading
    assert np.allclose(m.rotational_velocity, [0, 0, np.pi, np.pi])  # 90 degrees in 0.5 s
    assert np.allclose(m.times, [0, 0.5, 1.0, 1.5]) and len(m) == 4


def hand_motion(velocity, turn=None) -> Motion:
    v = np.asarray(velocity, dtype=float)
    w = np.zeros(len(v)) if turn is None else np.asarray(turn, dtype=float)
    return Motion(times=np.zeros(len(v)), positions=np.zeros_like(v), velocity=v,
                  heading=np.zeros(len(v)), rotational_velocity=w, dt=0.1)


def test_compass_actions_on_hand_made_velocities():
    a22, a23 = np.radians(22), np.radians(23)
    v = [[1, 0], [1, 1], [0, -1], [-1, -0.01], [0.01, 0], [np.cos(a22), np.sin(a22)],
         [np.cos(a23), np.sin(a23)], [0.3, -0.3]]
    names = [CompassActions.action_names[k] for k in CompassActions().actions(hand_motion(v))]
    assert names == ["east", "northeast", "south", "west", "stop", "east", "northeast",
                     "southeast"]


def test_turn_actions_follow_the_twist_rule():
    speed = [0.5, 0.5, 0.1, 0.01, 0.0, 0.03]
    turn = [1.0, -1.0, 0.2, 0.0, 0.6, -0.49]
    rule = TurnActions(linear_threshold=0.02, angular_threshold=0.5)
    got = [rule.action_names[k] for k in rule.actions(hand_motion([[s, 0] for s in speed], turn))]
    assert got == ["turn_left", "turn_right", "forward", "stop", "turn_left", "forward"]
    assert got == [twist_action(s, w, 0.02, 0.5) for s, w in zip(speed, turn)]


def test_the_arena_refuses_an_explorer_that_would_steer():
    world = ArenaWorld(layout="open")
    with pytest.raises(ValueError, match="cannot steer the arena"):
        world.simulate(10, active_explorer(), np.random.default_rng(0))


@pytest.mark.parametrize("kwargs, match", [
    ({"dt": 0}, "dt must be a positive number"),
    ({"thigmotaxis": 2.0}, r"thigmotaxis must be in \[0, 1\]"),
    ({"layout": "maze"}, "layout='maze' is neither a built-in layout"),
    ({"sensor": "sonar"}, "sensor must be one of range, bvc, ovc"),
    ({"actions": "keys"}, "actions must be one of compass, turns"),
    ({"path": "rat.txt"}, "neither a recorded path of ratinabox"),
    ({"extra_actions": ["jump"]}, "fixed set of actions"),
])
def test_bad_arguments_name_the_parameter(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ArenaWorld(**kwargs)


def test_a_recorded_path_is_resampled_through_its_samples(tmp_path):
    t = np.arange(0, 10.0, 0.25)
    pos = np.column_stack([0.1 + 0.08 * t, 0.5 + 0.3 * np.sin(t)])
    np.savez(tmp_path / "rat.npz", t=t + 100.0, pos=pos)  # times need not start at 0
    world = ArenaWorld(layout="open", path=str(tmp_path / "rat.npz"), dt=0.5)
    assert world.path_steps == 19  # 9.75 s of path
    traj = world.walk_from(2, 5)
    assert np.allclose(traj.positions, pos[4:14:2])  # a spline passes through its samples
    assert np.allclose(world.simulate(5, None, None).positions, pos[:10:2])
    with pytest.raises(ValueError, match=r"n_steps=30 from step 0 exceeds the 19 steps"):
        world.walk_from(0, 30)


def test_recorded_path_files_are_checked(tmp_path):
    (tmp_path / "bad.csv").write_text("t,x\n0,1\n")
    with pytest.raises(ValueError, match="must have the header t,x,y"):
        ArenaWorld(layout="open", path=str(tmp_path / "bad.csv"))
    (tmp_path / "back.csv").write_text("t,x,y\n0,0.5,0.5\n1,0.5,0.5\n1,0.5,0.5\n2,0.5,0.5\n")
    with pytest.raises(ValueError, match="times must increase, but sample 2"):
        ArenaWorld(layout="open", path=str(tmp_path / "back.csv"))
    with pytest.raises(ValueError, match="layout is needed for the recorded path"):
        np.savez(tmp_path / "ok.npz", times=np.arange(5.0), positions=np.full((5, 2), 0.5))
        ArenaWorld(path=str(tmp_path / "ok.npz"))
    far = np.column_stack([np.linspace(0.5, 1.2, 8), np.full(8, 0.5)])
    np.savez(tmp_path / "far.npz", t=np.arange(8.0), pos=far)
    with pytest.raises(ValueError, match=r"lies 0.200 m off the floor of layout 'open'"):
        ArenaWorld(layout="open", path=str(tmp_path / "far.npz"), dt=1.0).walk_from(0, 7)


def test_the_shipped_rat_paths_come_with_their_boxes():
    sarg = ArenaWorld(path="sargolini", dt=0.1)
    assert sarg.layout.extent == (0.0, 1.0, 0.0, 1.0) and sarg.path_steps == 5996
    tanni = ArenaWorld(path="tanni", dt=0.1, start=100.0)
    assert tanni.layout.extent == (0.0, 3.5, 0.0, 2.5)
    traj = tanni.simulate(50, None, None)
    assert traj.meta["first_step"] == 1000 and tanni.layout.inside(traj.positions).all()


def test_vector_cells_see_the_same_cells_on_every_walk():
    plan = floorplan_from_dict({"boundary": [[0, 0], [2, 0], [2, 1], [0, 1]],
                                "objects": [[0.5, 0.5], [1.5, 0.5, 1]]})
    for sensor in (BoundaryVectorCells(n=5, seed=3, dtheta=10.0), ObjectVectorCells(n=4, seed=3)):
        world = ArenaWorld(layout=plan, sensor=sensor)
        a = world.simulate(40, None, np.random.default_rng(0))
        b = ArenaWorld(layout=plan, sensor=type(sensor)(n=sensor.n, seed=3)).simulate(
            40, None, np.random.default_rng(0))
        assert a.observations.shape == (40, sensor.n)
        assert np.all(a.observations >= 0) and np.all(a.observations <= 1 + 1e-9)
        if isinstance(sensor, ObjectVectorCells):
            assert np.array_equal(a.observations, b.observations)
    with pytest.raises(ValueError, match="objects are needed by object-vector cells"):
        ArenaWorld(layout="open", sensor="ovc").simulate(5, None, np.random.default_rng(0))


def test_regions_of_the_built_in_layouts():
    world = ArenaWorld(layout="corridor")
    points = [[0.5, 0.5], [1.5, 0.5], [1.0, 1.2], [0.5, 2.0], [1.5, 2.0]]
    assert [world.region_names[r] for r in world.region_of(points)] == [
        "south-west", "south-east", "corridor", "north-west", "north-east"]


def test_without_ratinabox_the_world_says_how_to_install(monkeypatch):
    """The package imports without ratinabox (the app knows its components and configs); building
    a world says, in one line, how to install ratinabox."""
    import topomap.worlds

    saved = {k: v for k, v in sys.modules.items() if k.startswith("topomap.worlds.arena")}
    for name in saved:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.delattr(topomap.worlds, "arena", raising=False)  # put back afterwards
    monkeypatch.setitem(sys.modules, "ratinabox", None)
    arena = importlib.import_module("topomap.worlds.arena")
    assert arena.RangeFinder(n_beams=4).n_beams == 4  # a sensor needs no ratinabox
    for build in (arena.ArenaWorld, lambda: arena.RecordedPath("tanni")):
        with pytest.raises(ImportError, match=r'pip install "topomap\[arena\]"') as err:
            build()
        assert isinstance(err.value, ValueError) and "\n" not in str(err.value)


def test_every_component_has_a_typed_config_of_plain_values():
    import dataclasses

    from topomap import Component
    from topomap.app.compose.schemas import schema_of

    for factory in (ArenaWorld, RangeFinder, BoundaryVectorCells, ObjectVectorCells,
                    CompassActions, TurnActions):
        schema = schema_of(Component("env", "arena", factory))
        types = {f.name: f.type for f in dataclasses.fields(schema)}
        assert all(t in (int, float, bool, str, str | None, float | None)
                   or str(t) in ("typing.Optional[str]", "typing.Optional[float]")
                   for t in types.values()), (factory, types)
