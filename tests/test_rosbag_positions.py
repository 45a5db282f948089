"""Positions through ROS bags: a pose or odometry topic read as the steps' positions."""

from __future__ import annotations

import numpy as np
import pytest
from rosbag_helpers import (FORMATS, bag_path, fmt, header, pose, scan, string,  # noqa: F401
                            write_bag)

from topomap import Trajectory
from topomap.core.data.rosbag import read_rosbag, write_rosbag


def trajectory(dims: int) -> Trajectory:
    rng = np.random.default_rng(3)
    T = 12
    return Trajectory(rng.uniform(0, 2, (T, 4)).astype(np.float32).astype(float),
                      rng.integers(0, 3, T), positions=rng.uniform(-3, 3, (T, dims)),
                      action_names=["a", "b", "c"])


@pytest.mark.parametrize("dims", [2, 3])
def test_positions_round_trip_through_a_bag(tmp_path, fmt, dims):
    traj = trajectory(dims)
    version, storage = FORMATS[fmt]
    path = write_rosbag(traj, bag_path(tmp_path, fmt), version=version, storage=storage)
    back = read_rosbag(path, "/scan", "/action", action_names=traj.action_names,
                       position_topic="/pose")
    assert back.positions.shape == (12, dims)
    assert np.array_equal(back.positions, traj.positions)  # float64 fields: exact
    assert np.array_equal(back.observations, traj.observations)
    assert read_rosbag(path, "/scan", "/action").positions is None


def odometry(x: float, y: float, z: float = 0.0):
    """Builder of a nav_msgs/Odometry at (x, y, z)."""
    def build(store):
        t = store.types
        p = t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=x, y=y, z=z),
                                        orientation=t["geometry_msgs/msg/Quaternion"](
                                            x=0.0, y=0.0, z=0.0, w=1.0))
        V = t["geometry_msgs/msg/Vector3"]
        tw = t["geometry_msgs/msg/Twist"](linear=V(x=0.0, y=0.0, z=0.0),
                                          angular=V(x=0.0, y=0.0, z=0.0))
        return t["nav_msgs/msg/Odometry"](
            header=header(store), child_frame_id="base",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36)))
    return build


def test_each_step_takes_the_latest_odometry_and_earlier_steps_are_dropped(tmp_path, fmt):
    # steps (actions) at 1, 2, 3, 4 s; scans from 0 s; odometry at 1.5 s (x=1) and 3.0 s (x=3)
    records = [("/scan", 0.0, scan([1.0]))]
    records += [("/action", float(k), string("a")) for k in (1, 2, 3, 4)]
    records += [("/odom", 1.5, odometry(1.0, 10.0)), ("/odom", 3.0, odometry(3.0, 30.0))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    traj = read_rosbag(path, "/scan", "/action", position_topic="/odom")
    # the step at 1 s has no position yet: dropped; 2 s -> the 1.5 s message; 3 s and 4 s -> 3 s
    assert traj.positions.tolist() == [[1.0, 10.0], [3.0, 30.0], [3.0, 30.0]]
    assert traj.meta["dropped_steps"] == [1]


def test_position_errors_name_the_topic(tmp_path, fmt):
    records = [("/scan", 0.0, scan([1.0])), ("/action", 1.0, string("a")),
               ("/pose", 2.0, pose(1.0, 2.0)), ("/label", 0.5, string("x"))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    with pytest.raises(ValueError, match=r"all 1 positions on /pose come after the last action "
                                         r"on /action .* so no step has a position"):
        read_rosbag(path, "/scan", "/action", position_topic="/pose")
    with pytest.raises(ValueError, match=r"position topic /label has type std_msgs/msg/String, "
                                         r"which is not supported; supported types: "
                                         r"geometry_msgs/msg/PoseStamped"):
        read_rosbag(path, "/scan", "/action", position_topic="/label")
    with pytest.raises(ValueError, match="no position topic /where; its topics are"):
        read_rosbag(path, "/scan", "/action", position_topic="/where")
    with pytest.raises(ValueError, match="observation, action, GDS, position and odometry "
                                         "topics must differ"):
        read_rosbag(path, "/scan", "/action", position_topic="/scan")
