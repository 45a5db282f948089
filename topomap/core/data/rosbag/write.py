"""Writing a :class:`~topomap.core.data.trajectory.Trajectory` as ROS bags, one per episode."""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ..trajectory import Trajectory
from .common import (FLOAT64_ARRAY, INT32, LASER_SCAN, POSE_STAMPED, STRING, _positive, _rosbags,
                     names_topic)

__all__ = ["write_rosbag"]


def _episodes(traj: Trajectory) -> list[tuple[int, int]]:
    """``(start, stop)`` of every episode of ``traj``."""
    lengths = [len(traj)] if traj.lengths is None else traj.lengths.tolist()
    stops = np.cumsum(lengths).tolist()
    return list(zip([0] + stops[:-1], stops))


@dataclasses.dataclass(frozen=True)
class _WriteSpec:
    """How :func:`write_rosbag` lays a trajectory out as messages."""

    version: int
    storage: str
    scan: bool
    period_ns: int
    start_ns: int
    observation_topic: str
    action_topic: str
    gds_topic: str
    range_max: float
    position_topic: str


def _typestore(version: int):
    """The typestore whose message definitions are written into a bag of ``version``."""
    ts = _rosbags().typesys
    return ts.get_typestore(ts.Stores.ROS1_NOETIC if version == 1 else ts.Stores.ROS2_HUMBLE)


def _header(store, stamp_ns: int, seq: int, frame_id: str):
    """A ``std_msgs/Header`` (ROS 1 headers have a ``seq``, ROS 2 ones do not)."""
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    if "seq" in {f.name for f in dataclasses.fields(Header)}:
        return Header(seq=seq, stamp=stamp, frame_id=frame_id)
    return Header(stamp=stamp, frame_id=frame_id)


def _observation_message(store, row: np.ndarray, stamp_ns: int, seq: int, spec: _WriteSpec):
    """A LaserScan (float32 ranges) or Float64MultiArray holding observation ``row``."""
    if not spec.scan:
        types = store.types
        layout = types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        return types[FLOAT64_ARRAY](layout=layout, data=row.astype(np.float64))
    increment = 2 * math.pi / row.size
    return store.types[LASER_SCAN](
        header=_header(store, stamp_ns, seq, "base_scan"), angle_min=-math.pi,
        angle_max=-math.pi + (row.size - 1) * increment, angle_increment=increment,
        time_increment=0.0, scan_time=spec.period_ns / 1e9, range_min=0.0,
        range_max=spec.range_max, ranges=row.astype(np.float32),
        intensities=np.zeros(0, dtype=np.float32))


def _label(store, value: int, names: list | None):
    """A ``std_msgs/String`` with the name of id ``value``, or an ``Int32`` without names."""
    if names is None:
        return INT32, store.types[INT32](data=int(value))
    return STRING, store.types[STRING](data=names[value])


def _pose_message(store, position: np.ndarray, stamp_ns: int, seq: int):
    """A ``geometry_msgs/PoseStamped`` at ``position`` (x, y and, if given, z), facing +x."""
    types = store.types
    xyz = [float(v) for v in position] + [0.0] * (3 - position.size)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    return types[POSE_STAMPED](header=_header(store, stamp_ns, seq, "map"), pose=pose)


def _open_writer(out: Path, spec: _WriteSpec):
    """An unopened rosbags writer for a bag at ``out``."""
    rb = _rosbags()
    if spec.version == 1:
        return rb.rosbag1.Writer(out)
    plugin = {"sqlite3": rb.rosbag2.StoragePlugin.SQLITE3, "mcap": rb.rosbag2.StoragePlugin.MCAP}
    return rb.rosbag2.Writer(out, version=rb.rosbag2.Writer.VERSION_LATEST,
                             storage_plugin=plugin[spec.storage])


def _write_episode(out: Path, traj: Trajectory, start: int, stop: int, spec: _WriteSpec) -> None:
    """Write steps ``start:stop`` of ``traj`` as a bag at ``out``."""
    store = _typestore(spec.version)
    serialize = store.serialize_ros1 if spec.version == 1 else store.serialize_cdr
    obs_type = LASER_SCAN if spec.scan else FLOAT64_ARRAY
    act_type = STRING if traj.action_names is not None else INT32
    gds_type = STRING if traj.gds_names is not None else INT32
    with _open_writer(out, spec) as writer:
        conn = {"obs": writer.add_connection(spec.observation_topic, obs_type, typestore=store),
                "act": writer.add_connection(spec.action_topic, act_type, typestore=store)}
        if traj.gds is not None:
            conn["gds"] = writer.add_connection(spec.gds_topic, gds_type, typestore=store)
        if traj.positions is not None:
            conn["pos"] = writer.add_connection(spec.position_topic, POSE_STAMPED, typestore=store)
        if traj.action_names is not None:  # the names in id order, before the first step
            names = writer.add_connection(names_topic(spec.action_topic), STRING, typestore=store)
            for i, name in enumerate(traj.action_names):
                msg = store.types[STRING](data=str(name))
                stamp = spec.start_ns - len(traj.action_names) + i
                writer.write(names, stamp, serialize(msg, STRING))
        for k, t in enumerate(range(start, stop)):
            stamp = spec.start_ns + k * spec.period_ns
            msg = _observation_message(store, traj.observations[t], stamp, k, spec)
            writer.write(conn["obs"], stamp, serialize(msg, obs_type))
            typ, msg = _label(store, traj.actions[t], traj.action_names)
            writer.write(conn["act"], stamp, serialize(msg, typ))
            if traj.gds is not None and traj.gds[t] >= 0:
                typ, msg = _label(store, traj.gds[t], traj.gds_names)
                writer.write(conn["gds"], stamp, serialize(msg, typ))
            if traj.positions is not None:
                msg = _pose_message(store, traj.positions[t], stamp, k)
                writer.write(conn["pos"], stamp, serialize(msg, POSE_STAMPED))


def _target_paths(traj: Trajectory, path, version: int) -> list[Path]:
    """The bag path of each episode, checked: right count, right form, not existing yet."""
    episodes = _episodes(traj)
    if isinstance(path, (list, tuple)):
        targets = [Path(p) for p in path]
    elif len(episodes) == 1:
        targets = [Path(path)]
    else:
        raise ValueError(f"the trajectory has {len(episodes)} episodes; give a list of "
                         f"{len(episodes)} bag paths, one per episode")
    if len(targets) != len(episodes):
        raise ValueError(f"{len(targets)} bag paths given for {len(episodes)} episodes")
    if len(set(t.resolve() for t in targets)) != len(targets):
        raise ValueError("the bag paths must differ")
    for target in targets:
        if target.exists():
            raise ValueError(f"bag {target} exists already; not overwriting")
        if (version == 1) != (target.suffix == ".bag"):
            raise ValueError(f"ROS 1 bags are .bag files and ROS 2 bags folders not named .bag; "
                             f"{target} does not fit version {version}")
    return targets


def _write_spec(traj: Trajectory, version, storage, scan, rate, start_time, topics) -> _WriteSpec:
    """Validate the arguments of :func:`write_rosbag`."""
    if version not in (1, 2):
        raise ValueError(f"version must be 1 (ROS 1) or 2 (ROS 2), got {version!r}")
    if storage not in ("sqlite3", "mcap"):
        raise ValueError(f"storage must be 'sqlite3' or 'mcap', got {storage!r}")
    period_ns = round(1e9 / _positive("rate", rate))
    if period_ns < 1:
        raise ValueError(f"rate {rate!r} Hz is too high: steps need distinct nanosecond stamps")
    start_ns = round(_positive("start_time", start_time) * 1e9)
    obs_topic = topics[0] or ("/scan" if scan else "/observation")
    if len({obs_topic, *topics[1:]}) != 4:
        raise ValueError(f"the observation, action, GDS and position topics must differ, got "
                         f"{[obs_topic, *topics[1:]]!r}")
    return _WriteSpec(int(version), storage, bool(scan), period_ns, start_ns, obs_topic,
                      topics[1], topics[2], float(max(traj.observations.max(), 0.0)), topics[3])


def write_rosbag(traj: Trajectory, path, *, version: int = 1, storage: str = "sqlite3",
                 scan: bool = True, rate: float = 10.0, start_time: float = 1.7e9,
                 observation_topic: str | None = None, action_topic: str = "/action",
                 gds_topic: str = "/gds", position_topic: str = "/pose"):
    """Write ``traj`` as a ROS bag, one bag per episode; nothing appears unless all succeed.

    Step ``k`` of an episode is stamped ``start_time + k / rate`` seconds; its observation,
    action and (if any) GDS messages all carry that bag timestamp, so :func:`read_rosbag` with
    the same topics gives the steps back (use ``gds_window < 1 / (2 * rate)`` to get the GDS of
    exactly the steps that had one).

    Parameters
    ----------
    traj : Trajectory
    path : path or list of paths
        The bag (a single-episode trajectory) or one bag per episode.  ROS 1 bags are ``.bag``
        files; ROS 2 bags are folders.  Existing paths are never overwritten.
    version : 1 or 2
    storage : ``"sqlite3"`` or ``"mcap"``
        ROS 2 storage plugin (ignored for ROS 1).
    scan : bool
        True: observations as ``sensor_msgs/LaserScan`` ranges (float32, ``range_max`` the
        largest observation value, at least 0); False: as ``std_msgs/Float64MultiArray`` ``data``
        (exact; read back with ``observation_fields=["data"]``).
    rate : float
        Steps per second.
    start_time : float
        Bag time of the first step, in seconds since the epoch.
    observation_topic, action_topic, gds_topic, position_topic : str
        Topic names; the observation topic defaults to ``/scan`` (scan) or ``/observation``.
        Actions are ``std_msgs/String`` names (``Int32`` ids without ``action_names``), the
        names also on ``<action_topic>/names`` in id order (read back, they keep their ids); GDS
        likewise, written only at steps with a GDS; positions (if the trajectory has them) as
        ``geometry_msgs/PoseStamped`` (``z`` = 0 for positions in the plane), read back with
        ``read_rosbag(..., position_topic=...)``.

    Returns
    -------
    Path or list of Path, mirroring ``path``.
    """
    spec = _write_spec(traj, version, storage, scan, rate, start_time,
                       (observation_topic, action_topic, gds_topic, position_topic))
    targets = _target_paths(traj, path, spec.version)
    staging = []
    try:
        for target in targets:
            target.parent.mkdir(parents=True, exist_ok=True)
            staging.append(Path(tempfile.mkdtemp(prefix=".topomap-bag-", dir=target.parent)))
        for target, stage, (start, stop) in zip(targets, staging, _episodes(traj), strict=True):
            _write_episode(stage / target.name, traj, start, stop, spec)
        for target, stage in zip(targets, staging, strict=True):
            os.replace(stage / target.name, target)
    finally:
        for stage in staging:
            shutil.rmtree(stage, ignore_errors=True)
    return list(targets) if isinstance(path, (list, tuple)) else targets[0]
