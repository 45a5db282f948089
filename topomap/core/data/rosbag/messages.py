"""The ROS messages :func:`~topomap.core.data.rosbag.write_rosbag` writes for a step: headers,
poses, odometry, transforms and velocity commands, in the frames of REP 105 (``map`` for the
ground truth, ``odom`` for the robot's dead reckoning, ``base_link`` the robot)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..odometry import quaternion_of_yaw
from .common import ODOM_FRAME, ODOMETRY, POSE_STAMPED, TF_MESSAGE, TWIST, _rosbags

__all__ = ["TWIST_OF_ACTION", "typestore", "header", "pose_message", "odometry_message",
           "tf_message", "twist_message", "odometry_twists"]

#: the velocity command ``(linear.x m/s, angular.z rad/s)`` written for each action name on
#: ``write_rosbag``'s ``cmd_vel_topic``: 0.2 m/s and 1.0 rad/s, a small indoor robot's cruising
#: speed and turn rate, each well beyond the thresholds that read a command back as an action
#: (:func:`~topomap.core.data.rosbag.decode.twist_action`: 0.05 m/s and 0.1 rad/s; the arena's
#: ``TurnActions``: 0.02 m/s and 0.5 rad/s), so that reading the bag gives every step its action
#: back.  The command names the action; the speeds measured are on the odometry topic.
TWIST_OF_ACTION = {"forward": (0.2, 0.0), "backward": (-0.2, 0.0), "turn_left": (0.0, 1.0),
                   "turn_right": (0.0, -1.0), "stop": (0.0, 0.0)}
#: the frames of REP 105 besides ``odom``: the ground truth's and the robot's own
MAP_FRAME, BASE_FRAME = "map", "base_link"
#: ``tf2_msgs/TFMessage`` in ROS 1's message language (ROS 1's standard typestore lacks it)
_TF_DEFINITION = "geometry_msgs/TransformStamped[] transforms\n"


def typestore(version: int):
    """The typestore whose message definitions are written into a bag of ``version``, with
    ``tf2_msgs/TFMessage`` (registered for ROS 1; its MD5 sum is the one ROS computes)."""
    ts = _rosbags().typesys
    store = ts.get_typestore(ts.Stores.ROS1_NOETIC if version == 1 else ts.Stores.ROS2_HUMBLE)
    if TF_MESSAGE not in store.types:
        store.register(ts.get_types_from_msg(_TF_DEFINITION, TF_MESSAGE))
    return store


def header(store, stamp_ns: int, seq: int, frame_id: str):
    """A ``std_msgs/Header`` (ROS 1 headers have a ``seq``, ROS 2 ones do not)."""
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    if "seq" in {f.name for f in dataclasses.fields(Header)}:
        return Header(seq=seq, stamp=stamp, frame_id=frame_id)
    return Header(stamp=stamp, frame_id=frame_id)


def _pose(store, xyz, yaw: float):
    """A ``geometry_msgs/Pose`` at ``xyz`` (x, y and, if given, z) facing ``yaw`` radians."""
    types = store.types
    xyz = [float(v) for v in xyz] + [0.0] * (3 - len(xyz))
    qx, qy, qz, qw = quaternion_of_yaw(float(yaw))
    return types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw))


def pose_message(store, position: np.ndarray, stamp_ns: int, seq: int):
    """A ``geometry_msgs/PoseStamped`` in ``map`` at ``position`` (x, y and, if given, z),
    facing +x: the ground truth of a step."""
    return store.types[POSE_STAMPED](header=header(store, stamp_ns, seq, MAP_FRAME),
                                     pose=_pose(store, position, 0.0))


def _vector(store, x: float = 0.0, y: float = 0.0, z: float = 0.0):
    return store.types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))


def twist_message(store, linear_x: float, angular_z: float, linear_y: float = 0.0):
    """A ``geometry_msgs/Twist`` (m/s along the robot's x and y, rad/s about z)."""
    return store.types[TWIST](linear=_vector(store, linear_x, linear_y),
                              angular=_vector(store, z=angular_z))


def odometry_message(store, odometry: np.ndarray, velocity: np.ndarray, stamp_ns: int, seq: int):
    """A ``nav_msgs/Odometry`` from ``odom`` to ``base_link``: the pose ``odometry`` (x, y,
    heading) and the twist ``velocity`` (m/s forward, m/s to the left, rad/s), covariances 0."""
    types = store.types
    zeros = np.zeros(36, dtype=np.float64)
    return types[ODOMETRY](
        header=header(store, stamp_ns, seq, ODOM_FRAME), child_frame_id=BASE_FRAME,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=_pose(store, odometry[:2], odometry[2]), covariance=zeros),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=twist_message(store, velocity[0], velocity[2], velocity[1]), covariance=zeros))


def tf_message(store, odometry: np.ndarray, stamp_ns: int, seq: int):
    """A ``tf2_msgs/TFMessage`` holding the one transform ``odom`` -> ``base_link`` of the pose
    ``odometry`` (x, y, heading), as a robot's odometry publishes it."""
    types = store.types
    qx, qy, qz, qw = quaternion_of_yaw(float(odometry[2]))
    transform = types["geometry_msgs/msg/TransformStamped"](
        header=header(store, stamp_ns, seq, ODOM_FRAME), child_frame_id=BASE_FRAME,
        transform=types["geometry_msgs/msg/Transform"](
            translation=_vector(store, odometry[0], odometry[1]),
            rotation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)))
    return types[TF_MESSAGE](transforms=[transform])


def odometry_twists(odometry: np.ndarray, period_s: float) -> np.ndarray:
    """``(T, 3)``: at each step the velocity over the step before it, in the robot's frame of that
    step's start (m/s forward, m/s to the left, rad/s anticlockwise); 0 at the first step."""
    out = np.zeros((odometry.shape[0], 3))
    if odometry.shape[0] < 2:
        return out
    d = np.diff(odometry, axis=0)
    c, s = np.cos(odometry[:-1, 2]), np.sin(odometry[:-1, 2])
    out[1:, 0] = (c * d[:, 0] + s * d[:, 1]) / period_s
    out[1:, 1] = (-s * d[:, 0] + c * d[:, 1]) / period_s
    out[1:, 2] = np.angle(np.exp(1j * d[:, 2])) / period_s
    return out
