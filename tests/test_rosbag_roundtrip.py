"""A simulated walk written as a bag and read back is the same data and gives the same map.

Why the map stays the same: the bag stores observations as float32 LaserScan ranges.  The
default gridroom's observations are one-hot vectors (0.0 and 1.0), exact in float32, so the
observations read back are bit-identical to the world's; the actions are identical when
``action_names`` fixes the ids to the world's; and the learner is deterministic
(``random_state=0``), so its labels are identical.  For observations that float32 cannot hold
exactly, the read-back data equal the world's data rounded to float32, and the map learned from
the bag equals the map learned from that rounded trajectory.
"""

from __future__ import annotations

import numpy as np
import pytest
from rosbag_helpers import FORMATS, bag_path, fmt  # noqa: F401 (fmt is a fixture)

from pathlib import Path

import topomap
from topomap.core.data.rosbag import read_rosbag, write_rosbag
from topomap.worlds.table.gridroom import GridRoom
from topomap.worlds.explorers import RandomExplorer
from topomap.core.data.trajectory import Trajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def walk(steps: int = 600, seed: int = 0, **world):
    """A random walk in a gridroom (default: the 8 x 6 one-hot room)."""
    return GridRoom(**world).simulate(steps, RandomExplorer(), np.random.default_rng(seed))


def labels(traj: Trajectory) -> np.ndarray:
    """The states the learner assigns to the steps of ``traj``."""
    return topomap.MapLearner(n_clusters=4, n_states=48).fit_trajectory(traj).labels_


def write(traj, tmp_path, fmt, name="walk", **kw):
    """Write ``traj`` in format ``fmt`` (one bag, or one per episode)."""
    version, storage = FORMATS[fmt]
    episodes = (1 if traj.lengths is None else traj.lengths.size)
    path = bag_path(tmp_path, fmt, name) if episodes == 1 else \
        [bag_path(tmp_path, fmt, f"{name}{e}") for e in range(episodes)]
    return write_rosbag(traj, path, version=version, storage=storage, **kw)


def test_gridroom_walk_gives_same_data_and_map(tmp_path, fmt):
    world = walk()
    back = read_rosbag(write(world, tmp_path, fmt), "/scan", "/action",
                       action_names=world.action_names)
    assert np.array_equal(back.observations, world.observations)  # 0/1 are exact in float32
    assert np.array_equal(back.actions, world.actions)
    assert back.action_names == world.action_names
    assert back.gds is None and back.lengths is None
    assert np.array_equal(back.lengths, world.lengths)
    assert back.meta["dropped_steps"] == [0]
    assert np.array_equal(labels(back), labels(world))


def test_without_action_names_the_step_names_are_the_same(tmp_path):
    world = walk(200)
    back = read_rosbag(write(world, tmp_path, "ros1"), "/scan", "/action")
    names_back = np.array(back.action_names)[back.actions]
    assert np.array_equal(names_back, np.array(world.action_names)[world.actions])


def test_float_observations_come_back_at_float32_precision(tmp_path, fmt):
    world = walk(400, obs_dim=6)  # random symbol vectors, not exact in float32
    back = read_rosbag(write(world, tmp_path, fmt), "/scan", "/action",
                       action_names=world.action_names)
    rounded = world.observations.astype(np.float32).astype(np.float64)
    assert not np.array_equal(rounded, world.observations)
    assert np.array_equal(back.observations, rounded)
    np.testing.assert_allclose(back.observations, world.observations, rtol=1e-7)
    as_float32 = Trajectory(observations=rounded, actions=world.actions,
                            action_names=world.action_names)
    assert np.array_equal(labels(back), labels(as_float32))


def test_numeric_messages_are_exact(tmp_path, fmt):
    world = walk(300, obs_dim=5)
    path = write(world, tmp_path, fmt, scan=False)
    back = read_rosbag(path, "/observation", "/action", observation_fields=["data"],
                       action_names=world.action_names)
    assert np.array_equal(back.observations, world.observations)
    assert back.meta["topics"]["/observation"] == "std_msgs/msg/Float64MultiArray"


def test_several_bags_are_the_episodes(tmp_path, fmt):
    parts = [walk(n, seed=s) for s, n in enumerate((250, 180, 300))]
    world = Trajectory(observations=np.concatenate([p.observations for p in parts]),
                       actions=np.concatenate([p.actions for p in parts]),
                       lengths=[len(p) for p in parts], action_names=parts[0].action_names)
    paths = write(world, tmp_path, fmt)
    assert len(paths) == 3 and all(p.exists() for p in paths)
    back = read_rosbag(paths, "/scan", "/action", action_names=world.action_names)
    assert back.lengths.tolist() == [250, 180, 300]
    assert np.array_equal(back.lengths, world.lengths)
    assert np.array_equal(back.observations, world.observations)
    assert np.array_equal(back.actions, world.actions)
    assert np.array_equal(labels(back), labels(world))


def test_gds_come_back(tmp_path, fmt):
    world = walk(300)
    gds = np.where(world.places == 0, 0, np.where(world.places == 47, 1, -1))
    world = Trajectory(observations=world.observations, actions=world.actions, gds=gds,
                       action_names=world.action_names, gds_names=["door", "lift"])
    back = read_rosbag(write(world, tmp_path, fmt), "/scan", "/action", gds_topic="/gds",
                       gds_window=0.04, action_names=world.action_names, gds_names=["door", "lift"])
    assert np.array_equal(back.gds, world.gds)
    assert back.gds_names == ["door", "lift"]


def test_int32_ids_are_written_without_names(tmp_path):
    world = walk(50)
    plain = Trajectory(observations=world.observations, actions=world.actions)
    back = read_rosbag(write(plain, tmp_path, "mcap"), "/scan", "/action")
    assert back.meta["topics"]["/action"] == "std_msgs/msg/Int32"
    assert back.action_names is None
    assert np.array_equal(back.actions, world.actions)


@pytest.mark.parametrize("version, storage", [(1, "sqlite3"), (2, "mcap")])
def test_export_script_writes_a_readable_bag(tmp_path, capsys, version, storage):
    import runpy

    export_bag = runpy.run_path(str(EXAMPLES / "export_bag.py"))
    out = tmp_path / ("walk.bag" if version == 1 else "walk")
    npz = tmp_path / "walk.npz"
    export_bag["main"]([str(out), "--steps", "300", "--version", str(version), "--storage", storage,
                     "--npz", str(npz)])
    assert "read_rosbag(" in capsys.readouterr().out
    world = topomap.load_trajectory(npz)
    back = read_rosbag(out, "/scan", "/action")  # the bag records the names in id order
    assert np.array_equal(back.observations, world.observations)
    assert np.array_equal(labels(back), labels(world))
    assert back.action_names == world.action_names and np.array_equal(back.actions, world.actions)
    first_seen = list(dict.fromkeys(world.actions.tolist()))
    assert first_seen != sorted(first_seen)  # the walk's first actions are not in id order

