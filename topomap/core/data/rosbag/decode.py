"""Messages into step values: observation vectors, and action and GDS names or ids.

Each ``*_decoder`` returns a function of one deserialised message, chosen by the topic's message
type and the :class:`~topomap.core.data.rosbag.options.Options` of the read, or raises a
ValueError saying why the type cannot be read.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .common import (ACTION_TYPES, GDS_TYPES, INT32, LASER_SCAN, POSITION_TYPES, STRING, TWIST,
                     TWIST_STAMPED)
from .options import Options

__all__ = ["twist_action", "observation_decoder", "action_decoder", "gds_decoder",
           "position_decoder"]


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


def position_decoder(msgtype: str, opts: Options):
    """The decoder for position messages of ``msgtype`` (message -> ``(x, y, z)``), or a
    ValueError listing the types that carry a position."""
    if msgtype not in POSITION_TYPES:
        raise ValueError(f"position topic {opts.position_topic} has type {msgtype}, which is not "
                         f"supported; supported types: {', '.join(POSITION_TYPES)}")
    parts = [p for p in POSITION_TYPES[msgtype].split(".") if p]

    def decode(msg) -> tuple:
        """The position (x, y, z) carried by ``msg``."""
        for part in parts:
            msg = getattr(msg, part)
        return (float(msg.x), float(msg.y), float(msg.z))
    return decode
