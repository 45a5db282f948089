"""``Trajectory.odometry``: the robot's own dead reckoning, kept through .npz and .csv files and
refused in one line (naming the field and the step) when it cannot be a robot's odometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from topomap import Trajectory, load_trajectory, save_trajectory
from topomap.core.data.odometry import (MAX_ODOMETRY_STEP, check_odometry, quaternion_of_yaw,
                                        yaw_of_quaternion)


def odometry_walk(T: int = 6) -> Trajectory:
    """``T`` steps; the odometry drives 0.1 m per step along a heading that turns 0.3 rad per
    step, the heading running past pi (no wrapping) to test that the files keep it as given."""
    theta = 0.3 * np.arange(T) + 2.5
    xy = np.cumsum(0.1 * np.c_[np.cos(theta), np.sin(theta)], axis=0)
    rng = np.random.default_rng(0)
    return Trajectory(rng.normal(size=(T, 2)), rng.integers(0, 3, T),
                      positions=rng.uniform(0, 4, (T, 2)), odometry=np.c_[xy, theta])


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_odometry_is_kept_by_the_files_exactly(tmp_path, suffix):
    traj = odometry_walk()
    back = load_trajectory(save_trajectory(traj, tmp_path / f"walk{suffix}"))
    assert back.odometry.dtype == np.float64 and back.odometry.shape == (6, 3)
    assert np.array_equal(back.odometry, traj.odometry)  # npz binary, csv repr(): both exact
    assert np.array_equal(back.positions, traj.positions)  # the truth stays apart from it


def test_the_csv_columns_are_named_odom_x_odom_y_odom_theta(tmp_path):
    traj = odometry_walk(2)
    save_trajectory(traj, tmp_path / "w.csv")
    header = (tmp_path / "w.csv").read_text().splitlines()[0].split(",")
    assert header == ["o0", "o1", "action", "x", "y", "odom_x", "odom_y", "odom_theta"]
    assert load_trajectory(save_trajectory(Trajectory(traj.observations, traj.actions),
                                           tmp_path / "none.csv")).odometry is None


def test_a_csv_with_some_odometry_columns_names_the_missing_ones(tmp_path):
    path = tmp_path / "part.csv"
    path.write_text("o0,action,odom_x,odom_y\n0.5,0,1.0,2.0\n")
    with pytest.raises(ValueError, match=r"part.csv has the odometry column\(s\) odom_x, odom_y "
                                         r"but not odom_theta"):
        load_trajectory(path)
    path.write_text("o0,action,odom_th\n0.5,0,1.0\n")
    with pytest.raises(ValueError, match="did you mean 'odom_theta'"):
        load_trajectory(path)


@pytest.mark.parametrize("odometry, match", [
    (np.zeros((4, 2)), r"odometry must have shape \(4, 3\): x and y in metres and the heading in "
                       r"radians; got \(4, 2\)"),
    (np.zeros((3, 3)), "odometry has 3 rows but observations has 4 rows"),
    (np.zeros(4), r"odometry must have shape \(4, 3\)"),
    ([[0, 0, 0], [0, 0], [0, 0, 0], [0, 0, 0]], "odometry must be a rectangular array"),
    (np.array([["a", "b", "c"]] * 4), "odometry must be numbers"),
    (np.array([[0, 0, 0], [0, 0, 0], [0, np.nan, 0], [np.inf, 0, 0]]),
     r"odometry contains NaN or inf in 2 row\(s\), first at step 2"),
    (np.array([[0, 0, 0], [0, 0, np.inf], [0, 0, 0], [0, 0, 0]]), "first at step 1"),
])
def test_bad_odometry_is_refused_naming_the_field(odometry, match):
    with pytest.raises(ValueError, match=match):
        Trajectory(np.zeros((4, 1)), np.zeros(4, dtype=int), odometry=odometry)


def test_a_jump_of_metres_in_one_step_is_refused_naming_the_steps():
    # steps of 0.1, 0.1, then 3.0 m (sqrt(1.8^2 + 2.4^2) = 3.0 by hand): steps 2 -> 3
    odometry = [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [2.0, 2.4, 0], [2.1, 2.4, 0]]
    with pytest.raises(ValueError, match=r"odometry moves 3 m from step 2 to step 3, more than "
                                         r"MAX_ODOMETRY_STEP = 2 m in one step .* start a new "
                                         r"episode at step 3"):
        Trajectory(np.zeros((5, 1)), np.zeros(5, dtype=int), odometry=odometry)


def test_the_jump_threshold_is_inclusive_and_ignores_the_heading():
    steps = np.zeros((2, 1)), np.zeros(2, dtype=int)
    at = Trajectory(*steps, odometry=[[0, 0, 3.1], [MAX_ODOMETRY_STEP, 0, -3.1]])  # heading wraps
    assert at.odometry[1, 0] == MAX_ODOMETRY_STEP
    with pytest.raises(ValueError, match="from step 0 to step 1"):
        Trajectory(*steps, odometry=[[0, 0, 0], [MAX_ODOMETRY_STEP + 1e-9, 0, 0]])


def test_an_odometry_reset_between_episodes_is_no_jump():
    # two episodes of 2 steps, the second's odometry starting 50 m away: allowed; a jump inside
    # the second episode is refused with its step in the whole trajectory
    X, u = np.zeros((4, 1)), np.zeros(4, dtype=int)
    reset = [[0, 0, 0], [0.1, 0, 0], [50, 0, 0], [50.1, 0, 0]]
    assert Trajectory(X, u, lengths=[2, 2], odometry=reset).odometry[2, 0] == 50
    with pytest.raises(ValueError, match="from step 2 to step 3"):
        Trajectory(X, u, lengths=[2, 2], odometry=[[0, 0, 0], [0.1, 0, 0], [50, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="from step 1 to step 2"):
        Trajectory(X, u, odometry=reset)  # one episode: the same reset is a jump


def test_a_file_with_bad_odometry_names_the_file(tmp_path):
    path = tmp_path / "bad.npz"
    np.savez(path, observations=np.zeros((3, 1)), actions=np.zeros(3, dtype=int),
             odometry=np.array([[0, 0, 0], [0, 0, 0], [9, 0, 0]], dtype=float))
    with pytest.raises(ValueError, match=r"trajectory file .*bad.npz: odometry moves 9 m from "
                                         r"step 1 to step 2"):
        load_trajectory(path)
    traj = odometry_walk(3)
    traj.odometry = np.ones((3, 2))  # changed after it was made: refused before writing
    with pytest.raises(ValueError, match=r"cannot write trajectory file .*: odometry must have"):
        save_trajectory(traj, tmp_path / "out.npz")
    assert not (tmp_path / "out.npz").exists()


def test_check_odometry_returns_float64():
    out = check_odometry(np.array([[1, 2, 3]], dtype=np.int32), 1)
    assert out.dtype == np.float64 and out.tolist() == [[1.0, 2.0, 3.0]]


@pytest.mark.parametrize("yaw", [0.0, 0.5, math.pi / 2, -2.0, 3.0])
def test_yaw_of_a_quaternion_about_z(yaw):
    # q = (0, 0, sin(yaw/2), cos(yaw/2)) rotates by yaw about z; any positive multiple of it too
    q = quaternion_of_yaw(yaw)
    assert q == (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    assert yaw_of_quaternion(*q) == pytest.approx(yaw, abs=1e-12)
    assert yaw_of_quaternion(*(3.0 * v for v in q)) == pytest.approx(yaw, abs=1e-12)


def test_yaw_ignores_a_roll_and_refuses_the_zero_quaternion():
    # a roll of 0.7 rad about x alone, (sin 0.35, 0, 0, cos 0.35), turns the robot's heading by 0
    assert yaw_of_quaternion(math.sin(0.35), 0.0, 0.0, math.cos(0.35)) == 0.0
    # yaw 1.0 then roll 0.7: q = qz(1.0) * qx(0.7) = (cz*sx, sz*sx, sz*cx, cz*cx)
    cz, sz, cx, sx = math.cos(0.5), math.sin(0.5), math.cos(0.35), math.sin(0.35)
    assert yaw_of_quaternion(cz * sx, sz * sx, sz * cx, cz * cx) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError, match="zero quaternion"):
        yaw_of_quaternion(0.0, 0.0, 0.0, 0.0)
