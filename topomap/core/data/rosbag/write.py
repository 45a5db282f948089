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
from .common import (FLOAT64_ARRAY, INT32, LASER_SCAN, ODOMETRY, POSE_STAMPED, STRING, TF_MESSAGE,
                     TWIST, _positive, _rosbags, names_topic)
from .messages import (TWIST_OF_ACTION, header, odometry_message, odometry_twists, pose_message,
                       tf_message, twist_message, typestore)

__all__ = ["write_rosbag"]


def _episodes(traj: Trajectory) -> list[tuple[int, int]]:
    """``(start, stop)`` of every episode of ``traj``."""
    lengths = [len(traj)] if traj.lengths is None else traj.lengths.tolist()
    stops = np.cumsum(lengths).tolist()
    return list(zip([0] + stops[:-1], stops))


@dataclasses.dataclass(frozen=True)
class _WriteSpec:
    """How :func:`write_rosbag` lays a trajectory out as messages; ``topics`` maps each role
    (``observation``, ``action``, ``gds``, ``position``, ``odometry``, ``tf``, ``cmd_vel``) to its
    topic, or None for a role not written."""

    version: int
    storage: str
    scan: bool
    period_ns: int
    start_ns: int
    range_max: float
    topics: dict


def _observation_message(store, row: np.ndarray, stamp_ns: int, seq: int, spec: _WriteSpec):
    """A LaserScan (float32 ranges) or Float64MultiArray holding observation ``row``."""
    if not spec.scan:
        types = store.types
        layout = types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        return types[FLOAT64_ARRAY](layout=layout, data=row.astype(np.float64))
    increment = 2 * math.pi / row.size  # beam 0 ahead, anticlockwise: the arena's own frame
    return store.types[LASER_SCAN](
        header=header(store, stamp_ns, seq, "base_scan"), angle_min=0.0,
        angle_max=(row.size - 1) * increment, angle_increment=increment,
        time_increment=0.0, scan_time=spec.period_ns / 1e9, range_min=0.0,
        range_max=spec.range_max, ranges=row.astype(np.float32),
        intensities=np.zeros(0, dtype=np.float32))


def _label(store, value: int, names: list | None):
    """A ``std_msgs/String`` with the name of id ``value``, or an ``Int32`` without names."""
    if names is None:
        return store.types[INT32](data=int(value))
    return store.types[STRING](data=names[value])


def _open_writer(out: Path, spec: _WriteSpec):
    """An unopened rosbags writer for a bag at ``out``."""
    rb = _rosbags()
    if spec.version == 1:
        return rb.rosbag1.Writer(out)
    plugin = {"sqlite3": rb.rosbag2.StoragePlugin.SQLITE3, "mcap": rb.rosbag2.StoragePlugin.MCAP}
    return rb.rosbag2.Writer(out, version=rb.rosbag2.Writer.VERSION_LATEST,
                             storage_plugin=plugin[spec.storage])


def _streams(store, traj: Trajectory, start: int, stop: int, spec: _WriteSpec) -> dict:
    """``{role: (message type, make)}`` of each topic written, ``make(t, k, stamp)`` the message
    of step ``t`` (the ``k``-th of the episode) or None for no message at that step."""
    names = traj.action_names
    streams = {"observation": (LASER_SCAN if spec.scan else FLOAT64_ARRAY,
                               lambda t, k, ns: _observation_message(
                                   store, traj.observations[t], ns, k, spec)),
               "action": (STRING if names is not None else INT32,
                          lambda t, k, ns: _label(store, traj.actions[t], names))}
    if traj.gds is not None:
        streams["gds"] = (STRING if traj.gds_names is not None else INT32,
                          lambda t, k, ns: None if traj.gds[t] < 0 else
                          _label(store, traj.gds[t], traj.gds_names))
    if traj.positions is not None:
        streams["position"] = (POSE_STAMPED,
                               lambda t, k, ns: pose_message(store, traj.positions[t], ns, k))
    if traj.odometry is not None:
        odo = traj.odometry
        velocity = odometry_twists(odo[start:stop], spec.period_ns / 1e9)
        streams["odometry"] = (ODOMETRY, lambda t, k, ns: odometry_message(
            store, odo[t], velocity[k], ns, k))
        streams["tf"] = (TF_MESSAGE, lambda t, k, ns: tf_message(store, odo[t], ns, k))
    if spec.topics["cmd_vel"] is not None:
        streams["cmd_vel"] = (TWIST, lambda t, k, ns: twist_message(
            store, *TWIST_OF_ACTION[names[traj.actions[t]]]))
    return {role: kind for role, kind in streams.items() if spec.topics[role] is not None}


def _write_episode(out: Path, traj: Trajectory, start: int, stop: int, spec: _WriteSpec) -> None:
    """Write steps ``start:stop`` of ``traj`` as a bag at ``out``."""
    store = typestore(spec.version)
    serialize = store.serialize_ros1 if spec.version == 1 else store.serialize_cdr
    streams = _streams(store, traj, start, stop, spec)
    with _open_writer(out, spec) as writer:
        conns = {role: writer.add_connection(spec.topics[role], typ, typestore=store)
                 for role, (typ, _) in streams.items()}
        if traj.action_names is not None and spec.topics["action"] is not None:
            names = writer.add_connection(names_topic(spec.topics["action"]), STRING,
                                          typestore=store)
            for i, name in enumerate(traj.action_names):  # in id order, before the first step
                msg = store.types[STRING](data=str(name))
                stamp = spec.start_ns - len(traj.action_names) + i
                writer.write(names, stamp, serialize(msg, STRING))
        for k, t in enumerate(range(start, stop)):
            stamp = spec.start_ns + k * spec.period_ns
            for role, (typ, make) in streams.items():
                msg = make(t, k, stamp)
                if msg is not None:
                    writer.write(conns[role], stamp, serialize(msg, typ))


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


def _check_commands(traj: Trajectory) -> None:
    """A ValueError unless every action of ``traj`` has a velocity command
    (:data:`~topomap.core.data.rosbag.messages.TWIST_OF_ACTION`)."""
    if traj.action_names is None:
        raise ValueError("cmd_vel_topic writes each action as the velocity command of its name, "
                         "and the trajectory has no action_names")
    used = [traj.action_names[i] for i in np.unique(traj.actions).tolist()]
    unknown = [name for name in used if name not in TWIST_OF_ACTION]
    if unknown:
        raise ValueError(f"cmd_vel_topic writes each action as the velocity command of its name, "
                         f"and the action {unknown[0]!r} has none; commands exist for "
                         f"{', '.join(TWIST_OF_ACTION)}")


def _write_spec(traj: Trajectory, version, storage, scan, rate, start_time, topics) -> _WriteSpec:
    """Validate the arguments of :func:`write_rosbag` (``topics``: role -> topic or None)."""
    if version not in (1, 2):
        raise ValueError(f"version must be 1 (ROS 1) or 2 (ROS 2), got {version!r}")
    if storage not in ("sqlite3", "mcap"):
        raise ValueError(f"storage must be 'sqlite3' or 'mcap', got {storage!r}")
    period_ns = round(1e9 / _positive("rate", rate))
    if period_ns < 1:
        raise ValueError(f"rate {rate!r} Hz is too high: steps need distinct nanosecond stamps")
    start_ns = round(_positive("start_time", start_time) * 1e9)
    topics = {role: topic or None for role, topic in topics.items()}
    topics["observation"] = topics["observation"] or ("/scan" if scan else "/observation")
    given = [(role, t) for role, t in topics.items() if t is not None]
    for i, (role, topic) in enumerate(given):
        same = [other for other, t in given[i + 1:] if t == topic]
        if same:
            raise ValueError(f"topics must differ: {role}_topic and {same[0]}_topic are both "
                             f"{topic}")
    if topics["action"] is None and topics["cmd_vel"] is None:
        raise ValueError("action_topic and cmd_vel_topic are both None: the actions need one")
    if topics["cmd_vel"] is not None:
        _check_commands(traj)
    return _WriteSpec(int(version), storage, bool(scan), period_ns, start_ns,
                      float(max(traj.observations.max(), 0.0)), topics)


def write_rosbag(traj: Trajectory, path, *, version: int = 1, storage: str = "sqlite3",
                 scan: bool = True, rate: float = 10.0, start_time: float = 1.7e9,
                 observation_topic: str | None = None, action_topic: str | None = "/action",
                 gds_topic: str | None = "/gds", position_topic: str | None = "/pose",
                 odometry_topic: str | None = "/odom", tf_topic: str | None = "/tf",
                 cmd_vel_topic: str | None = None):
    """Write ``traj`` as a ROS bag, one bag per episode; nothing appears unless all succeed.

    Step ``k`` of an episode is stamped ``start_time + k / rate`` seconds; all its messages carry
    that bag timestamp, so :func:`read_rosbag` with the same topics gives the steps back (use
    ``gds_window < 1 / (2 * rate)`` to get the GDS of exactly the steps that had one).  What each
    topic carries: :mod:`topomap.core.data.rosbag` (the package's docstring).

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
    rate, start_time : float
        Steps per second; bag time of the first step, in seconds since the epoch.
    observation_topic, action_topic, gds_topic, position_topic : str or None
        The observations (None: ``/scan``, or ``/observation`` without ``scan``), the actions'
        names or ids, the GDS, the ground truth (``geometry_msgs/PoseStamped`` in ``map``).
    odometry_topic, tf_topic, cmd_vel_topic : str or None
        The odometry (``nav_msgs/Odometry``), its transform ``odom`` -> ``base_link``
        (``tf2_msgs/TFMessage``) and the actions as velocity commands (``geometry_msgs/Twist``,
        :data:`~topomap.core.data.rosbag.messages.TWIST_OF_ACTION`; None by default).  A
        topic of None is not written, nor is a field the trajectory lacks.

    Returns
    -------
    Path or list of Path, mirroring ``path``.
    """
    spec = _write_spec(traj, version, storage, scan, rate, start_time, dict(
        observation=observation_topic, action=action_topic, gds=gds_topic,
        position=position_topic, odometry=odometry_topic, tf=tf_topic, cmd_vel=cmd_vel_topic))
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
