"""What reading and writing bags share: the optional rosbags import, message types, errors."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

from ...checks import ParameterError

LASER_SCAN = "sensor_msgs/msg/LaserScan"
STRING = "std_msgs/msg/String"


def names_topic(action_topic: str) -> str:
    """The topic on which :func:`~topomap.core.data.rosbag.write_rosbag` records the action
    names in id order (``/action/names`` for ``/action``), so that reading the bag gives the
    actions the ids they had."""
    return action_topic.rstrip("/") + "/names"
INT32 = "std_msgs/msg/Int32"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
FLOAT64_ARRAY = "std_msgs/msg/Float64MultiArray"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
ODOMETRY = "nav_msgs/msg/Odometry"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
#: message types accepted on the position topic, each with the dotted path of its position
#: (a ``geometry_msgs/Point``, or ``Vector3`` for a transform; for a ``TFMessage``, the path in
#: the transform of the frames ``position_frame`` -> ``position_child_frame`` it holds)
POSITION_TYPES = {
    POSE_STAMPED: "pose.position",
    "geometry_msgs/msg/PoseWithCovarianceStamped": "pose.pose.position",
    ODOMETRY: "pose.pose.position",
    "geometry_msgs/msg/Pose": "position",
    "geometry_msgs/msg/PointStamped": "point",
    "geometry_msgs/msg/Point": "",
    TRANSFORM_STAMPED: "transform.translation",
    TF_MESSAGE: "transform.translation",
}
#: message types accepted on the odometry topic, each with the dotted paths of its position and
#: its orientation (a quaternion, whose yaw is the heading)
ODOMETRY_TYPES = {
    ODOMETRY: ("pose.pose.position", "pose.pose.orientation"),
    POSE_STAMPED: ("pose.position", "pose.orientation"),
    "geometry_msgs/msg/PoseWithCovarianceStamped": ("pose.pose.position", "pose.pose.orientation"),
    TRANSFORM_STAMPED: ("transform.translation", "transform.rotation"),
}
#: message types whose ``child_frame_id`` names the frame they place (besides ``TFMessage``'s
#: transforms)
CHILD_FRAME_TYPES = (ODOMETRY, TRANSFORM_STAMPED)
#: the frame of a robot's own odometry (REP 105): it drifts, so it is no ground truth
ODOM_FRAME = "odom"
#: message types accepted on the action topic (any type when ``action_rule`` is given)
ACTION_TYPES = (STRING, INT32, TWIST, TWIST_STAMPED)
#: message types accepted on the GDS topic
GDS_TYPES = (STRING, INT32)
#: words in rosbags' error messages that mean a cut-off or unfinished recording
_TRUNCATED_HINTS = ("not indexed", "index looks damaged", "end magic", "truncated", "malformed",
                    "got only")
#: words in rosbags' error messages that mean the file is not a bag at all
_CORRUPT_HINTS = ("magic is invalid", "not a database", "could not load yaml", "codec",
                  "checksum mismatch", "invalid or unsupported cdr")


class MissingDependencyError(ImportError, ValueError):
    """The optional ``rosbags`` package is not installed (also a ValueError, so the command line
    reports it in one line)."""


def _rosbags():
    """Import rosbags on first use, so that topomap imports without the optional extra."""
    try:
        import rosbags.highlevel
        import rosbags.rosbag1
        import rosbags.rosbag2
        import rosbags.serde
        import rosbags.typesys
    except ImportError as exc:  # pragma: no cover - the tests run with rosbags installed
        raise MissingDependencyError(f'ROS bags need the optional rosbags package ({exc}): '
                                     'pip install "topomap[ros]"') from None
    return rosbags


def _read_errors() -> tuple:
    """Exception types that rosbags (and the sqlite/MCAP layers under it) raise on bad bags."""
    rb = _rosbags()
    errors = [rb.highlevel.AnyReaderError, rb.rosbag1.ReaderError, rb.rosbag2.ReaderError,
              rb.serde.SerdeError, OSError, UnicodeDecodeError, struct.error]
    try:
        import apsw
        errors.append(apsw.Error)
    except ImportError:  # pragma: no cover - rosbags' sqlite3 storage depends on apsw
        pass
    return tuple(errors)


def _one_line(text) -> str:
    """``text`` with all runs of whitespace (newlines included) collapsed to one space."""
    return " ".join(str(text).split())


def _describe_failure(path: Path, exc: BaseException) -> str:
    """A one-line message naming ``path`` for an error rosbags raised while reading it."""
    text = _one_line(exc) or type(exc).__name__
    low = text.lower()
    if any(hint in low for hint in _TRUNCATED_HINTS):
        return f"bag {path} is truncated or was not closed properly ({text})"
    if any(hint in low for hint in _CORRUPT_HINTS):
        return f"bag {path} is corrupt or not a ROS bag ({text})"
    return f"bag {path} could not be read ({text})"


def _check_bag_path(path: Path) -> None:
    """Raise a ValueError naming ``path`` unless it looks like a bag rosbags can open."""
    if not path.exists():
        raise ValueError(f"bag {path} does not exist")
    if path.is_dir():
        if path.suffix == ".bag":
            raise ValueError(f"bag folder {path} ends in .bag, which rosbags takes for a ROS 1 "
                             "file; rename it")
        if not (path / "metadata.yaml").is_file():
            raise ValueError(f"bag folder {path} has no metadata.yaml (a recording that did not "
                             "finish?); pass the .db3 or .mcap file inside it instead")
        return
    if path.stat().st_size == 0:
        raise ValueError(f"bag {path} is empty (0 bytes)")
    if path.suffix in (".bag", ".db3", ".mcap"):
        return
    with open(path, "rb") as fh:
        magic = fh.read(13)
    if magic.startswith(b"#ROSBAG"):
        raise ValueError(f"bag {path} looks like a ROS 1 bag but its name does not end in .bag; "
                         "rename it")
    raise ValueError(f"{path} is not a ROS bag: expected a ROS 1 .bag file, a ROS 2 bag folder, "
                     "or a ROS 2 .db3 or .mcap file")


def _positive(name: str, value, *, zero: bool = False) -> float:
    """``value`` as a float if it is a finite positive (or, with ``zero``, non-negative) number,
    else a :class:`~topomap.core.checks.ParameterError` naming ``name``."""
    kinds = (int, float, np.integer, np.floating)
    ok = isinstance(value, kinds) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not zero):
        raise ParameterError(name, f"must be a {'non-negative' if zero else 'positive'} number, "
                                   f"got {value!r}")
    return float(value)
