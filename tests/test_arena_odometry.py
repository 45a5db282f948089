"""The robot's wheel odometry in the arena (``odometry=wheel``): dead reckoning from the true moves
with encoder noise, a gyro bias and slips, kept as the walks' ``Trajectory.odometry``."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("ratinabox")

from topomap import load_trajectory  # noqa: E402
from topomap.app.run.experiment import check_and_build, run  # noqa: E402
from topomap.worlds.arena import ArenaWorld, Motion, RangeFinder, WheelOdometry  # noqa: E402

EXACT = dict(speed_noise=0, turn_noise=0, gyro_bias=0, slip_rate=0, slip_size=0)


def _start_frame(positions, heading0):
    """``positions`` seen from the pose (positions[0], heading0)."""
    d = np.asarray(positions) - positions[0]
    c, s = math.cos(heading0), math.sin(heading0)
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def test_without_errors_the_odometry_is_the_path_from_the_start_pose():
    """A square of 0.1 m sides walked anticlockwise from (1, 1) facing north: in the robot's own
    frame it starts at (0, 0) facing +x and turns left by 90 degrees at each corner."""
    P = np.array([[1, 1], [1, 1.1], [0.9, 1.1], [0.9, 1.0], [1, 1], [1, 1.1]])
    motion = Motion.from_samples(P, 0.1)
    odo = WheelOdometry(**EXACT).dead_reckoning(motion, np.random.default_rng(0))
    assert np.allclose(odo[:, :2], [[0, 0], [0.1, 0], [0.1, 0.1], [0, 0.1], [0, 0]])
    assert np.allclose(odo[:, 2], [0, 0, np.pi / 2, -np.pi, -np.pi / 2])


def test_a_gyro_bias_alone_turns_a_straight_path_at_its_rate():
    """Driving straight east for 100 steps of 0.1 s with a bias of 0.1 rad/s at most: the heading
    ends 99 x 0.1 x 0.1 x k rad off, |k| in [1/2, 1]; the distance driven is exact."""
    P = np.column_stack([np.linspace(0, 1, 101), np.full(101, 0.5)])
    motion = Motion.from_samples(P, 0.1)
    for seed in range(5):
        odo = WheelOdometry(**{**EXACT, "gyro_bias": 0.1}).dead_reckoning(
            motion, np.random.default_rng(seed))
        k = odo[-1, 2] / (99 * 0.1 * 0.1)
        assert 0.5 <= abs(k) <= 1.0
        steps = np.hypot(*np.diff(odo[:, :2], axis=0).T)
        assert steps == pytest.approx(np.full(99, 0.01))


def test_the_world_keeps_the_odometry_and_walks_the_same_path():
    """The same seed walks the same path with and without odometry; without errors the odometry
    is the truth seen from the start pose, with them it drifts from it."""
    sensor = RangeFinder(frame="egocentric")
    plain = ArenaWorld("two_rooms", sensor=sensor, actions="turns")
    robot = ArenaWorld("two_rooms", sensor=sensor, actions="turns", odometry="wheel")
    a = plain.simulate(1000, None, np.random.default_rng(3))
    b = robot.simulate(1000, None, np.random.default_rng(3))
    again = robot.simulate(1000, None, np.random.default_rng(3))
    assert a.odometry is None and b.odometry.shape == (1000, 3)
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.observations, b.observations)
    assert np.array_equal(b.odometry, again.odometry)
    exact = ArenaWorld("two_rooms", sensor=sensor, odometry=WheelOdometry(**EXACT))
    heading0 = Motion.from_samples(np.vstack([b.positions, b.positions[-1:]]), 0.1).heading[0]
    truth = _start_frame(b.positions, heading0)
    ideal = exact.simulate(1000, None, np.random.default_rng(3)).odometry
    assert np.allclose(ideal[:, :2], truth, atol=1e-9)
    assert np.hypot(*(b.odometry[-1, :2] - truth[-1])) > 0.01


@pytest.mark.parametrize("value, message", [
    ("odometry.speed_noise=-0.1", r"odometry.speed_noise must be a non-negative number"),
    ("odometry.slip_rate=-1", r"odometry.slip_rate must be a non-negative number"),
])
def test_bad_odometry_settings_are_one_line(value, message, make_cfg):
    with pytest.raises(ValueError, match=message):
        check_and_build(make_cfg(["env=arena", "odometry=wheel", value]))


def test_odometry_goes_only_to_a_world_that_takes_it(make_cfg):
    with pytest.raises(ValueError, match=r"^odometry=wheel: env=office takes no odometry; "
                                         r"env=arena does"):
        check_and_build(make_cfg(["odometry=wheel"]))
    with pytest.raises(ValueError, match=r"odometry"):
        ArenaWorld("open", odometry="gps")


def test_the_command_writes_the_odometry_with_the_walk(tmp_path, make_cfg):
    run(make_cfg(["env=arena", "sensor=range", "sensor.frame=egocentric", "actions=turns",
                  "odometry=wheel", "data.n_steps=300", "data.heldout_steps=100",
                  "clusters.ns=6", "stop.n_states=10", "output.progress=false",
                  "output.figures=false"]), tmp_path)
    traj = load_trajectory(tmp_path / "trajectory.npz")
    assert traj.odometry.shape == (300, 3) and traj.odometry[0].tolist() == [0, 0, 0]
    run(make_cfg(["env=arena", "odometry=none", "data.n_steps=300", "data.heldout_steps=0",
                  "clusters.ns=6", "stop.n_states=10", "output.progress=false",
                  "output.figures=false"]), tmp_path / "none")
    assert load_trajectory(tmp_path / "none" / "trajectory.npz").odometry is None
