"""The arguments of :func:`~topomap.core.data.rosbag.read.read_rosbag`, checked once."""

from __future__ import annotations

import dataclasses

from ...checks import ParameterError, check_count
from .common import _positive

__all__ = ["Options", "make_options"]


@dataclasses.dataclass(frozen=True)
class Options:
    """The validated keyword arguments of :func:`read_rosbag`."""

    observation_topic: str
    action_topic: str
    observation_fields: tuple | None
    scan_bins: int | None
    max_range: float | None
    gds_topic: str | None
    position_topic: str | None
    gds_window: float
    action_names: list | None
    gds_names: list | None
    linear_threshold: float
    angular_threshold: float
    action_rule: object
    odometry_topic: str | None = None
    position_frame: str | None = None
    position_child_frame: str | None = None

    def roles(self) -> list[tuple[str, str]]:
        """``(role, topic)`` of each topic read: observation, action and, if any, GDS, position
        and odometry."""
        extra = [(role, topic) for role, topic in (("GDS", self.gds_topic),
                                                   ("position", self.position_topic),
                                                   ("odometry", self.odometry_topic)) if topic]
        return [("observation", self.observation_topic), ("action", self.action_topic), *extra]


def _name_list(name: str, values) -> list | None:
    """``values`` as a list of distinct strings, or None."""
    if values is None:
        return None
    if isinstance(values, str) or not all(isinstance(v, str) for v in values):
        raise ParameterError(name, f"must be a list of strings, got {values!r}")
    values = list(values)
    if not values or len(set(values)) != len(values):
        raise ParameterError(name, f"must be a non-empty list of distinct names, got {values!r}")
    return values


def _field_list(fields) -> tuple | None:
    """``observation_fields`` as a tuple of dotted field paths, or None."""
    if fields is None:
        return None
    if isinstance(fields, str):
        fields = [fields]
    fields = tuple(fields)
    if not fields or not all(isinstance(f, str) and f.strip(".") for f in fields):
        raise ParameterError("observation_fields", "must be a non-empty list of field names such "
                                                   f"as 'pose.position.x', got {list(fields)!r}")
    return fields


def _frame(name: str, value) -> str | None:
    """A frame id as TF compares them (without ROS 1's leading ``/``), or None."""
    if value is None or value == "":
        return None
    if not isinstance(value, str) or not value.strip("/"):
        raise ParameterError(name, f"must be a frame id such as 'map', got {value!r}")
    return value.lstrip("/")


def make_options(observation_topic, action_topic, kw: dict) -> Options:
    """The arguments of :func:`~topomap.core.data.rosbag.read.read_rosbag`, checked."""
    optional = [kw[k] for k in ("gds_topic", "position_topic", "odometry_topic") if kw[k]]
    topics = [observation_topic, action_topic] + optional
    if not all(isinstance(t, str) and t for t in topics):
        raise ValueError(f"topics must be non-empty strings, got {topics!r}")
    if len(set(topics)) != len(topics):
        raise ValueError(f"the observation, action, GDS, position and odometry topics must "
                         f"differ, got {topics!r}")
    frames = [k for k in ("position_frame", "position_child_frame") if kw[k]]
    if frames and not kw["position_topic"]:
        raise ParameterError(frames[0], "names the frame of the positions; give position_topic "
                                        "too")
    if kw["action_rule"] is not None and not callable(kw["action_rule"]):
        raise ParameterError("action_rule", f"must be callable, got {kw['action_rule']!r}")
    return Options(
        observation_topic=observation_topic, action_topic=action_topic,
        observation_fields=_field_list(kw["observation_fields"]),
        scan_bins=None if kw["scan_bins"] is None else check_count(kw["scan_bins"], "scan_bins"),
        max_range=None if kw["max_range"] is None else _positive("max_range", kw["max_range"]),
        gds_topic=kw["gds_topic"] or None, position_topic=kw["position_topic"] or None,
        gds_window=_positive("gds_window", kw["gds_window"], zero=True),
        action_names=_name_list("action_names", kw["action_names"]),
        gds_names=_name_list("gds_names", kw["gds_names"]),
        linear_threshold=_positive("linear_threshold", kw["linear_threshold"]),
        angular_threshold=_positive("angular_threshold", kw["angular_threshold"]),
        action_rule=kw["action_rule"], odometry_topic=kw["odometry_topic"] or None,
        position_frame=_frame("position_frame", kw["position_frame"]),
        position_child_frame=_frame("position_child_frame", kw["position_child_frame"]),
    )
