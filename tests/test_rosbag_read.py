"""read_rosbag's rules on hand-made bags: steps, actions, Twist, GDS, scans, fields, episodes."""

from __future__ import annotations

import numpy as np
import pytest
from rosbag_helpers import (  # noqa: F401 (fmt is a fixture)
    fmt,
    bag_path,
    int32,
    pose,
    scan,
    simple_records,
    string,
    twist,
    write_bag,
)

from topomap.core.data.rosbag import read_rosbag, twist_action
from topomap.core.data.rosbag.read import _Rows


def test_observation_is_the_latest_at_or_before_each_action(tmp_path, fmt):
    records = [("/action", 0.2, string("early")),   # before any observation: dropped
               ("/scan", 1.0, scan([1, 1])), ("/scan", 2.0, scan([2, 2])),
               ("/scan", 3.0, scan([3, 3])),
               ("/action", 1.5, string("a")), ("/action", 2.0, string("b")),  # 2.0: a tie
               ("/action", 2.9, string("c")), ("/action", 7.0, string("d"))]
    traj = read_rosbag(write_bag(bag_path(tmp_path, fmt), fmt, records), "/scan", "/action")
    assert traj.observations[:, 0].tolist() == [1, 2, 2, 3]
    assert traj.action_names == ["a", "b", "c", "d"]
    assert traj.actions.tolist() == [0, 1, 2, 3]
    assert traj.meta["dropped_steps"] == [1]


def test_string_actions_get_ids_by_first_appearance_or_by_action_names(tmp_path):
    path = write_bag(tmp_path / "r.bag", "ros1", simple_records(5, ("west", "east", "west")))
    traj = read_rosbag(path, "/scan", "/action")
    assert traj.action_names == ["west", "east"] and traj.actions.tolist() == [0, 1, 0, 0, 1]
    fixed = read_rosbag(path, "/scan", "/action", action_names=["north", "east", "south", "west"])
    assert fixed.actions.tolist() == [3, 1, 3, 3, 1]
    assert fixed.action_names == ["north", "east", "south", "west"]


def test_int32_actions_keep_their_ids(tmp_path, fmt):
    records = [("/scan", 0.0, scan([1.0]))] + [("/action", 0.1 * k + 0.1, int32(v))
                                               for k, v in enumerate([2, 0, 5, 2])]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    traj = read_rosbag(path, "/scan", "/action")
    assert traj.actions.tolist() == [2, 0, 5, 2] and traj.action_names is None
    named = read_rosbag(path, "/scan", "/action", action_names=list("abcdef"))
    assert named.action_names == list("abcdef")


def test_negative_int32_action_is_an_error(tmp_path):
    records = [("/scan", 0.0, scan([1.0])), ("/action", 0.1, int32(-1))]
    path = write_bag(tmp_path / "r.bag", "ros1", records)
    with pytest.raises(ValueError, match=r"r\.bag.*action ids must be >= 0"):
        read_rosbag(path, "/scan", "/action")


@pytest.mark.parametrize("vx, wz, name", [
    (0.0, 0.0, "stop"), (0.04, 0.09, "stop"), (-0.04, -0.09, "stop"),
    (0.05, 0.0, "forward"), (0.3, 0.05, "forward"), (-0.05, 0.0, "backward"),
    (0.0, 0.1, "turn_left"), (0.3, 0.5, "turn_left"), (0.0, -0.1, "turn_right"),
    (-0.3, -2.0, "turn_right"),
])
def test_twist_rule(vx, wz, name):
    assert twist_action(vx, wz) == name


def test_twist_topics_are_discretised(tmp_path, fmt):
    commands = [(0.2, 0.0), (0.0, 0.5), (0.0, -0.5), (0.0, 0.0), (0.2, 0.0)]
    records = [("/scan", 0.0, scan([1.0]))]
    records += [("/cmd_vel", 0.1 * (k + 1), twist(vx, wz)) for k, (vx, wz) in enumerate(commands)]
    records += [("/cmd_stamped", 0.1 * (k + 1), twist(vx, wz, stamped=True))
                for k, (vx, wz) in enumerate(commands)]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    expected = ["forward", "turn_left", "turn_right", "stop", "forward"]
    for topic in ("/cmd_vel", "/cmd_stamped"):
        traj = read_rosbag(path, "/scan", topic)
        assert [traj.action_names[a] for a in traj.actions] == expected
    slow = read_rosbag(path, "/scan", "/cmd_vel", linear_threshold=0.5, angular_threshold=1.0)
    assert set(slow.action_names) == {"stop"}


def test_action_rule_reads_any_message_type(tmp_path):
    records = [("/scan", 0.0, scan([1.0])), ("/goal", 0.1, pose(1.0, 0.0)),
               ("/goal", 0.2, pose(-1.0, 0.0))]
    path = write_bag(tmp_path / "r.bag", "ros1", records)
    traj = read_rosbag(path, "/scan", "/goal",
                       action_rule=lambda m: "east" if m.pose.position.x > 0 else "west")
    assert traj.action_names == ["east", "west"]


def test_gds_window_and_nearest_message(tmp_path, fmt):
    records = [("/scan", 0.0, scan([1.0])),
               ("/gds", 1.0, string("door")), ("/gds", 3.0, string("lift"))]
    step_times = [0.4, 0.6, 1.0, 1.5, 1.6, 2.0, 2.4, 2.6, 4.0]
    records += [("/action", t, string("go")) for t in step_times]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    traj = read_rosbag(path, "/scan", "/action", gds_topic="/gds", gds_window=0.5)
    names = [traj.gds_names[g] if g >= 0 else None for g in traj.gds]
    assert names == [None, "door", "door", "door", None, None, None, "lift", None]
    wide = read_rosbag(path, "/scan", "/action", gds_topic="/gds", gds_window=1.0)
    assert [wide.gds_names[g] for g in wide.gds][5] == "door"  # 2.0 is 1 s from both: the earlier
    fixed = read_rosbag(path, "/scan", "/action", gds_topic="/gds", gds_names=["lift", "door"])
    assert fixed.gds.tolist() == [0 if n == "lift" else 1 if n == "door" else -1
                                  for n in [None, "door", "door", "door", None, None, None,
                                            "lift", None]]


def test_int32_gds_and_a_gds_topic_without_messages(tmp_path):
    records = [("/scan", 0.0, scan([1.0])), ("/action", 0.1, string("a")),
               ("/action", 5.0, string("a")), ("/gds", 0.1, int32(3))]
    traj = read_rosbag(write_bag(tmp_path / "r.bag", "ros1", records), "/scan", "/action",
                       gds_topic="/gds")
    assert traj.gds.tolist() == [3, -1] and traj.gds_names is None
    empty = records[:3] + [("/gds", "std_msgs/msg/String", None)]
    traj = read_rosbag(write_bag(tmp_path / "e.bag", "ros1", empty), "/scan", "/action",
                       gds_topic="/gds")
    assert traj.gds.tolist() == [-1, -1]


def test_scan_invalid_ranges_clipping_and_bins(tmp_path, fmt):
    ranges = [0.5, np.inf, np.nan, 4.0, 9.0, 1.0, 2.0, 3.0, 8.0, 0.2]
    records = [("/scan", 0.0, scan(ranges, range_max=6.0)), ("/action", 0.1, string("a"))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    raw = read_rosbag(path, "/scan", "/action").observations[0]
    np.testing.assert_array_equal(raw, np.float32([0.5, 6, 6, 4, 9, 1, 2, 3, 8, 0.2]))
    clipped = read_rosbag(path, "/scan", "/action", max_range=5.0).observations[0]
    np.testing.assert_array_equal(clipped, np.float32([0.5, 5, 5, 4, 5, 1, 2, 3, 5, 0.2]))
    binned = read_rosbag(path, "/scan", "/action", scan_bins=3).observations[0]
    # sectors of 10 beams in 3: [0, 3), [3, 6), [6, 10), each its minimum
    np.testing.assert_array_equal(binned, np.float32([0.5, 1.0, 0.2]))
    both = read_rosbag(path, "/scan", "/action", scan_bins=2, max_range=0.4).observations[0]
    np.testing.assert_array_equal(both, np.float32([0.4, 0.2]))


def test_infinite_range_max_needs_max_range(tmp_path):
    records = [("/scan", 0.0, scan([1.0, np.inf], range_max=np.inf)), ("/action", 0.1, string("a"))]
    path = write_bag(tmp_path / "r.bag", "ros1", records)
    with pytest.raises(ValueError, match=r"r\.bag.*NaN or inf.*max_range"):
        read_rosbag(path, "/scan", "/action")
    assert read_rosbag(path, "/scan", "/action", max_range=8.0).observations.tolist() == [[1, 8]]


def test_scan_bins_larger_than_the_scan(tmp_path):
    path = write_bag(tmp_path / "r.bag", "ros1", simple_records(2))
    with pytest.raises(ValueError, match=r"r\.bag.*scan_bins=4 exceeds the 3 beams"):
        read_rosbag(path, "/scan", "/action", scan_bins=4)


def test_scans_of_different_sizes(tmp_path):
    records = [("/scan", 0.0, scan([1, 1, 1])), ("/action", 0.1, string("a")),
               ("/scan", 1.0, scan([1, 1])), ("/action", 1.1, string("a"))]
    path = write_bag(tmp_path / "r.bag", "ros1", records)
    with pytest.raises(ValueError, match=r"r\.bag: observation message 1 has 2 values"):
        read_rosbag(path, "/scan", "/action")


def test_observation_fields_nested_and_arrays(tmp_path, fmt):
    records = [("/pose", 0.0, pose(1.5, -2.0)), ("/action", 0.1, string("a")),
               ("/pose", 1.0, pose(3.0, 4.0)), ("/action", 1.1, string("b")),
               ("/scan", 0.0, scan([7, 8])), ("/scan", 1.0, scan([9, 10]))]
    path = write_bag(bag_path(tmp_path, fmt), fmt, records)
    traj = read_rosbag(path, "/pose", "/action",
                       observation_fields=["pose.position.x", "pose.position.y"])
    assert traj.observations.tolist() == [[1.5, -2.0], [3.0, 4.0]]
    arrays = read_rosbag(path, "/scan", "/action", observation_fields=["range_max", "ranges"])
    assert arrays.observations.tolist() == [[10, 7, 8], [10, 9, 10]]


def test_observation_field_errors(tmp_path):
    records = [("/pose", 0.0, pose(1.5, -2.0)), ("/action", 0.1, string("a"))]
    path = write_bag(tmp_path / "r.bag", "ros1", records)
    with pytest.raises(ValueError, match=r"r\.bag.*'pose\.positon\.x' not found.*position, "
                                         r"orientation"):
        read_rosbag(path, "/pose", "/action", observation_fields=["pose.positon.x"])
    with pytest.raises(ValueError, match=r"r\.bag.*'header\.frame_id' .* is not numeric"):
        read_rosbag(path, "/pose", "/action", observation_fields=["header.frame_id"])
    with pytest.raises(ValueError, match="cannot be combined with observation_fields"):
        read_rosbag(path, "/pose", "/action", observation_fields=["pose.position.x"], scan_bins=2)


def test_bags_share_one_name_table_across_episodes(tmp_path, fmt):
    first = write_bag(bag_path(tmp_path, fmt, "one"), fmt, simple_records(3, ("b", "a")))
    second = write_bag(bag_path(tmp_path, fmt, "two"), fmt, simple_records(4, ("c", "a")))
    traj = read_rosbag([first, second], "/scan", "/action")
    assert traj.lengths.tolist() == [3, 4]
    assert traj.action_names == ["b", "a", "c"]
    assert traj.actions.tolist() == [0, 1, 0, 2, 1, 2, 1]
    assert traj.meta["bags"] == [str(first), str(second)]
    single = read_rosbag([first], "/scan", "/action")
    assert single.lengths.tolist() == [3]


def test_mixing_names_and_ids_across_bags_is_an_error(tmp_path):
    first = write_bag(tmp_path / "a.bag", "ros1", simple_records(2))
    records = [("/scan", 0.0, scan([1, 1, 1])), ("/action", 0.1, int32(1))]
    second = write_bag(tmp_path / "b.bag", "ros1", records)
    with pytest.raises(ValueError, match=r"bags .*a\.bag, .*b\.bag: the action values mix names"):
        read_rosbag([first, second], "/scan", "/action")


@pytest.mark.parametrize("fmt_", ["sqlite3", "mcap"])
def test_ros2_storage_file_can_be_read_directly(tmp_path, fmt_):
    folder = write_bag(bag_path(tmp_path, fmt_), fmt_, simple_records(3))
    (storage,) = [p for p in folder.iterdir() if p.suffix in (".db3", ".mcap")]
    assert read_rosbag(storage, "/scan", "/action").actions.tolist() == [0, 1, 0]


def test_row_buffer_grows_past_its_capacity_and_reorders():
    rows = _Rows(capacity=1)
    for k in range(5):
        rows.append(np.full(2, k, dtype=np.float32))
    assert rows.take(np.arange(5))[:, 0].tolist() == [0, 1, 2, 3, 4]
    assert rows.take(np.array([4, 0, 1, 2, 3]))[:, 0].tolist() == [4, 0, 1, 2, 3]
    assert rows.take(np.arange(5)).dtype == np.float32
