"""``data=rosbag``: a bag of a simulated walk learns the same map as the walk's own file."""

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("rosbags")

from topomap import read_rosbag, save_trajectory, write_rosbag  # noqa: E402
from topomap.app.run.experiment import run  # noqa: E402
from topomap.worlds import GridRoom, RandomExplorer  # noqa: E402

LEARN = ["clusters.ns=4", "stop.n_states=48", "output.figures=false", "output.progress=false"]


@pytest.fixture
def walk(tmp_path):
    traj = GridRoom().simulate(1500, RandomExplorer(), np.random.default_rng(3))
    traj.places = traj.positions = None  # a robot's log has no ground truth
    return traj, save_trajectory(traj, tmp_path / "walk.npz")


@pytest.mark.parametrize("version, storage", [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")])
def test_a_bag_learns_the_same_states_and_map_as_the_file(walk, tmp_path, make_cfg, version,
                                                          storage):
    traj, npz = walk
    bag = write_rosbag(traj, tmp_path / ("walk.bag" if version == 1 else "walk"), version=version,
                       storage=storage)
    from_bag = run(make_cfg(["data=rosbag", f"data.path={bag}", "data.observation_topic=/scan",
                             "data.action_topic=/action", *LEARN]), tmp_path / "bag")
    from_file = run(make_cfg(["data=file", f"data.path={npz}", *LEARN]), tmp_path / "file")
    assert from_bag["n_states"] == from_file["n_states"]
    for name in ("states.csv", "map.json"):
        assert (tmp_path / "bag" / name).read_bytes() == (tmp_path / "file" / name).read_bytes()


def test_the_export_scripts_bag_and_file_learn_the_same_map(tmp_path, make_cfg):
    """``docs/examples/export_bag.py walk.bag --npz walk.npz``, then the two documented
    commands: the same states and the same map, byte for byte."""
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "docs" / "examples" / "export_bag.py"
    runpy.run_path(str(script))["main"]([str(tmp_path / "walk.bag"), "--npz",
                                         str(tmp_path / "walk.npz")])
    run(make_cfg(["data=rosbag", f"data.path={tmp_path / 'walk.bag'}", *LEARN,
                  "data.observation_topic=/scan", "data.action_topic=/action"]), tmp_path / "bag")
    run(make_cfg(["data=file", f"data.path={tmp_path / 'walk.npz'}", *LEARN]), tmp_path / "file")
    assert (tmp_path / "bag" / "map.json").read_bytes() == \
        (tmp_path / "file" / "map.json").read_bytes()
    states = [np.loadtxt(tmp_path / where / "states.csv", delimiter=",", skiprows=1,
                         usecols=(0, 1, 2), dtype=int) for where in ("bag", "file")]
    assert np.array_equal(*states)  # the file's walk has its places too; the bag has none


def test_a_list_of_bags_is_one_episode_each(walk, tmp_path, make_cfg):
    traj, _ = walk
    first = write_rosbag(traj, tmp_path / "a.bag")
    second = write_rosbag(traj, tmp_path / "b.bag")
    results = run(make_cfg(["data=rosbag", f"data.path=[{first},{second}]",
                            "data.observation_topic=/scan", "data.action_topic=/action", *LEARN,
                            f"data.heldout_path={first}"]), tmp_path / "out")
    both = read_rosbag([first, second], "/scan", "/action")
    assert both.lengths.tolist() == [len(traj), len(traj)]
    assert results["heldout_steps"] == len(traj) and results["heldout_loglik"] is not None


@pytest.mark.slow
def test_bag_errors_are_one_line_and_write_nothing(walk, tmp_path):
    traj, _ = walk
    bag = write_rosbag(traj, tmp_path / "walk.bag")
    r = subprocess.run([sys.executable, "-m", "topomap", "data=rosbag", f"data.path={bag}",
                        "data.observation_topic=/laser", "data.action_topic=/action", *LEARN],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    line = r.stderr.strip().splitlines()[-1]
    assert "no observation topic /laser; its topics are: /action (std_msgs/msg/String, 1500" in line
    assert not list((tmp_path / "outputs" / "runs").rglob("map.json"))


@pytest.mark.slow
def test_without_rosbags_installed_the_message_says_how_to_get_it(walk, tmp_path):
    write_rosbag(walk[0], tmp_path / "x.bag")
    code = ("import sys; sys.modules['rosbags'] = None\n"
            "import topomap\n"
            "try:\n    topomap.read_rosbag('x.bag', '/scan', '/action')\n"
            "except ValueError as exc:\n    print(exc)\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                       timeout=60)
    assert 'pip install "topomap[ros]"' in r.stdout, r.stderr


def test_the_command_reads_the_steps_positions_from_a_pose_topic(tmp_path, make_cfg):
    """``data.position_topic`` is read_rosbag's ``position_topic``: the run's trajectory holds the
    positions the bag's ``/pose`` messages carry."""
    from topomap import load_trajectory

    traj = GridRoom().simulate(600, RandomExplorer(), np.random.default_rng(3))
    traj.places = None
    bag = write_rosbag(traj, tmp_path / "walk.bag")
    run(make_cfg(["data=rosbag", f"data.path={bag}", "data.observation_topic=/scan",
                  "data.action_topic=/action", "data.position_topic=/pose", "clusters.ns=4",
                  "stop.n_states=10", "output.figures=false", "output.progress=false"]),
        tmp_path / "out")
    assert np.array_equal(load_trajectory(tmp_path / "out" / "trajectory.npz").positions,
                          traj.positions)
