"""Odometry and frames through ROS bags: ``odometry_topic`` read as ``Trajectory.odometry``, the
ground truth kept apart from the robot's ``odom`` frame, and ``tf2_msgs/TFMessage`` as a position
source chosen by its frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbag_helpers import (bag_path, fmt, odometry_msg, pose_msg, scan, string,  # noqa: F401
                            tf_msg, write_bag)

from topomap.core.checks import ParameterError
from topomap.core.data.rosbag import read_rosbag


def steps(n: int, extra):
    """``n`` steps at 1, 2, ... s, each a scan 0.5 s before its action, plus ``extra(k, t)``
    records at each step's time ``t`` (step ``k``)."""
    records = []
    for k in range(n):
        t = float(k + 1)
        records += [("/scan", t - 0.5, scan([k])), ("/action", t, string("a")), *extra(k, t)]
    return records


def test_odometry_gives_x_y_and_the_yaw_of_the_orientation(tmp_path, fmt):
    # step k: odometry at (k, -k) facing 0.9 k rad, recorded 0.2 s before the step; from 0.9 * 4
    # = 3.6 rad on, the quaternion's yaw comes back wrapped into (-pi, pi]: 3.6 - 2 pi
    poses = [(k, -k, 0.9 * k) for k in range(5)]
    path = write_bag(bag_path(tmp_path, fmt), fmt,
                     steps(5, lambda k, t: [("/odom", t - 0.2, odometry_msg(*poses[k]))]))
    traj = read_rosbag(path, "/scan", "/action", odometry_topic="/odom")
    expected = np.array(poses, dtype=float)
    expected[4, 2] -= 2 * math.pi
    np.testing.assert_allclose(traj.odometry, expected, atol=1e-12)
    assert traj.positions is None  # odometry is not the truth
    assert traj.meta["topics"]["/odom"] == "nav_msgs/msg/Odometry"


def test_a_pose_topic_gives_odometry_and_steps_before_the_first_are_dropped(tmp_path, fmt):
    # poses at 2.5 s and 4.0 s: the steps at 1 and 2 s have none (dropped), 3 s takes the 2.5 s
    # pose, 4 s and 5 s the 4.0 s one
    records = steps(5, lambda k, t: []) + [("/slam", 2.5, pose_msg(1.0, 2.0, 0.5)),
                                           ("/slam", 4.0, pose_msg(2.0, 3.0, -0.5))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    traj = read_rosbag(path, "/scan", "/action", odometry_topic="/slam")
    np.testing.assert_allclose(traj.odometry, [[1, 2, 0.5], [2, 3, -0.5], [2, 3, -0.5]],
                               atol=1e-12)
    assert traj.observations[:, 0].tolist() == [2, 3, 4]
    assert traj.meta["dropped_steps"] == [2]


def test_odometry_errors_name_the_bag_the_topic_and_the_step(tmp_path):
    # a reset to the origin at the fourth step (3 m back): steps 2 -> 3
    xs = [0.0, 1.0, 3.0, 0.0]
    path = write_bag(bag_path(tmp_path, "ros1"), "ros1",
                     steps(4, lambda k, t: [("/odom", t, odometry_msg(xs[k], 0.0))]))
    with pytest.raises(ValueError, match=r"bag .*run.bag: odometry topic /odom: odometry moves "
                                         r"3 m from step 2 to step 3, more than "
                                         r"MAX_ODOMETRY_STEP = 2 m"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/odom")
    with pytest.raises(ValueError, match=r"odometry topic /scan has type "
                                         r"sensor_msgs/msg/LaserScan, which is not supported; "
                                         r"supported types: nav_msgs/msg/Odometry"):
        read_rosbag(path, "/odom", "/action", odometry_topic="/scan",
                    observation_fields=["pose.pose.position.x"])
    with pytest.raises(ValueError, match="no odometry topic /wheel; its topics are"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/wheel")
    with pytest.raises(ValueError, match="must differ"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/odom", position_topic="/odom")


def test_a_zero_quaternion_is_no_heading(tmp_path):
    def zero(store):
        msg = pose_msg(0.0, 0.0)(store)
        msg.pose.orientation.w = 0.0
        return msg
    path = write_bag(bag_path(tmp_path, "ros1"), "ros1", steps(2, lambda k, t: [("/o", t, zero)]))
    with pytest.raises(ValueError, match=r"bag .*: odometry topic /o: orientation is the zero "
                                         r"quaternion"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/o")


def test_all_odometry_after_the_last_step_says_so(tmp_path):
    records = steps(2, lambda k, t: []) + [("/odom", 9.0, odometry_msg(0.0, 0.0))]
    path = write_bag(bag_path(tmp_path, "ros1"), "ros1", records)
    with pytest.raises(ValueError, match=r"all 1 odometry messages on /odom come after the last "
                                         r"action on /action .* so no step has an odometry pose"):
        read_rosbag(path, "/scan", "/action", odometry_topic="/odom")


# ------------------------------------------------------------------- the truth, and its frames


def test_positions_in_the_odom_frame_are_refused_unless_asked_for(tmp_path, fmt):
    path = write_bag(bag_path(tmp_path, fmt), fmt,
                     steps(3, lambda k, t: [("/odom", t, odometry_msg(float(k), 0.0))]))
    with pytest.raises(ValueError, match=r"the positions on /odom are in the frame 'odom', the "
                                         r"robot's own odometry \(REP 105\), which drifts and is "
                                         r"no ground truth: give it as odometry_topic=/odom.* "
                                         r"set position_frame=odom"):
        read_rosbag(path, "/scan", "/action", position_topic="/odom")
    traj = read_rosbag(path, "/scan", "/action", position_topic="/odom", position_frame="odom")
    assert traj.positions.tolist() == [[0, 0], [1, 0], [2, 0]]


def test_the_frames_of_a_position_topic_are_checked(tmp_path):
    records = steps(2, lambda k, t: [("/truth", t, odometry_msg(1.0, 2.0, frame="/world",
                                                                child="robot")),
                                     ("/pose", t, pose_msg(3.0, 4.0, frame="map"))])
    path = write_bag(bag_path(tmp_path, "ros1"), "ros1", records)
    # ROS 1's leading slash is no part of the frame's name
    traj = read_rosbag(path, "/scan", "/action", position_topic="/truth",
                       position_frame="world", position_child_frame="/robot")
    assert traj.positions.tolist() == [[1, 2], [1, 2]]
    assert read_rosbag(path, "/scan", "/action", position_topic="/truth").positions.shape == (2, 2)
    with pytest.raises(ValueError, match=r"the positions on /truth are in the frame 'world', not "
                                         r"position_frame='map'"):
        read_rosbag(path, "/scan", "/action", position_topic="/truth", position_frame="map")
    with pytest.raises(ValueError, match=r"the positions on /truth place the frame 'robot', not "
                                         r"position_child_frame='base_link'"):
        read_rosbag(path, "/scan", "/action", position_topic="/truth",
                    position_child_frame="base_link")
    with pytest.raises(ValueError, match=r"position_child_frame='base_link' needs position "
                                         r"messages that name a child frame .* /pose carries "
                                         r"geometry_msgs/msg/PoseStamped"):
        read_rosbag(path, "/scan", "/action", position_topic="/pose",
                    position_child_frame="base_link")
    with pytest.raises(ParameterError, match="position_frame names the frame of the positions; "
                                             "give position_topic too"):
        read_rosbag(path, "/scan", "/action", position_frame="map")


def test_a_tf_topic_gives_the_translation_of_the_chosen_transform(tmp_path, fmt):
    # each /tf message holds map -> odom (10 + k, 0) and odom -> base_link (k, 2k); ROS 1 tools
    # wrote frames with a leading slash.  A /tf message with only map -> odom at 2.95 s is skipped
    def transforms(k, t):
        return [("/tf", t - 0.1, tf_msg(("/map", "odom", 10.0 + k, 0.0),
                                         ("odom", "/base_link", float(k), 2.0 * k)))]
    records = steps(3, transforms) + [("/tf", 2.95, tf_msg(("map", "odom", 99.0, 0.0)))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    base = read_rosbag(path, "/scan", "/action", position_topic="/tf", position_frame="odom",
                       position_child_frame="base_link")
    assert base.positions.tolist() == [[0, 0], [1, 2], [2, 4]]
    odom = read_rosbag(path, "/scan", "/action", position_topic="/tf", position_frame="map",
                       position_child_frame="odom")
    assert odom.positions.tolist() == [[10, 0], [11, 0], [99, 0]]  # 3 s: the 2.95 s message


def test_a_tf_topic_without_the_frames_lists_its_transforms(tmp_path):
    records = steps(2, lambda k, t: [("/tf", t, tf_msg(("map", "odom", 0.0, 0.0),
                                                       ("odom", "base_link", 1.0, 0.0)))])
    path = write_bag(bag_path(tmp_path, "ros1"), "ros1", records)
    with pytest.raises(ValueError, match=r"bag .*: position topic /tf is a tf2_msgs/msg/TFMessage:"
                                         r" set position_frame and position_child_frame .* \(its "
                                         r"transforms: map -> odom, odom -> base_link\)"):
        read_rosbag(path, "/scan", "/action", position_topic="/tf")
    with pytest.raises(ValueError, match=r"position topic /tf holds no transform from 'world' "
                                         r"\(position_frame\) to 'base_link' "
                                         r"\(position_child_frame\); its transforms: map -> odom, "
                                         r"odom -> base_link"):
        read_rosbag(path, "/scan", "/action", position_topic="/tf", position_frame="world",
                    position_child_frame="base_link")
