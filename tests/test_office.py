"""Tests of the office world (paper Section 4.1) and the random explorer."""

import json
import math

import numpy as np
import pytest

from topomap.worlds.office import (
    Action,
    ApproachType,
    FollowWall,
    GoTo,
    OfficeLayout,
    OfficeWorld,
    Pose,
    paper_layout,
    random_layout,
)
from topomap.worlds.explorers import RandomExplorer
from topomap.core.data.trajectory import Trajectory

T = 2000


@pytest.fixture(scope="module")
def world():
    # dock=False: the robot stays where each action ended, so the stop rules can be checked
    return OfficeWorld(dock=False, view_range=10.0)  # a long view: every place is reached


@pytest.fixture(scope="module")
def traj(world):
    return world.simulate(T, RandomExplorer(), np.random.default_rng(0))


def poses_of(world, traj):
    """Rebuild the pose of every step from the trajectory (position, heading, places)."""
    out = []
    for t in range(len(traj)):
        prev = int(traj.places[t - 1]) if t else -1
        x, y = traj.positions[t]
        out.append(Pose(float(x), float(y), traj.meta["headings"][t], int(traj.places[t]), prev))
    return out


# ------------------------------------------------------------------ the paper room


def test_paper_layout_counts_and_actions(world):
    assert world.n_objects == 25 and world.n_types == 15 and world.n_gds == 2
    assert len(set(world.object_types.tolist())) == 15
    counts = np.bincount(world.object_types, minlength=15)
    assert counts.max() >= 3 and (counts >= 2).sum() >= 8  # types really repeat
    assert world.n_actions == 17 and len(world.action_names) == 17
    assert world.action_names[15:] == ["follow left wall", "follow right wall"]
    assert world.action_names[0] == f"approach {world.type_names[0]}"
    assert isinstance(world.actions[3], ApproachType) and isinstance(world.actions[16], FollowWall)
    assert len(world.place_names) == world.n_places == world.place_positions.shape[0] == 29
    assert np.allclose(world.place_positions[:25], world.object_positions)


def test_paper_layout_is_fixed_and_gds_isolated(world):
    lay = paper_layout()
    assert np.array_equal(lay.centers, OfficeWorld(seed=5).object_positions)
    gaps = np.hypot(*(lay.centers[:, None] - lay.centers[None]).transpose(2, 0, 1))
    gaps = gaps - lay.radii[:, None] - lay.radii[None]
    np.fill_diagonal(gaps, np.inf)
    assert gaps.min() >= 1.0
    for g in lay.gds:  # nobody can be within reach of a GDS and of another object at once
        assert gaps[g].min() > 2 * world.reach


def test_trajectory_shapes_and_meta(world, traj):
    assert isinstance(traj, Trajectory) and len(traj) == T
    assert traj.observations.shape == (T, world.n_types)
    assert np.all(traj.observations >= 0) and np.all(traj.observations <= math.pi)
    assert traj.places.min() >= 0 and traj.places.max() < world.n_places
    assert traj.positions.shape == (T, 2)
    assert traj.action_names == world.action_names and traj.gds_names == ["GDS1", "GDS2"]
    assert traj.meta["world"] == "office" and traj.meta["place_names"] == world.place_names
    assert len(traj.meta["end_reasons"]) == T - 1
    json.dumps(traj.meta)


def test_robot_stays_in_room_and_outside_objects(world, traj):
    P = traj.positions
    assert np.all((P > 0) & (P < [world.width, world.height]))
    sd = np.hypot(*(world.object_positions[None] - P[:, None]).transpose(2, 0, 1)) - world.object_radii
    assert sd.min() > 0


def test_actions_chosen_only_when_executable(world, traj):
    for t, pose in enumerate(poses_of(world, traj)):
        a = int(traj.actions[t])
        assert world.actions[a].is_executable(world, pose), (t, world.action_names[a])
        mask = world.executable_mask(pose)
        assert mask[15] and mask[16]
        for k in range(world.n_types):  # vectorised mask agrees with the action objects
            assert mask[k] == world.actions[k].is_executable(world, pose)


def test_every_action_stops_as_specified(world, traj):
    reasons = traj.meta["end_reasons"]
    turns = traj.meta["turns_deg"]
    assert set(reasons) <= {"reach", "turn"}  # no safety cap, no blocking in the paper room
    assert reasons.count("turn") > 0
    poses = poses_of(world, traj)
    for t in range(T - 1):
        start, stop, place = poses[t], poses[t + 1], int(traj.places[t + 1])
        sd_stop = world.surface_distances(stop.xy)
        if reasons[t] == "reach":
            assert turns[t] <= world.max_turn_deg
            assert place < world.n_objects and sd_stop[place] <= world.reach + 1e-6
            # the object reached was not the one the robot started at
            assert world.surface_distances(start.xy)[place] > world.reach
        else:
            assert turns[t] > world.max_turn_deg
            assert world.action_names[traj.actions[t]].startswith("follow")
            assert place >= world.n_objects  # a corner
            assert np.allclose(stop.xy, world.place_positions[place], atol=1e-6)
        # approach actions reach their target unless they bumped into something on the way
        a = int(traj.actions[t])
        if a < world.n_types and place < world.n_objects and world.object_types[place] != a:
            on_way = world.surface_distances(stop.xy)
            assert on_way[place] <= world.reach + 1e-6


def test_gds_labels_exactly_at_gds_places(world, traj):
    gds_obj = np.array(world.gds_places)
    P = traj.positions
    sd = np.hypot(*(world.object_positions[gds_obj][None] - P[:, None]).transpose(2, 0, 1))
    sd = sd - world.object_radii[gds_obj]
    within = sd <= world.reach + 1e-7
    expected = np.where(within.any(axis=1), within.argmax(axis=1), -1)
    assert np.array_equal(traj.gds, expected)
    labelled = traj.gds >= 0
    assert labelled.sum() > 50 and set(np.unique(traj.gds[labelled])) == {0, 1}
    assert np.array_equal(traj.places[labelled], gds_obj[traj.gds[labelled]])
    assert not np.isin(traj.places[~labelled], gds_obj).any()


def test_places_visited_often(world, traj):
    counts = np.bincount(traj.places, minlength=world.n_places)
    assert np.all(counts[: world.n_objects] >= 10)
    assert np.all(counts > 0)
    assert len(set(zip(traj.places[:-1].tolist(), traj.places[1:].tolist()))) > 100


def test_same_seed_same_trajectory_different_seed_differs(world, traj):
    again = world.simulate(300, RandomExplorer(), np.random.default_rng(0))
    assert np.array_equal(again.actions, traj.actions[:300])
    assert np.array_equal(again.observations, traj.observations[:300])
    assert np.array_equal(again.places, traj.places[:300])
    other = world.simulate(300, RandomExplorer(), np.random.default_rng(1))
    assert not np.array_equal(other.actions, again.actions)


def test_aliasing_is_real_but_places_differ(world):
    obs = np.array([world.observe(world.pose_at(*world.standing_point(i))) for i in range(world.n_objects)])
    d = np.linalg.norm(obs[:, None] - obs[None], axis=2)
    np.fill_diagonal(d, np.inf)
    assert d.min() > 0.05  # every object place looks different overall ...
    t = world.object_types
    for i in range(world.n_objects):
        for j in range(i + 1, world.n_objects):
            if t[i] == t[j]:  # ... but its own type's entry is the same for objects of one type
                assert obs[i, t[i]] == pytest.approx(obs[j, t[j]])
    # the two desk groups mirror each other: their computers look almost alike
    comp = np.flatnonzero(np.array(world.type_names)[t] == "computer")
    assert d[comp[0], comp[1]] < np.median(d[np.isfinite(d)])


def test_docking_puts_every_step_at_its_place_standing_point():
    w = OfficeWorld(view_range=10.0)  # dock=True, the default
    tr = w.simulate(400, RandomExplorer(), np.random.default_rng(4))
    stand = np.array([w.standing_point(p) for p in range(w.n_places)])
    assert np.allclose(tr.positions[1:], stand[tr.places[1:]])
    # noise-free observations are then a function of the place alone
    for p in np.unique(tr.places[1:]):
        rows = tr.observations[1:][tr.places[1:] == p]
        assert np.allclose(rows, rows[0])
    gds_obj = np.array(w.gds_places)
    labelled = tr.gds >= 0
    assert np.array_equal(tr.places[labelled], gds_obj[tr.gds[labelled]])
    assert not np.isin(tr.places[~labelled], gds_obj).any()


# ------------------------------------------------------------------ hand-made rooms


def tiny_world(**kw):
    lay = OfficeLayout(
        width=12.0, height=10.0, type_names=["big", "small"], types=[0, 1],
        centers=[(5.0, 5.0), (8.0, 5.0)], radii=[1.0, 0.3], gds=[1],
    )
    kw.setdefault("dock", False)
    kw.setdefault("view_range", 10.0)
    return OfficeWorld.from_layout(lay, **kw)


def test_occlusion_by_a_nearer_bigger_object():
    w = tiny_world()
    behind = w.observe(w.pose_at(2.0, 5.0))
    assert behind[0] == pytest.approx(2 * math.atan(1.0 / 3.0))
    assert behind[1] == 0.0
    assert not w.actions[1].is_executable(w, w.pose_at(2.0, 5.0))
    side = w.observe(w.pose_at(2.0, 8.5))
    assert side[1] == pytest.approx(2 * math.atan(0.3 / math.hypot(6.0, 3.5)))
    assert w.actions[1].is_executable(w, w.pose_at(2.0, 8.5))


def test_view_range_hides_far_objects():
    w = tiny_world(view_range=2.0)
    obs = w.observe(w.pose_at(2.0, 8.5))
    assert obs[1] == 0.0 and obs[0] == 0.0
    assert w.observe(w.pose_at(5.0, 7.5))[0] > 0


def test_approach_and_wall_following_in_tiny_room():
    w = tiny_world()
    rng = np.random.default_rng(0)
    start = w.pose_at(10.5, 8.0)
    stop = w.step(start, 1, rng)  # approach small
    assert stop.end_reason == "reach" and stop.place == 1 and w.gds_of(stop) == 0
    assert w.surface_distances(stop.xy)[1] == pytest.approx(w.reach)
    # follow left wall near the west wall: face it, turn north (wall on the left), stop at the corner
    stop = w.step(w.pose_at(2.5, 5.0), 2, rng)
    assert stop.end_reason == "turn" and w.place_names[stop.place] == "corner NW"
    assert stop.turned_deg == pytest.approx(180.0)
    stop = w.step(w.pose_at(2.5, 5.0), 3, rng)
    assert stop.end_reason == "turn" and w.place_names[stop.place] == "corner SW"
    # from a corner the two wall-following actions leave in different directions
    corner = w.pose_at(*w.place_positions[w.place_names.index("corner SW")])
    a, b = w.step(corner, 2, rng), w.step(corner, 3, rng)
    assert a.place != b.place and a.path_length > 1 and b.path_length > 1


def test_wall_following_stops_at_the_next_wall_object(world):
    rng = np.random.default_rng(0)
    # robot on the south lane between the red wall (x=4) and the yellow wall (x=7.5)
    pose = world.pose_at(5.8, 1.5)
    left, right = world.step(pose, 15, rng), world.step(pose, 16, rng)
    assert world.place_names[left.place] == "red wall 1" and left.end_reason == "reach"
    assert world.place_names[right.place] == "yellow wall 1" and right.end_reason == "reach"


def test_action_cap(world):
    w = OfficeWorld(max_action_steps=2, step_size=0.25, dock=False, view_range=10.0)
    stop = w.step(w.pose_at(2.5, 8.0), 15, np.random.default_rng(0))
    assert stop.end_reason == "cap" and stop.path_length == pytest.approx(0.5)


class GoToCentre(Action):
    name = "go to centre"

    def is_executable(self, world, pose):
        return math.hypot(pose.x - world.width / 2, pose.y - world.height / 2) > 3.0

    def execute(self, world, pose, rng):
        return world.drive(pose, [GoTo((world.width / 2, world.height / 2), stop_distance=0.0)])


def test_extra_actions_are_appended_and_used():
    w = OfficeWorld(extra_actions=[GoToCentre()], view_range=10.0)
    assert w.n_actions == 18 and w.action_names[-1] == "go to centre"
    tr = w.simulate(400, RandomExplorer(), np.random.default_rng(0))
    assert (tr.actions == 17).sum() > 5
    for t, pose in enumerate(poses_of(w, tr)):
        if tr.actions[t] == 17:
            assert w.actions[17].is_executable(w, pose)
    with pytest.raises(ValueError, match="extra_actions"):
        OfficeWorld(extra_actions=[object()])


# ------------------------------------------------------------------ random rooms and validation


def test_random_layout_reproducible_and_valid():
    a = OfficeWorld("random", seed=7)
    b = OfficeWorld("random", seed=7)
    c = OfficeWorld("random", seed=8)
    assert np.array_equal(a.object_positions, b.object_positions)
    assert a.type_names == b.type_names and a.gds_places == b.gds_places
    assert not np.array_equal(a.object_positions, c.object_positions)
    w = OfficeWorld("random", n_objects=12, n_types=7, n_gds=1, width=16, height=12, seed=2)
    assert sorted(set(w.object_types.tolist())) == list(range(7))
    tr = w.simulate(1500, RandomExplorer(), np.random.default_rng(0))
    assert tr.observations.shape[1] == 7 and w.n_actions == 9
    assert set(tr.meta["end_reasons"]) <= {"reach", "turn"}
    assert set(tr.places[np.isin(tr.places, np.arange(w.n_objects))].tolist()) == set(range(12))
    lay = random_layout(np.random.default_rng(7))
    assert np.array_equal(lay.centers, a.object_positions)
    with pytest.raises(TypeError, match="positional"):  # the spacings are given by keyword
        random_layout(np.random.default_rng(7), 25, 15, 2, 20.0, 14.0, 1.0)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        (dict(layout="random", n_types=30, n_objects=25), "n_types"),
        (dict(layout="random", n_gds=26), "n_gds"),
        (dict(layout="circle"), "layout"),
        (dict(layout="random", width=-3.0), "width"),
        (dict(layout="random", height=0), "height"),
        (dict(reach=0.0), "reach"),
        (dict(step_size=-1.0), "step_size"),
        (dict(max_turn_deg=0), "max_turn_deg"),
        (dict(max_action_steps=0), "max_action_steps"),
        (dict(view_range=-1), "view_range"),
        (dict(n_objects=20), "n_objects"),
        (dict(layout="random", n_objects=200, seed=1), "n_objects"),
    ],
)
def test_bad_arguments_raise(kwargs, word):
    with pytest.raises(ValueError, match=word):
        OfficeWorld(**kwargs)


def test_bad_layouts_raise():
    with pytest.raises(ValueError, match="overlap"):
        OfficeLayout(10, 10, ["a"], [0, 0], [(5, 5), (5.5, 5)], [1.0, 1.0])
    with pytest.raises(ValueError, match="inside the room"):
        OfficeLayout(10, 10, ["a"], [0], [(0.2, 5)], [1.0])
    with pytest.raises(ValueError, match="gds"):
        OfficeLayout(10, 10, ["a"], [0], [(5, 5)], [1.0], gds=[3])


def test_simulate_rejects_bad_input(world):
    with pytest.raises(ValueError, match="n_steps"):
        world.simulate(0, RandomExplorer(), np.random.default_rng(0))

    class Bad:
        def choose(self, mask, rng):
            return int(np.flatnonzero(~mask)[0]) if (~mask).any() else 99

    with pytest.raises(ValueError, match="not executable"):
        world.simulate(50, Bad(), np.random.default_rng(0))


def test_plot_room(world):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    assert world.plot_room(ax) is ax
    assert len(ax.patches) == 1 + world.n_objects + world.n_gds
    plt.close(fig)


# ------------------------------------------------------------------ explorer


def test_random_explorer_uniform_over_executable():
    ex = RandomExplorer()
    rng = np.random.default_rng(0)
    mask = np.array([False, True, False, True, True])
    picks = np.array([ex.choose(mask, rng) for _ in range(3000)])
    assert set(picks.tolist()) == {1, 3, 4}
    assert np.allclose(np.bincount(picks, minlength=5)[[1, 3, 4]] / 3000, 1 / 3, atol=0.04)
    with pytest.raises(ValueError, match="executable"):
        ex.choose(np.zeros(4, dtype=bool), rng)
