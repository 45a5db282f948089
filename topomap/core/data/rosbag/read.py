"""Reading bags into a :class:`~topomap.core.data.trajectory.Trajectory` (see the package docstring)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..odometry import check_odometry
from ..trajectory import Trajectory
from ...checks import ParameterError
from .common import (STRING, _check_bag_path, _describe_failure, _one_line, _read_errors,
                     _rosbags, names_topic)
from .decode import (TransformPicker, action_decoder, gds_decoder, observation_decoder,
                     odometry_decoder, position_decoder)
from .options import Options, make_options

__all__ = ["read_rosbag"]


# ---------------------------------------------------------------------------------- one bag


@dataclasses.dataclass
class _Episode:
    """What one bag contributes: per step its observation row, action value, GDS value,
    position and odometry."""

    path: Path
    observations: np.ndarray
    actions: list
    gds: list | None
    dropped: int
    types: dict
    positions: np.ndarray | None = None
    declared: list | None = None  # the action names in id order, as the bag records them
    odometry: np.ndarray | None = None


def _topic_listing(topics: dict) -> str:
    """``/a (type, N messages), ...`` for the error message about a missing topic."""
    return ", ".join(f"{name} ({info.msgtype}, {info.msgcount} messages)"
                     for name, info in sorted(topics.items()))


def _topic_types(reader, opts: Options) -> dict:
    """Map each topic read to its message type, checking that it exists with one type."""
    topics = reader.topics
    if reader.message_count == 0:
        raise ValueError("empty, it has no messages")
    types = {}
    for role, topic in opts.roles():
        info = topics.get(topic)
        if info is None:
            raise ValueError(f"no {role} topic {topic}; its topics are: {_topic_listing(topics)}")
        if info.msgtype is None:
            raise ValueError(f"topic {topic} mixes several message types")
        types[topic] = info.msgtype
    return types


class _Rows:
    """Observation vectors kept in one growing 2-D array, not as one small array per message.

    (Hundreds of thousands of small arrays cost more than their data and, once freed, are not
    given back to the system; one large array is.)
    """

    def __init__(self, capacity: int):
        self.data = None
        self.n = 0
        self.capacity = max(int(capacity), 1)

    def append(self, row: np.ndarray) -> None:
        """Add ``row``, which must have as many values as the first row."""
        if self.data is None:
            self.data = np.empty((self.capacity, row.size), dtype=row.dtype)
        if row.size != self.data.shape[1]:
            raise ValueError(f"observation message {self.n} has {row.size} values but the first "
                             f"has {self.data.shape[1]}; all observations must have the same size")
        if self.n == self.data.shape[0]:
            self.data = np.concatenate([self.data, np.empty_like(self.data)])
        self.data[self.n] = row
        self.n += 1

    def take(self, order: np.ndarray) -> np.ndarray:
        """The rows in ``order`` (no copy when that is the order they came in)."""
        if self.data is None:
            return np.empty((0, 0))
        rows = self.data[: self.n]
        return rows if np.array_equal(order, np.arange(self.n)) else rows[order]


def _collect(reader, types: dict, decoders: dict, obs_topic: str) -> dict:
    """Read and decode every message of the chosen topics, in time order.

    Returns ``{topic: (times, values)}``: the values are a 2-D array for ``obs_topic`` and a
    list for the other topics.
    """
    counts = {t: info.msgcount for t, info in reader.topics.items()}
    streams = {topic: ([], _Rows(counts[topic]) if topic == obs_topic else []) for topic in types}
    connections = [c for c in reader.connections if c.topic in types]
    for conn, stamp, raw in reader.messages(connections=connections):
        times, values = streams[conn.topic]
        times.append(stamp)
        values.append(decoders[conn.topic](reader.deserialize(raw, conn.msgtype)))
    result = {}
    for topic, (times, values) in streams.items():
        t = np.asarray(times, dtype=np.int64)
        order = np.argsort(t, kind="stable")
        ordered = values.take(order) if isinstance(values, _Rows) else [values[i] for i in order]
        result[topic] = (t[order], ordered)
    return result


def _picked(streams: dict, decoders: dict) -> dict:
    """``streams`` with the messages of a transform topic that lack the chosen transform left
    out; a ValueError when none has it."""
    for topic, decode in decoders.items():
        if isinstance(decode, TransformPicker):
            times, values = streams[topic]
            has = [i for i, v in enumerate(values) if v is not None]
            if not has:
                raise ValueError(decode.missing())
            streams[topic] = (times[has], [values[i] for i in has])
    return streams


def _read_streams(path: Path, opts: Options):
    """Open the bag at ``path`` and return its topic types and decoded message streams.

    Every error becomes a one-line ValueError starting with ``bag PATH``.
    """
    rb = _rosbags()
    default = rb.typesys.get_typestore(rb.typesys.Stores.ROS2_HUMBLE)
    try:
        with rb.highlevel.AnyReader([path], default_typestore=default) as reader:
            types = _topic_types(reader, opts)
            obs, act = opts.observation_topic, opts.action_topic
            decoders = {obs: observation_decoder(types[obs], opts),
                        act: action_decoder(types[act], opts)}
            if opts.gds_topic is not None:
                decoders[opts.gds_topic] = gds_decoder(types[opts.gds_topic], opts)
            if opts.position_topic is not None:
                decoders[opts.position_topic] = position_decoder(types[opts.position_topic], opts)
            if opts.odometry_topic is not None:
                decoders[opts.odometry_topic] = odometry_decoder(types[opts.odometry_topic], opts)
            names = names_topic(act)
            info = reader.topics.get(names)
            if opts.action_names is None and info is not None and info.msgtype == STRING:
                types[names], decoders[names] = STRING, (lambda msg: str(msg.data))
            return types, _picked(_collect(reader, types, decoders, obs), decoders)
    except _read_errors() as exc:  # first: UnicodeDecodeError is a ValueError too
        raise ValueError(_describe_failure(path, exc)) from None
    except ValueError as exc:  # raised above without the path, or by a decoder
        raise ValueError(f"bag {path}: {_one_line(exc)}") from None


def _select_rows(rows: np.ndarray, index: np.ndarray, path: Path, topic: str) -> np.ndarray:
    """The observation of each step (``rows[index]``), checked to be non-empty and finite."""
    if rows.shape[1] == 0:
        raise ValueError(f"bag {path}: the observations on {topic} are empty (0 values)")
    X = rows if np.array_equal(index, np.arange(rows.shape[0])) else rows[index]
    finite = np.isfinite(X).all(axis=1)
    if not finite.all():
        bad = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"bag {path}: observation at step {bad} (from {topic}) contains NaN or "
                         "inf (for a LaserScan whose range_max is not finite, set max_range)")
    return X


def _match_gds(step_t: np.ndarray, gds_t: np.ndarray, window_ns: float) -> np.ndarray:
    """Index of the GDS message nearest each step within the window (earlier on a tie), or -1."""
    if gds_t.size == 0:
        return np.full(step_t.size, -1, dtype=np.int64)
    right = np.searchsorted(gds_t, step_t, side="left")
    left = np.clip(right - 1, 0, gds_t.size - 1)
    right = np.clip(right, 0, gds_t.size - 1)
    d_left, d_right = np.abs(step_t - gds_t[left]), np.abs(gds_t[right] - step_t)
    nearest = np.where(d_left <= d_right, left, right)
    return np.where(np.minimum(d_left, d_right) <= window_ns, nearest, -1)


#: how the messages of each role are named in an error: plural, and one of them
_NOUNS = {"observation": ("observations", "an observation"),
          "position": ("positions", "a position"),
          "odometry": ("odometry messages", "an odometry pose")}


def _no_step_left(path: Path, role: str, times: np.ndarray, topic: str, act_t: np.ndarray,
                  action_topic: str) -> str:
    """The message for a bag whose every step comes before the first message on ``topic``."""
    many, one = _NOUNS[role]
    return (f"bag {path}: all {times.size} {many} on {topic} come after the last action on "
            f"{action_topic} (first {role} at {times[0] / 1e9:.3f} s, last action at "
            f"{act_t[-1] / 1e9:.3f} s), so no step has {one}")


def _read_episode(path: Path, opts: Options) -> _Episode:
    """Read one bag into the steps of one episode."""
    _check_bag_path(path)
    types, streams = _read_streams(path, opts)
    for role, topic in opts.roles():
        if role != "GDS" and streams[topic][0].size == 0:
            raise ValueError(f"bag {path}: no messages on the {role} topic {topic}")
    obs_t, obs_rows = streams[opts.observation_topic]
    act_t, act_values = streams[opts.action_topic]
    obs_idx = np.searchsorted(obs_t, act_t, side="right") - 1
    keep = obs_idx >= 0
    if not keep.any():
        raise ValueError(_no_step_left(path, "observation", obs_t, opts.observation_topic,
                                       act_t, opts.action_topic))
    latest = {}  # role -> (values, index of each step's latest message)
    for role, topic in (("position", opts.position_topic), ("odometry", opts.odometry_topic)):
        if topic is None:
            continue
        times, values = streams[topic]
        latest[role] = (values, np.searchsorted(times, act_t, side="right") - 1)
        keep &= latest[role][1] >= 0
        if not keep.any():
            raise ValueError(_no_step_left(path, role, times, topic, act_t, opts.action_topic))
    keep = np.flatnonzero(keep)
    X = _select_rows(obs_rows, obs_idx[keep], path, opts.observation_topic)
    sampled = {role: np.asarray(values, dtype=np.float64)[index[keep]]
               for role, (values, index) in latest.items()}
    gds = None
    if opts.gds_topic is not None:
        gds_t, gds_values = streams[opts.gds_topic]
        match = _match_gds(act_t[keep], gds_t, opts.gds_window * 1e9)
        gds = [None if m < 0 else gds_values[m] for m in match.tolist()]
    declared = streams.get(names_topic(opts.action_topic), (None, None))[1]
    odometry = sampled.get("odometry")
    if odometry is not None:
        try:
            check_odometry(odometry, odometry.shape[0])
        except ValueError as exc:
            raise ValueError(f"bag {path}: odometry topic {opts.odometry_topic}: {exc}") from None
    return _Episode(path, X, [act_values[i] for i in keep.tolist()], gds,
                    int(act_t.size - keep.size), types, sampled.get("position"), declared,
                    odometry)


# ---------------------------------------------------------------------------------- assembly


def _encode(values: list, names: list | None, what: str, source: str):
    """Turn step values (names or ids; None = no value) into ``(ids, names)``.

    Names get ids in order of first appearance unless ``names`` fixes them; ids are kept.
    """
    present = [v for v in values if v is not None]
    kinds = {isinstance(v, str) for v in present}
    if len(kinds) > 1:
        raise ValueError(f"{source}: the {what} values mix names and numeric ids")
    if kinds == {True}:
        table = {n: i for i, n in enumerate(names)} if names is not None else {}
        for v in present:
            if v not in table:
                if names is not None:
                    raise ValueError(f"{source}: {what} {v!r} is not one of the given {what}_names "
                                     f"{names}")
                table[v] = len(table)
        ids = [-1 if v is None else table[v] for v in values]
        return np.asarray(ids, dtype=np.int64), list(table)
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in present):
        raise ValueError(f"{source}: the {what} values must be names (str) or ids (int)")
    if present and min(present) < 0:
        raise ValueError(f"{source}: {what} ids must be >= 0, found {int(min(present))}")
    ids = np.asarray([-1 if v is None else int(v) for v in values], dtype=np.int64)
    return ids, names


def _assemble(episodes: list, opts: Options, many: bool) -> Trajectory:
    """Concatenate the episodes into one :class:`Trajectory`."""
    source = f"bag {episodes[0].path}" if len(episodes) == 1 else \
        f"bags {', '.join(str(e.path) for e in episodes)}"
    X = episodes[0].observations if len(episodes) == 1 else \
        np.concatenate([e.observations for e in episodes])
    for e in episodes:
        e.observations = None  # let each episode's rows go once concatenated
    if opts.scan_bins is not None:
        X = _reduce_bins(X, opts.scan_bins, source, opts.observation_topic)
    declared = opts.action_names or next((e.declared for e in episodes if e.declared), None)
    actions, action_names = _encode([a for e in episodes for a in e.actions], declared,
                                     "action", source)
    gds, gds_names = (None, None) if opts.gds_topic is None else _encode(
        [g for e in episodes for g in e.gds], opts.gds_names, "gds", source)
    meta = {"source": "rosbag", "bags": [str(e.path) for e in episodes],
            "topics": episodes[0].types, "dropped_steps": [e.dropped for e in episodes]}
    lengths = [len(e.actions) for e in episodes] if many else None
    odometry = None if opts.odometry_topic is None else \
        np.concatenate([e.odometry for e in episodes])
    try:
        return Trajectory(observations=X, actions=actions, gds=gds, lengths=lengths,
                          action_names=action_names, gds_names=gds_names, meta=meta,
                          positions=_positions(episodes, opts), odometry=odometry)
    except ValueError as exc:
        raise ValueError(f"{source}: {_one_line(exc)}") from None


def _positions(episodes: list, opts: Options) -> np.ndarray | None:
    """The steps' positions, ``(T, 3)`` when some ``z`` is not 0, else ``(T, 2)``; or None."""
    if opts.position_topic is None:
        return None
    P = np.concatenate([e.positions for e in episodes])
    return P if P[:, 2].any() else P[:, :2]


def _reduce_bins(X: np.ndarray, bins: int, source: str, topic: str) -> np.ndarray:
    """Reduce each scan to ``bins`` sectors holding the minimum range of their beams."""
    beams = X.shape[1]
    if bins > beams:
        raise ValueError(f"{source}: scan_bins={bins} exceeds the {beams} beams of the scans "
                         f"on {topic}")
    starts = (np.arange(bins) * beams) // bins
    return np.minimum.reduceat(X, starts, axis=1)


def _bag_list(path) -> tuple[list[Path], bool]:
    """The bag paths of ``path`` and whether a list (one episode per bag) was given."""
    if isinstance(path, (list, tuple)):
        if not path:
            raise ParameterError("path", "is an empty list; give at least one bag")
        return [Path(p) for p in path], True
    return [Path(path)], False


def read_rosbag(path, observation_topic: str, action_topic: str, *, observation_fields=None,
                scan_bins: int | None = None, max_range: float | None = None,
                gds_topic: str | None = None, gds_window: float = 0.5, action_names=None,
                gds_names=None, linear_threshold: float = 0.05, angular_threshold: float = 0.1,
                action_rule=None, position_topic: str | None = None,
                position_frame: str | None = None, position_child_frame: str | None = None,
                odometry_topic: str | None = None) -> Trajectory:
    """Read one ROS bag, or a list of bags (one episode each), into a :class:`Trajectory`.

    Parameters
    ----------
    path : path or list of paths
        A ROS 1 ``.bag`` file, a ROS 2 bag folder or ``.db3``/``.mcap`` file; a list gives one
        episode per bag, in order (``lengths``).
    observation_topic, action_topic : str
        One step per action message; its observation the latest observation message at or before
        it (steps before the first observation, or position or odometry, are dropped).
    observation_fields : list of str, optional
        Numeric fields of observation messages of any type (dotted paths; an array field gives a
        column per element); without it the topic must carry ``sensor_msgs/LaserScan``.
    scan_bins, max_range : int, float, optional
        Sectors per scan (each its beams' minimum); ranges clipped (``inf``, ``nan``: range_max).
    gds_topic, gds_window : str, float
        ``String`` or ``Int32`` topic of globally distinctive states; a step gets the GDS of the
        nearest GDS message at most ``gds_window`` s away.
    action_names, gds_names : list of str, optional
        Fix the id of each name (other names are an error); for Int32 topics, name the ids.
    linear_threshold, angular_threshold, action_rule : float, float, callable
        m/s and rad/s of :func:`~topomap.core.data.rosbag.decode.twist_action` for Twist action
        topics; ``action_rule(message) -> name or id`` reads action messages of any type.
    position_topic : str, optional
        The ground truth (a motion capture's, a simulator's) as ``positions``: a pose
        (``rosbag.POSITION_TYPES``), ``(T, 3)`` if some ``z`` is not 0; in the frame ``odom``
        (the robot's own, REP 105) only with ``position_frame="odom"``.
    position_frame, position_child_frame : str, optional
        The messages' ``header.frame_id`` and (where they have one) ``child_frame_id`` must be
        these.  A ``tf2_msgs/TFMessage`` topic needs both: the position is the translation of the
        transform ``position_frame`` -> ``position_child_frame``.
    odometry_topic : str, optional
        The robot's own dead reckoning as ``odometry`` (x, y and the orientation's yaw):
        ``nav_msgs/Odometry``, ``PoseStamped``, ... (``rosbag.ODOMETRY_TYPES``).

    Returns
    -------
    Trajectory
        Observations (float64), actions and, with their topics, ``gds``, ``positions``,
        ``odometry``; ``lengths`` (``path`` a list), the names, and ``meta``: ``source``,
        ``bags``, ``topics`` (topic -> type) and ``dropped_steps`` (per bag).

    Raises
    ------
    ValueError
        One line naming the file: a missing topic (listing the bag's), an unsupported type, a bad
        bag, no step left, a jump of the odometry, positions in another frame than asked.
    """
    kw = dict(locals())  # the arguments, as make_options checks them
    opts = make_options(kw.pop("observation_topic"), kw.pop("action_topic"), kw)
    paths, many = _bag_list(path)
    episodes = [_read_episode(p, opts) for p in paths]
    return _assemble(episodes, opts, many)
