"""Messages into step values: observation vectors, and action and GDS names or ids.

Each ``*_decoder`` returns a function of one deserialised message, chosen by the topic's message
type and the :class:`~topomap.core.data.rosbag.options.Options` of the read, or raises a
ValueError saying why the type cannot be read.  A ``tf2_msgs/TFMessage`` position topic's decoder
is a :class:`TransformPicker`, which gives None for a message without the chosen transform.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..odometry import yaw_of_quaternion
from .common import (ACTION_TYPES, CHILD_FRAME_TYPES, GDS_TYPES, INT32, LASER_SCAN, ODOM_FRAME,
                     ODOMETRY_TYPES, POSITION_TYPES, STRING, TF_MESSAGE, TWIST, TWIST_STAMPED)
from .options import Options

__all__ = ["twist_action", "observation_decoder", "action_decoder", "gds_decoder",
           "position_decoder", "odometry_decoder", "TransformPicker"]


def twist_action(linear_x: float, angular_z: float, linear_threshold: float = 0.05,
                 angular_threshold: float = 0.1) -> str:
    """Name of the discrete action for a velocity command (m/s, rad/s; REP 103 axes).

    Turning wins over driving: ``angular_z >= angular_threshold`` is ``"turn_left"``,
    ``angular_z <= -angular_threshold`` is ``"turn_right"``; otherwise
    ``linear_x >= linear_threshold`` is ``"forward"``, ``linear_x <= -linear_threshold`` is
    ``"backward"``, and anything slower is ``"stop"``.
    """
    if angular_z >= angular_threshold:
        return "turn_left"
    if angular_z <= -angular_threshold:
        return "turn_right"
    if linear_x >= linear_threshold:
        return "forward"
    if linear_x <= -linear_threshold:
        return "backward"
    return "stop"


def _field_value(msg, dotted: str, msgtype: str):
    """The value at the dotted field path ``dotted`` of ``msg``."""
    value = msg
    for depth, part in enumerate(dotted.split(".")):
        is_message = dataclasses.is_dataclass(value)
        names = [f.name for f in dataclasses.fields(value)] if is_message else []
        if part not in names:
            where = ".".join(dotted.split(".")[:depth]) or msgtype
            raise ValueError(f"field {dotted!r} not found in {msgtype}: {where} has fields "
                             f"{', '.join(names) or '(none: it is a value)'}")
        value = getattr(value, part)
    return value


def _numeric(value, dotted: str, msgtype: str) -> np.ndarray:
    """A field's value as a flat float64 array, or a ValueError if it is not numeric."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"field {dotted!r} of {msgtype} is not numeric (it holds "
                         f"{type(value).__name__} values)")
    return arr.astype(np.float64).ravel()


def _fields_decoder(fields: tuple, msgtype: str):
    """A function turning a message of ``msgtype`` into the vector of its ``fields``."""
    def decode(msg) -> np.ndarray:
        """The concatenated values of the fields of ``msg``."""
        parts = [_numeric(_field_value(msg, f, msgtype), f, msgtype) for f in fields]
        return np.concatenate(parts)
    return decode


def _scan_decoder(max_range: float | None):
    """A function turning a LaserScan into its float32 ranges (inf/nan -> range_max, clipped)."""
    def decode(msg) -> np.ndarray:
        """The processed ranges of scan ``msg``."""
        ranges = np.array(msg.ranges, dtype=np.float32)
        ranges[~np.isfinite(ranges)] = msg.range_max
        if max_range is not None:
            np.fmin(ranges, np.float32(max_range), out=ranges)
        return ranges
    return decode


def observation_decoder(msgtype: str, opts: Options):
    """The decoder for observation messages of ``msgtype``, or a ValueError."""
    if opts.observation_fields is not None:
        if opts.scan_bins is not None or opts.max_range is not None:
            raise ValueError("scan_bins and max_range apply to LaserScan ranges; they cannot be "
                             "combined with observation_fields")
        return _fields_decoder(opts.observation_fields, msgtype)
    if msgtype == LASER_SCAN:
        return _scan_decoder(opts.max_range)
    raise ValueError(f"observation topic {opts.observation_topic} has type {msgtype}, which is not "
                     f"supported: without observation_fields only {LASER_SCAN} is read; pass "
                     "observation_fields=[...] to read numeric fields by name (e.g. "
                     "'pose.position.x')")


def action_decoder(msgtype: str, opts: Options):
    """The decoder for action messages of ``msgtype`` (message -> name or id), or a ValueError."""
    if opts.action_rule is not None:
        return opts.action_rule
    if msgtype in (STRING, INT32):
        return lambda msg: msg.data
    lin, ang = opts.linear_threshold, opts.angular_threshold
    if msgtype == TWIST:
        return lambda msg: twist_action(msg.linear.x, msg.angular.z, lin, ang)
    if msgtype == TWIST_STAMPED:
        return lambda msg: twist_action(msg.twist.linear.x, msg.twist.angular.z, lin, ang)
    raise ValueError(f"action topic {opts.action_topic} has type {msgtype}, which is not "
                     f"supported; supported types: {', '.join(ACTION_TYPES)} (or pass action_rule)")


def gds_decoder(msgtype: str, opts: Options):
    """The decoder for GDS messages of ``msgtype`` (message -> name or id), or a ValueError."""
    if msgtype in GDS_TYPES:
        return lambda msg: msg.data
    raise ValueError(f"GDS topic {opts.gds_topic} has type {msgtype}, which is not supported; "
                     f"supported types: {', '.join(GDS_TYPES)}")


def _at(msg, dotted: str):
    """The value at the dotted path ``dotted`` ('' is ``msg`` itself)."""
    for part in (p for p in dotted.split(".") if p):
        msg = getattr(msg, part)
    return msg


def _frame_id(name: str) -> str:
    """A frame id as TF compares them: without ROS 1's leading ``/``."""
    return name.lstrip("/")


class TransformPicker:
    """The decoder of a ``tf2_msgs/TFMessage`` position topic: the position ``(x, y, z)`` of the
    transform from ``opts.position_frame`` to ``opts.position_child_frame`` in a message, or None
    when the message holds no such transform; the frame pairs seen are kept for the error that
    says which to choose (:meth:`missing`)."""

    def __init__(self, opts: Options):
        self.topic = opts.position_topic
        self.pair = (opts.position_frame, opts.position_child_frame)
        self.seen: dict = {}

    def __call__(self, msg) -> tuple | None:
        found = None
        for transform in msg.transforms:
            pair = (_frame_id(transform.header.frame_id), _frame_id(transform.child_frame_id))
            self.seen[pair] = None
            if pair == self.pair:
                p = transform.transform.translation
                found = (float(p.x), float(p.y), float(p.z))
        return found

    def missing(self) -> str:
        """Why no message gave a position, naming the settings and the transforms there are."""
        there = ", ".join(f"{a} -> {b}" for a, b in self.seen) or "none"
        if None in self.pair:
            return (f"position topic {self.topic} is a {TF_MESSAGE}: set position_frame and "
                    f"position_child_frame to the transform whose translation is the position "
                    f"(its transforms: {there})")
        return (f"position topic {self.topic} holds no transform from {self.pair[0]!r} "
                f"(position_frame) to {self.pair[1]!r} (position_child_frame); its transforms: "
                f"{there}")


def _frame_check(msgtype: str, opts: Options):
    """A check of a position message's frames: ``position_frame`` (its header's ``frame_id``) and
    ``position_child_frame`` (its ``child_frame_id``) where given; without ``position_frame``,
    positions in the robot's own ``odom`` frame are refused (they drift: no ground truth)."""
    stamped = msgtype not in ("geometry_msgs/msg/Pose", "geometry_msgs/msg/Point")
    topic, frame, child = opts.position_topic, opts.position_frame, opts.position_child_frame
    if frame is not None and not stamped:
        raise ValueError(f"position_frame={frame!r} needs position messages that name their "
                         f"frame (a header); {topic} carries {msgtype}")
    if child is not None and msgtype not in CHILD_FRAME_TYPES:
        raise ValueError(f"position_child_frame={child!r} needs position messages that name a "
                         f"child frame ({', '.join(CHILD_FRAME_TYPES)}, {TF_MESSAGE}); {topic} "
                         f"carries {msgtype}")

    def check(msg) -> None:
        """Raise a ValueError unless ``msg``'s frames are the ones asked for."""
        if not stamped:
            return
        got = _frame_id(msg.header.frame_id)
        if frame is None and got == ODOM_FRAME:
            raise ValueError(
                f"the positions on {topic} are in the frame {ODOM_FRAME!r}, the robot's own "
                f"odometry (REP 105), which drifts and is no ground truth: give it as "
                f"odometry_topic={topic}, and as position_topic a motion capture's or a "
                f"simulator's truth; to score against the odometry all the same, set "
                f"position_frame={ODOM_FRAME}")
        if frame is not None and got != frame:
            raise ValueError(f"the positions on {topic} are in the frame {got!r}, not "
                             f"position_frame={frame!r}")
        if child is not None and _frame_id(msg.child_frame_id) != child:
            raise ValueError(f"the positions on {topic} place the frame "
                             f"{_frame_id(msg.child_frame_id)!r}, not position_child_frame="
                             f"{child!r}")
    return check


def position_decoder(msgtype: str, opts: Options):
    """The decoder for position messages of ``msgtype`` (message -> ``(x, y, z)``), or a
    ValueError listing the types that carry a position."""
    if msgtype not in POSITION_TYPES:
        raise ValueError(f"position topic {opts.position_topic} has type {msgtype}, which is not "
                         f"supported; supported types: {', '.join(POSITION_TYPES)}")
    if msgtype == TF_MESSAGE:
        return TransformPicker(opts)
    path, check = POSITION_TYPES[msgtype], _frame_check(msgtype, opts)

    def decode(msg) -> tuple:
        """The position (x, y, z) carried by ``msg``."""
        check(msg)
        p = _at(msg, path)
        return (float(p.x), float(p.y), float(p.z))
    return decode


def odometry_decoder(msgtype: str, opts: Options):
    """The decoder for odometry messages of ``msgtype`` (message -> ``(x, y, heading)``, the
    heading the yaw of its orientation), or a ValueError listing the types that carry a pose."""
    if msgtype not in ODOMETRY_TYPES:
        raise ValueError(f"odometry topic {opts.odometry_topic} has type {msgtype}, which is not "
                         f"supported; supported types: {', '.join(ODOMETRY_TYPES)}")
    position, orientation = ODOMETRY_TYPES[msgtype]

    def decode(msg) -> tuple:
        """The pose (x, y, heading) carried by ``msg``."""
        p, q = _at(msg, position), _at(msg, orientation)
        try:
            yaw = yaw_of_quaternion(float(q.x), float(q.y), float(q.z), float(q.w))
        except ValueError as exc:
            raise ValueError(f"odometry topic {opts.odometry_topic}: {exc}") from None
        return (float(p.x), float(p.y), yaw)
    return decode
