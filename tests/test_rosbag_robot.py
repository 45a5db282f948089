"""A robot's topics written by ``write_rosbag`` and read back: velocity commands (``/cmd_vel``),
odometry (``/odom``), its transform (``/tf``) and the ground truth, each the same arrays again."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from rosbag_helpers import FORMATS, bag_path, fmt  # noqa: F401 (fmt is a fixture)

from topomap import Trajectory, load_trajectory
from topomap.core.data.rosbag import TWIST_OF_ACTION, read_rosbag, twist_action, write_rosbag
from topomap.worlds.arena.actions import TurnActions

TURNS = ["forward", "turn_left", "turn_right", "stop"]


def robot_walk(T: int = 40, seed: int = 0, lengths=None) -> Trajectory:
    """A robot's log: 3-beam scans (float32-exact), turn / forward / stop commands, the truth
    and an odometry that drives 0.05 m per step while its heading turns past +-pi."""
    rng = np.random.default_rng(seed)
    theta = np.cumsum(rng.uniform(-0.6, 0.6, T)) + 3.0
    xy = np.cumsum(0.05 * np.c_[np.cos(theta), np.sin(theta)], axis=0)
    return Trajectory(rng.uniform(0, 4, (T, 3)).astype(np.float32).astype(float),
                      rng.integers(0, 4, T), positions=rng.uniform(-2, 2, (T, 2)),
                      odometry=np.c_[xy, theta], action_names=TURNS, lengths=lengths)


def wrapped(angle):
    return np.angle(np.exp(1j * np.asarray(angle)))


def write(traj, tmp_path, fmt, **kw):
    version, storage = FORMATS[fmt]
    return write_rosbag(traj, bag_path(tmp_path, fmt), version=version, storage=storage, **kw)


def test_cmd_vel_odom_tf_and_the_truth_read_back_as_written(tmp_path, fmt):
    traj = robot_walk()
    path = write(traj, tmp_path, fmt, cmd_vel_topic="/cmd_vel", position_topic="/truth")
    back = read_rosbag(path, "/scan", "/cmd_vel", action_names=TURNS, odometry_topic="/odom",
                       position_topic="/truth")
    assert np.array_equal(back.actions, traj.actions)
    assert np.array_equal(back.observations, traj.observations)
    assert np.array_equal(back.positions, traj.positions)  # float64 fields: exact
    assert np.array_equal(back.odometry[:, :2], traj.odometry[:, :2])
    # the heading goes through a quaternion and comes back as its yaw, wrapped into (-pi, pi]
    assert np.abs(wrapped(back.odometry[:, 2] - traj.odometry[:, 2])).max() < 1e-12
    assert np.abs(back.odometry[:, 2]).max() <= math.pi and np.abs(traj.odometry[:, 2]).max() > 4
    assert back.meta["dropped_steps"] == [0]
    # /tf holds odom -> base_link: the odometry again, when asked for as positions
    tf = read_rosbag(path, "/scan", "/action", position_topic="/tf", position_frame="odom",
                     position_child_frame="base_link")
    assert np.array_equal(tf.positions, traj.odometry[:, :2])
    assert back.meta["topics"]["/cmd_vel"] == "geometry_msgs/msg/Twist"


def test_every_episode_is_a_bag_with_its_own_odometry(tmp_path):
    traj = robot_walk(30, seed=1, lengths=[12, 18])
    paths = write_rosbag(traj, [tmp_path / "a.bag", tmp_path / "b.bag"], cmd_vel_topic="/cmd_vel")
    back = read_rosbag(paths, "/scan", "/cmd_vel", action_names=TURNS, odometry_topic="/odom")
    assert back.lengths.tolist() == [12, 18]
    assert np.array_equal(back.odometry[:, :2], traj.odometry[:, :2])
    assert np.array_equal(back.actions, traj.actions)


def test_the_odometry_twist_is_the_velocity_over_the_step_before(tmp_path):
    # at 10 Hz: step 1 drives 0.1 m along x facing 0 -> 1 m/s forward; step 2 turns 0.05 rad on
    # the spot -> 0.5 rad/s; step 3 moves 0.1 m along y while facing 0.05 rad -> forward
    # 0.1 sin(0.05) / 0.1 = sin(0.05) m/s, leftward cos(0.05) m/s, and turns pi/2 - 0.05 rad
    odometry = [[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0.05], [0.1, 0.1, math.pi / 2]]
    traj = Trajectory(np.ones((4, 1)), np.zeros(4, dtype=int), odometry=odometry)
    path = write_rosbag(traj, tmp_path / "w.bag", rate=10.0)
    fields = ["twist.twist.linear.x", "twist.twist.linear.y", "twist.twist.angular.z"]
    twist = read_rosbag(path, "/odom", "/action", observation_fields=fields).observations
    expected = [[0, 0, 0], [1, 0, 0], [0, 0, 0.5],
                [math.sin(0.05), math.cos(0.05), (math.pi / 2 - 0.05) * 10]]
    np.testing.assert_allclose(twist, expected, atol=1e-12)


def test_each_action_s_command_reads_back_as_that_action():
    """The commands of ``TWIST_OF_ACTION`` are read as their actions by ``read_rosbag``'s Twist
    rule (default thresholds) and by the arena's ``TurnActions`` (defaults), which reads a move."""
    for name, (linear, angular) in TWIST_OF_ACTION.items():
        assert twist_action(linear, angular) == name
    rule = TurnActions()
    motion = SimpleNamespace(velocity=np.array([[v, 0.0] for v, _ in TWIST_OF_ACTION.values()]),
                             rotational_velocity=np.array([w for _, w in TWIST_OF_ACTION.values()]))
    read = [rule.action_names[a] for a in rule.actions(motion)]
    # TurnActions has no backward: a reverse drive is a move at speed, so it reads forward
    assert read == [n if n != "backward" else "forward" for n in TWIST_OF_ACTION]


def test_without_action_topic_the_commands_are_the_actions(tmp_path):
    traj = robot_walk(10)
    path = write_rosbag(traj, tmp_path / "w.bag", action_topic=None, cmd_vel_topic="/cmd_vel")
    with pytest.raises(ValueError, match="no action topic /action"):
        read_rosbag(path, "/scan", "/action")
    back = read_rosbag(path, "/scan", "/cmd_vel")  # names in order of first appearance
    assert [back.action_names[a] for a in back.actions] == [TURNS[a] for a in traj.actions]


def test_without_odometry_or_with_its_topics_off_nothing_of_it_is_written(tmp_path):
    traj = robot_walk(5)
    path = write_rosbag(traj, tmp_path / "off.bag", odometry_topic=None, tf_topic=None)
    topics = read_rosbag(path, "/scan", "/action", position_topic="/pose").meta["topics"]
    with pytest.raises(ValueError, match=r"no odometry topic /odom; its topics are: /action "
                                         r"\(std_msgs/msg/String, 5 messages\), /action/names .*"
                                         r"/pose .* /scan \(sensor_msgs/msg/LaserScan, 5 "
                                         r"messages\)$"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/odom")
    assert "/odom" not in topics
    plain = Trajectory(traj.observations, traj.actions, action_names=TURNS)
    path = write_rosbag(plain, tmp_path / "plain.bag")
    with pytest.raises(ValueError, match=r"no position topic /tf; its topics are: /action "):
        read_rosbag(path, "/scan", "/action", position_topic="/tf", position_frame="odom",
                    position_child_frame="base_link")


@pytest.mark.parametrize("change, kw, match", [
    (dict(action_names=["north", "east", "south", "west"]), dict(cmd_vel_topic="/cmd_vel"),
     r"cmd_vel_topic writes each action as the velocity command of its name, and the action "
     r"'(north|east|south|west)' has none; commands exist for forward, backward, turn_left, "
     r"turn_right, stop"),
    (dict(action_names=None), dict(cmd_vel_topic="/cmd_vel"), "the trajectory has no "
                                                             "action_names"),
    ({}, dict(action_topic=None), "action_topic and cmd_vel_topic are both None"),
    ({}, dict(position_topic="/odom"), "topics must differ: position_topic and odometry_topic "
                                       "are both /odom"),
    ({}, dict(tf_topic="/scan"), "topics must differ: observation_topic and tf_topic are both "
                                 "/scan"),
])
def test_bad_robot_topics_are_refused_before_any_file(tmp_path, change, kw, match):
    traj = robot_walk(6)
    fields = dict(observations=traj.observations, actions=traj.actions, odometry=traj.odometry,
                  action_names=TURNS)
    fields.update(change)
    with pytest.raises(ValueError, match=match):
        write_rosbag(Trajectory(**fields), tmp_path / "w.bag", **kw)
    assert list(tmp_path.iterdir()) == []


def test_the_command_reads_odometry_and_the_truth(tmp_path, make_cfg):
    """``data.odometry_topic=/odom data.position_topic=/truth``: the run's trajectory holds the
    bag's odometry as ``odometry`` and its truth as ``positions``, each as written."""
    from topomap.app.run.experiment import run

    traj = robot_walk(300, seed=2)
    bag = write_rosbag(traj, tmp_path / "walk.bag", position_topic="/truth",
                       cmd_vel_topic="/cmd_vel")
    run(make_cfg(["data=rosbag", f"data.path={bag}", "data.observation_topic=/scan",
                  "data.action_topic=/cmd_vel", "data.odometry_topic=/odom",
                  "data.position_topic=/truth", f"data.action_names=[{','.join(TURNS)}]",
                  "clusters.ns=4", "stop.n_states=8", "output.figures=false",
                  "output.progress=false"]), tmp_path / "out")
    saved = load_trajectory(tmp_path / "out" / "trajectory.npz")
    assert np.array_equal(saved.positions, traj.positions)
    assert np.array_equal(saved.odometry[:, :2], traj.odometry[:, :2])
    assert np.array_equal(saved.actions, traj.actions)


# ------------------------------------------------------------- docs/examples/robot_bag.py

def example():
    import runpy
    from pathlib import Path

    pytest.importorskip("ratinabox")
    return runpy.run_path(str(Path(__file__).resolve().parents[1] / "docs" / "examples" /
                              "robot_bag.py"))


def test_the_example_s_true_odometry_is_the_path_from_the_robot_s_start():
    true_odometry = example()["true_odometry"]
    # north 1 m, then west 1 m (dt = 1 s): seen from the start, facing +x, that is +x then +y
    path = np.array([[0.0, 0.0], [0.0, 1.0], [-1.0, 1.0], [-1.0, 1.0]])
    np.testing.assert_allclose(true_odometry(path, 1.0),
                               [[0, 0, 0], [1, 0, 0], [1, 1, math.pi / 2]], atol=1e-12)


def test_the_example_s_robot_keeps_the_arena_s_wheel_odometry():
    """The bags' /odom is the arena's odometry=wheel of the same walk."""
    ns = example()
    world = ns["ArenaWorld"]("two_rooms", sensor=ns["RangeFinder"](frame="egocentric"),
                             actions="turns", odometry="wheel")
    log = ns["robot_log"](world, 200, np.random.default_rng(1))
    again = world.simulate(200, None, np.random.default_rng(1))
    assert np.array_equal(log.odometry, again.odometry)
    assert np.array_equal(log.positions, again.positions)


def test_the_example_simulates_records_and_learns(tmp_path, make_cfg, capsys):
    """``docs/examples/robot_bag.py``: the bags hold the robot's topics, the map is scored in
    metres, and the printed command learns from the same bags."""
    from topomap.app.run.experiment import run

    scores = example()["main"]([str(tmp_path / "robot.bag"), "--steps", "800",
                                "--heldout-steps", "300", "--clusters", "6", "--states", "8"])
    assert set(scores) == {"map", "ceiling", "kmeans_views", "kmeans_positions"}
    assert scores["map"]["steps"] == 300
    out = capsys.readouterr().out
    assert "the odometry drifted" in out
    back = read_rosbag(tmp_path / "robot.bag", "/scan", "/cmd_vel", odometry_topic="/odom",
                       position_topic="/tf", position_frame="odom",
                       position_child_frame="base_link")
    assert len(back) == 800 and np.array_equal(back.positions, back.odometry[:, :2])
    command = out.split("the same from the command line: topomap ")[1].split()
    overrides = [w.strip("'") for w in command]
    results = run(make_cfg([*overrides, "output.figures=false", "output.progress=false"]),
                  tmp_path / "run")
    assert results["position"]["heldout_steps"] == 300
    saved = load_trajectory(tmp_path / "run" / "trajectory.npz")
    assert saved.odometry.shape == (800, 3)
