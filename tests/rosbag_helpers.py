"""Helpers for the ROS bag tests: real bags written with rosbags' own writers, in all formats."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

#: format name -> (ROS version, ROS 2 storage)
FORMATS = {"ros1": (1, "sqlite3"), "sqlite3": (2, "sqlite3"), "mcap": (2, "mcap")}
STORES = {1: get_typestore(Stores.ROS1_NOETIC), 2: get_typestore(Stores.ROS2_HUMBLE)}
# ROS 1's standard typestore lacks tf2_msgs/TFMessage: its definition, as in ROS's tf2_msgs
STORES[1].register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms\n",
                                      "tf2_msgs/msg/TFMessage"))


@pytest.fixture(params=list(FORMATS))
def fmt(request) -> str:
    """Each bag format in turn: ROS 1, ROS 2 sqlite3, ROS 2 MCAP."""
    return request.param


def bag_path(tmp_path: Path, fmt: str, name: str = "run") -> Path:
    """Where a bag of format ``fmt`` named ``name`` goes (ROS 1: a .bag file; ROS 2: a folder)."""
    return tmp_path / (name + ".bag" if FORMATS[fmt][0] == 1 else name)


def write_bag(path: Path, fmt: str, records) -> Path:
    """Write ``records``, ``(topic, seconds, build)`` with ``build(store) -> message``, as a bag.

    Topics are registered with the type of their first message; a topic whose ``build`` is None
    is registered (with the type given as ``seconds``) but gets no message.
    """
    version, storage = FORMATS[fmt]
    store = STORES[version]
    if version == 1:
        writer, serialize = Writer1(path), store.serialize_ros1
    else:
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer, serialize = Writer2(path, version=9, storage_plugin=plugin), store.serialize_cdr
    with writer:
        conns = {}
        for topic, seconds, build in records:
            if build is None:
                conns[topic] = writer.add_connection(topic, seconds, typestore=store)
                continue
            msg = build(store)
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=store)
            writer.write(conns[topic], round(seconds * 1e9), serialize(msg, msg.__msgtype__))
    return path


def header(store, seq: int = 0, frame: str = "laser"):
    """A header in ``frame`` stamped at zero (ROS 1 headers have a seq)."""
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    if "seq" in Header.__dataclass_fields__:
        return Header(seq=seq, stamp=Time(sec=0, nanosec=0), frame_id=frame)
    return Header(stamp=Time(sec=0, nanosec=0), frame_id=frame)


def scan(ranges, range_max: float = 10.0):
    """Builder of a LaserScan with ``ranges``."""
    ranges = np.asarray(ranges, dtype=np.float32)

    def build(store):
        return store.types["sensor_msgs/msg/LaserScan"](
            header=header(store), angle_min=-math.pi, angle_max=math.pi,
            angle_increment=2 * math.pi / max(ranges.size, 1), time_increment=0.0, scan_time=0.1,
            range_min=0.0, range_max=range_max, ranges=ranges,
            intensities=np.zeros(0, dtype=np.float32))
    return build


def string(text: str):
    """Builder of a std_msgs/String."""
    return lambda store: store.types["std_msgs/msg/String"](data=text)


def int32(value: int):
    """Builder of a std_msgs/Int32."""
    return lambda store: store.types["std_msgs/msg/Int32"](data=value)


def float32(value: float):
    """Builder of a std_msgs/Float32 (a type no topic role supports)."""
    return lambda store: store.types["std_msgs/msg/Float32"](data=value)


def twist(vx: float, wz: float, stamped: bool = False):
    """Builder of a geometry_msgs/Twist (or TwistStamped) with linear.x and angular.z."""
    def build(store):
        V = store.types["geometry_msgs/msg/Vector3"]
        tw = store.types["geometry_msgs/msg/Twist"](linear=V(x=vx, y=0.0, z=0.0),
                                                    angular=V(x=0.0, y=0.0, z=wz))
        if stamped:
            return store.types["geometry_msgs/msg/TwistStamped"](header=header(store), twist=tw)
        return tw
    return build


def pose(x: float, y: float):
    """Builder of a geometry_msgs/PoseStamped at (x, y)."""
    def build(store):
        t = store.types
        return t["geometry_msgs/msg/PoseStamped"](
            header=header(store),
            pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                             orientation=t["geometry_msgs/msg/Quaternion"](
                                                 x=0.0, y=0.0, z=0.0, w=1.0)))
    return build


def simple_records(n: int = 5, actions=("a", "b")):
    """``n`` steps, 1 s apart: a 3-beam scan ``[k, k, k]`` then a String action 0.5 s later."""
    records = []
    for k in range(n):
        records.append(("/scan", float(k), scan([k, k, k])))
        records.append(("/action", k + 0.5, string(actions[k % len(actions)])))
    return records


def _pose(store, x: float, y: float, yaw: float):
    """A geometry_msgs/Pose at (x, y, 0) turned ``yaw`` radians about z."""
    t = store.types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                      w=math.cos(yaw / 2)))


def odometry_msg(x: float, y: float, yaw: float = 0.0, frame: str = "odom",
                 child: str = "base_link"):
    """Builder of a nav_msgs/Odometry in ``frame`` at (x, y) facing ``yaw``."""
    def build(store):
        t = store.types
        V = t["geometry_msgs/msg/Vector3"]
        tw = t["geometry_msgs/msg/Twist"](linear=V(x=0.0, y=0.0, z=0.0),
                                          angular=V(x=0.0, y=0.0, z=0.0))
        return t["nav_msgs/msg/Odometry"](
            header=header(store, frame=frame), child_frame_id=child,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=_pose(store, x, y, yaw),
                                                           covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36)))
    return build


def pose_msg(x: float, y: float, yaw: float = 0.0, frame: str = "map"):
    """Builder of a geometry_msgs/PoseStamped in ``frame`` at (x, y) facing ``yaw``."""
    return lambda store: store.types["geometry_msgs/msg/PoseStamped"](
        header=header(store, frame=frame), pose=_pose(store, x, y, yaw))


def tf_msg(*transforms):
    """Builder of a tf2_msgs/TFMessage of ``(parent, child, x, y)`` transforms (no rotation)."""
    def build(store):
        t = store.types
        return t["tf2_msgs/msg/TFMessage"](transforms=[
            t["geometry_msgs/msg/TransformStamped"](
                header=header(store, frame=parent), child_frame_id=child,
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                    rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
            for parent, child, x, y in transforms])
    return build
