"""Every failure is one ValueError line that names the file; nothing is written."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from rosbag_helpers import (  # noqa: F401 (fmt is a fixture)
    fmt,
    STORES,
    bag_path,
    float32,
    pose,
    scan,
    simple_records,
    string,
    write_bag,
)
from rosbags.rosbag1 import Writer as Writer1

from topomap.core.data.rosbag import read_rosbag


def read_error(path, *args, **kw) -> str:
    """The message of the ValueError that reading ``path`` raises, checked to be one line."""
    args = args or ("/scan", "/action")
    before = snapshot(Path(path).parent)
    with pytest.raises(ValueError) as info:
        read_rosbag(path, *args, **kw)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    assert snapshot(Path(path).parent) == before  # nothing written, nothing left behind
    return message


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` with its size and modification time."""
    return {p: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


def storage_file(folder: Path) -> Path:
    """The .db3 or .mcap file of a ROS 2 bag folder."""
    (found,) = [p for p in folder.iterdir() if p.suffix in (".db3", ".mcap")]
    return found


def test_missing_topic_lists_the_topics_with_types_and_counts(tmp_path, fmt):
    records = simple_records(3) + [("/odom", 0.3, pose(0.0, 0.0))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    message = read_error(path, "/scan", "/cmd")
    assert "no action topic /cmd; its topics are: /action (std_msgs/msg/String, 3 messages), " \
           "/odom (geometry_msgs/msg/PoseStamped, 1 messages), " \
           "/scan (sensor_msgs/msg/LaserScan, 3 messages)" in message
    assert "no observation topic /laser" in read_error(path, "/laser", "/action")
    assert "no GDS topic /gds" in read_error(path, "/scan", "/action", gds_topic="/gds")


def test_unsupported_types_name_the_supported_ones(tmp_path, fmt):
    records = simple_records(2) + [("/f", 0.1, float32(1.0)), ("/odom", 0.0, pose(0.0, 0.0))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    message = read_error(path, "/scan", "/f")
    assert ("action topic /f has type std_msgs/msg/Float32, which is not supported; supported "
            "types: std_msgs/msg/String, std_msgs/msg/Int32, geometry_msgs/msg/Twist, "
            "geometry_msgs/msg/TwistStamped") in message
    message = read_error(path, "/odom", "/action")
    assert "geometry_msgs/msg/PoseStamped, which is not supported" in message
    assert "sensor_msgs/msg/LaserScan" in message and "observation_fields" in message
    message = read_error(path, "/scan", "/action", gds_topic="/f")
    assert "supported types: std_msgs/msg/String, std_msgs/msg/Int32" in message


@pytest.mark.parametrize("name", ["empty.bag", "empty.db3", "empty.mcap"])
def test_zero_byte_file(tmp_path, name):
    (tmp_path / name).touch()
    assert "is empty (0 bytes)" in read_error(tmp_path / name)


def test_bag_without_messages(tmp_path, fmt):
    records = [("/scan", "sensor_msgs/msg/LaserScan", None),
               ("/action", "std_msgs/msg/String", None)]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    assert "empty, it has no messages" in read_error(path)


def test_topic_without_messages(tmp_path, fmt):
    records = [("/scan", 0.0, scan([1.0])), ("/action", "std_msgs/msg/String", None)]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    assert "no messages on the action topic /action" in read_error(path)
    records = [("/scan", "sensor_msgs/msg/LaserScan", None), ("/action", 0.0, string("a"))]
    path = write_bag(bag_path(tmp_path, fmt, "other"), fmt, records)
    assert "no messages on the observation topic /scan" in read_error(path)


def test_observations_all_after_the_last_action(tmp_path, fmt):
    records = [("/action", 1.0, string("a")), ("/action", 2.0, string("b")),
               ("/scan", 2.5, scan([1.0])), ("/scan", 3.0, scan([1.0]))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    message = read_error(path)
    assert "all 2 observations on /scan come after the last action on /action" in message
    assert "first observation at 2.500 s, last action at 2.000 s" in message


def cut(path: Path, fraction: float = 0.5) -> None:
    """Keep only the first ``fraction`` of the file at ``path``."""
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * fraction)])


def big_records():
    """Enough messages for a multi-chunk bag (ROS 1 chunks are 1 MiB)."""
    return [r for k in range(2000) for r in (("/scan", k * 0.1, scan([1.0] * 360)),
                                             ("/action", k * 0.1, string("a")))]


def test_truncated_ros1_bag(tmp_path):
    path = write_bag(tmp_path / "cut.bag", "ros1", big_records())
    cut(path)
    assert "cut.bag is truncated or was not closed properly" in read_error(path)


def test_unfinished_ros1_bag(tmp_path):
    """A recording that was killed has no index: rosbags' writer leaves one like it on abort."""
    path = tmp_path / "killed.bag"
    writer = Writer1(path)
    writer.open()
    conn = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=STORES[1])
    writer.write(conn, 1, STORES[1].serialize_ros1(scan([1.0])(STORES[1]), conn.msgtype))
    writer.abort()
    message = read_error(path)
    assert "killed.bag is truncated or was not closed properly" in message
    assert "not indexed" in message


@pytest.mark.parametrize("fmt_", ["sqlite3", "mcap"])
def test_truncated_ros2_storage(tmp_path, fmt_):
    folder = write_bag(bag_path(tmp_path, fmt_), fmt_, big_records())
    cut(storage_file(folder))
    message = read_error(folder)
    assert "truncated or was not closed properly" in message


def test_truncated_mcap_file(tmp_path):
    folder = write_bag(bag_path(tmp_path, "mcap"), "mcap", big_records())
    target = tmp_path / "cut.mcap"
    shutil.copy(storage_file(folder), target)
    cut(target, 0.7)
    assert "cut.mcap is truncated or was not closed properly" in read_error(target)


@pytest.mark.parametrize("name", ["junk.bag", "junk.mcap", "junk.db3"])
def test_corrupt_file(tmp_path, name):
    (tmp_path / name).write_bytes(os.urandom(4096))
    message = read_error(tmp_path / name)
    assert "is corrupt or not a ROS bag" in message


def test_corrupt_metadata(tmp_path):
    folder = write_bag(bag_path(tmp_path, "sqlite3"), "sqlite3", simple_records(2))
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: [\n")
    assert "is corrupt or not a ROS bag" in read_error(folder)


def test_folder_without_metadata(tmp_path):
    folder = write_bag(bag_path(tmp_path, "mcap"), "mcap", simple_records(2))
    (folder / "metadata.yaml").unlink()
    assert "no metadata.yaml" in read_error(folder)


def test_ros2_folder_named_bag(tmp_path):
    folder = write_bag(tmp_path / "run", "mcap", simple_records(2))
    folder.rename(tmp_path / "run.bag")
    assert "ends in .bag" in read_error(tmp_path / "run.bag")


def test_not_a_bag(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    assert "is not a ROS bag" in read_error(tmp_path / "notes.txt")


def test_ros1_bag_without_the_suffix(tmp_path):
    path = write_bag(tmp_path / "run.bag", "ros1", simple_records(2))
    path.rename(tmp_path / "run.dat")
    assert "does not end in .bag" in read_error(tmp_path / "run.dat")


def test_missing_path(tmp_path):
    assert "does not exist" in read_error(tmp_path / "nothing.bag")


def test_a_bad_bag_in_a_list_is_named(tmp_path):
    good = write_bag(tmp_path / "good.bag", "ros1", simple_records(2))
    (tmp_path / "bad.bag").write_bytes(b"#ROSBAG V2.0\n" + b"\0" * 100)
    with pytest.raises(ValueError, match=r"bad\.bag") as info:
        read_rosbag([good, tmp_path / "bad.bag"], "/scan", "/action")
    assert "good.bag" not in str(info.value)


@pytest.mark.parametrize("kw, match", [
    (dict(scan_bins=0), "scan_bins must be a positive integer"),
    (dict(scan_bins=2.5), "scan_bins must be a positive integer"),
    (dict(max_range=-1.0), "max_range must be a positive number"),
    (dict(gds_window=-0.1), "gds_window must be a non-negative number"),
    (dict(linear_threshold=0), "linear_threshold must be a positive number"),
    (dict(gds_topic="/action"), "must differ"),
    (dict(action_names=["a", "a"]), "distinct"),
    (dict(action_names="abc"), "list of strings"),
    (dict(observation_fields=[]), "observation_fields must be a non-empty list"),
    (dict(action_rule="forward"), "action_rule must be callable"),
])
def test_bad_arguments(tmp_path, kw, match):
    path = write_bag(tmp_path / "r.bag", "ros1", simple_records(2))
    with pytest.raises(ValueError, match=match):
        read_rosbag(path, "/scan", "/action", **kw)


def test_empty_list_of_bags():
    with pytest.raises(ValueError, match="empty list"):
        read_rosbag([], "/scan", "/action")


def test_unknown_action_name(tmp_path):
    path = write_bag(tmp_path / "r.bag", "ros1", simple_records(2, ("a", "jump")))
    message = read_error(path, action_names=["a", "b"])
    assert "action 'jump' is not one of the given action_names ['a', 'b']" in message

