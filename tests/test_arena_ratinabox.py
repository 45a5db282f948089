"""ratinabox's own objects and cells in the arena: a world from an ``Environment`` or an
``Agent``, and place-cell and grid-cell sensors seeded apart from numpy's global random state."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("ratinabox")

from ratinabox.Agent import Agent  # noqa: E402
from ratinabox.Environment import Environment  # noqa: E402

from topomap.app.run.experiment import check_and_build  # noqa: E402
from topomap.worlds.arena import ArenaWorld, GridCells, Motion, PlaceCells  # noqa: E402


def _box_with_wall():
    return Environment(params={"boundary": [[0, 0], [2, 0], [2, 1], [0, 1]],
                               "walls": [[[1, 0], [1, 0.6]]]})


def test_a_world_walks_a_ratinabox_environment_as_it_is():
    env = _box_with_wall()
    world = ArenaWorld(layout=env)
    assert world.arena.environment is env
    assert world.layout.boundary.tolist() == [[0, 0], [2, 0], [2, 1], [0, 1]]
    assert world.layout.walls.tolist() == [[[1, 0], [1, 0.6]]]
    assert world.layout.segments.shape == (5, 2, 2) and world.region_names == []
    traj = world.simulate(300, None, np.random.default_rng(0))
    assert world.layout.inside(traj.positions).all()


def test_a_periodic_environment_is_refused():
    env = Environment(params={"boundary_conditions": "periodic"})
    with pytest.raises(ValueError, match=r"^layout must be a 2D ratinabox Environment with solid "
                                         r"boundaries, got 2D periodic"):
        ArenaWorld(layout=env)


def test_a_world_from_an_agent_walks_as_the_agent_does():
    agent = Agent(_box_with_wall(), params={"speed_mean": 0.15, "dt": 0.05, "thigmotaxis": 0.2})
    world = ArenaWorld.from_agent(agent, actions="turns")
    assert world.dt == 0.05
    assert world.motion_params["speed_mean"] == 0.15 and world.motion_params["thigmotaxis"] == 0.2
    assert world.action_names == ["forward", "turn_left", "turn_right", "stop"]
    with pytest.raises(ValueError, match=r"^dt is the agent's own"):
        ArenaWorld.from_agent(agent, dt=0.1)


def test_place_cells_fire_one_at_their_centres_and_fall_as_gaussians():
    """A field of width 0.2 m (euclidean) fires exp(-1/2) = 0.607 at 0.2 m from its centre."""
    world = ArenaWorld("open", sensor=PlaceCells(n=4, seed=1, wall_geometry="euclidean"))
    centre = world.sensor._cells(world.arena).place_cell_centres[0]
    aside = centre + [0.2 if centre[0] < 0.5 else -0.2, 0]  # on the floor of the 1 x 1 m box
    motion = Motion.from_samples(np.vstack([centre, aside, aside]), 0.1)
    rates = world.sensor.sense(world.arena, motion)
    assert rates[0, 0] == pytest.approx(1.0)
    assert rates[1, 0] == pytest.approx(math.exp(-0.5), abs=1e-6)


@pytest.mark.parametrize("sensor", [PlaceCells, GridCells])
def test_the_cells_are_seeded_apart_from_the_global_random_state(sensor):
    """The same seed gives the same cells in two worlds, another seed other cells, and the
    caller's numpy global random state is left as it was."""
    walk = Motion.from_samples(np.random.default_rng(0).uniform(0.1, 0.9, (51, 2)), 0.1)

    def rates(seed):
        world = ArenaWorld("open", sensor=sensor(n=8, seed=seed))
        return world.sensor.sense(world.arena, walk)

    np.random.seed(7)
    expected = np.random.rand()
    np.random.seed(7)
    a, b, c = rates(3), rates(3), rates(4)
    assert np.random.rand() == expected
    assert a.shape == (50, 8) and np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0 <= a.min() and a.max() <= 1


@pytest.mark.parametrize("name", ["place_cells", "grid_cells"])
def test_the_cell_sensors_are_components(name, make_cfg):
    checked = check_and_build(make_cfg(["env=arena", f"sensor={name}", "sensor.n=5",
                                        "seed=2"]))
    assert checked.parts.env.sensor.n == 5 and checked.parts.env.sensor.seed == 2
    assert checked.parts.env.n_features == 5
