"""write_rosbag: what it writes, what it refuses, and that a failure leaves nothing behind."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from topomap.core.data.rosbag import write as rosbag_write
from topomap.core.data.rosbag import read_rosbag, write_rosbag
from topomap.core.data.trajectory import Trajectory


def small(steps: int = 6, lengths=None, names=("go", "turn")) -> Trajectory:
    """A tiny trajectory with 3-value observations."""
    obs = np.arange(steps * 3, dtype=float).reshape(steps, 3)
    return Trajectory(observations=obs, actions=np.arange(steps) % 2, lengths=lengths,
                      action_names=None if names is None else list(names))


def test_messages_topics_and_stamps(tmp_path):
    path = write_rosbag(small(), tmp_path / "t.bag", rate=4.0, start_time=100.0)
    with AnyReader([path]) as reader:
        topics = {name: (info.msgtype, info.msgcount) for name, info in reader.topics.items()}
        stamps = [t for c, t, _ in reader.messages() if c.topic != "/action/names"]
        names = [(t, reader.deserialize(raw, c.msgtype).data) for c, t, raw in reader.messages()
                 if c.topic == "/action/names"]
        scans = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                 if c.topic == "/scan"]
    assert topics == {"/scan": ("sensor_msgs/msg/LaserScan", 6),
                      "/action": ("std_msgs/msg/String", 6),
                      "/action/names": ("std_msgs/msg/String", 2)}
    assert sorted(set(stamps)) == [100 * 10**9 + k * 250_000_000 for k in range(6)]
    assert names == [(100 * 10**9 - 2, "go"), (100 * 10**9 - 1, "turn")]  # in id order, first
    assert scans[0].range_max == 17.0 and scans[0].ranges.dtype == np.float32
    assert np.isclose(scans[0].angle_increment * 3, 2 * np.pi)


def test_refuses_to_overwrite(tmp_path):
    target = tmp_path / "t.bag"
    target.write_bytes(b"keep me")
    with pytest.raises(ValueError, match=r"t\.bag exists already; not overwriting"):
        write_rosbag(small(), target)
    assert target.read_bytes() == b"keep me"


@pytest.mark.parametrize("kw, match", [
    (dict(version=3), "version must be 1"),
    (dict(version=2, storage="lz4"), "storage must be"),
    (dict(rate=0), "rate must be a positive number"),
    (dict(action_topic="/scan"), "topics must differ"),
])
def test_bad_arguments(tmp_path, kw, match):
    with pytest.raises(ValueError, match=match):
        write_rosbag(small(), tmp_path / "t.bag", **kw)
    assert list(tmp_path.iterdir()) == []


def test_paths_must_match_the_episodes(tmp_path):
    traj = small(6, lengths=[2, 4])
    with pytest.raises(ValueError, match="2 episodes; give a list of 2 bag paths"):
        write_rosbag(traj, tmp_path / "t.bag")
    with pytest.raises(ValueError, match="1 bag paths given for 2 episodes"):
        write_rosbag(traj, [tmp_path / "t.bag"])
    with pytest.raises(ValueError, match=r"t\.db3 does not fit version 1"):
        write_rosbag(small(), tmp_path / "t.db3")
    with pytest.raises(ValueError, match=r"t\.bag does not fit version 2"):
        write_rosbag(small(), tmp_path / "t.bag", version=2)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("version", [1, 2])
def test_a_failure_midway_leaves_nothing(tmp_path, monkeypatch, version):
    calls = []
    original = rosbag_write._observation_message

    def failing(store, row, stamp_ns, seq, spec):
        calls.append(seq)
        if len(calls) == 5:  # in the second episode, after the first bag is complete
            raise RuntimeError("disk full")
        return original(store, row, stamp_ns, seq, spec)

    monkeypatch.setattr(rosbag_write, "_observation_message", failing)
    suffix = ".bag" if version == 1 else ""
    paths = [tmp_path / f"a{suffix}", tmp_path / "sub" / f"b{suffix}"]
    with pytest.raises(RuntimeError, match="disk full"):
        write_rosbag(small(6, lengths=[3, 3]), paths, version=version)
    assert [p for p in tmp_path.rglob("*") if not p.is_dir()] == []
    assert [p.name for p in tmp_path.rglob("*")] == ["sub"]


def test_returns_what_it_was_given(tmp_path):
    single = write_rosbag(small(), tmp_path / "one", version=2, storage="mcap")
    assert single == tmp_path / "one" and (single / "metadata.yaml").is_file()
    listed = write_rosbag(small(), [tmp_path / "two.bag"])
    assert listed == [tmp_path / "two.bag"]


def test_negative_observations_round_trip_as_ranges(tmp_path):
    traj = Trajectory(observations=[[-1.0, 2.0], [0.5, -3.0], [1.0, 1.0]], actions=[0, 1, 0])
    back = read_rosbag(write_rosbag(traj, tmp_path / "n.bag"), "/scan", "/action")
    assert back.observations.tolist() == traj.observations.tolist()
