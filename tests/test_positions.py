"""Positions as data: (T, 2) or (T, 3) metres, checked, and kept through .npz and .csv files."""

from __future__ import annotations

import numpy as np
import pytest

from topomap import Trajectory, load_trajectory, save_trajectory


def walk(T: int = 6, dims: int = 2) -> Trajectory:
    """A short trajectory whose positions are not round numbers (repr must keep them exact)."""
    rng = np.random.default_rng(1)
    return Trajectory(rng.normal(size=(T, 3)), rng.integers(0, 3, T),
                      positions=rng.uniform(-2, 5, size=(T, dims)), lengths=[T - 2, 2])


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_positions_survive_files(tmp_path, dims, suffix):
    traj = walk(dims=dims)
    back = load_trajectory(save_trajectory(traj, tmp_path / f"walk{suffix}"))
    assert back.positions.shape == (6, dims)
    assert np.array_equal(back.positions, traj.positions)
    assert np.array_equal(back.lengths, traj.lengths)


def test_csv_header_names_the_position_columns(tmp_path):
    path = save_trajectory(walk(dims=3), tmp_path / "walk.csv")
    assert path.read_text().splitlines()[0] == "o0,o1,o2,action,x,y,z,episode"


@pytest.mark.parametrize("positions, match", [
    (np.zeros((5, 2)), r"positions has 5 rows but observations has 4 rows"),
    (np.zeros((4, 1)), r"positions must have shape \(4, 2\) or \(4, 3\), got \(4, 1\)"),
    (np.zeros(4), r"positions must have shape \(4, 2\) or \(4, 3\), got \(4,\)"),
    (np.zeros((4, 2, 1)), r"positions must have shape"),
    ([[0, 0], [1, 1], [2], [3, 3]], r"positions must be a rectangular array"),
    (np.array([["a", "b"]] * 4), r"positions must be numbers"),
    (np.array([[0, 0], [0, np.nan], [1, 1], [np.inf, 0]]),
     r"positions contain NaN or inf in 2 row\(s\), first at step 1"),
])
def test_bad_positions_are_one_line_errors_naming_positions(positions, match):
    with pytest.raises(ValueError, match=match) as err:
        Trajectory(np.zeros((4, 2)), [0, 1, 0, 1], positions=positions)
    assert "\n" not in str(err.value)


def test_a_file_with_nan_positions_is_refused_naming_file_and_field(tmp_path):
    p = tmp_path / "bad.npz"
    np.savez(p, observations=np.zeros((3, 1)), actions=np.zeros(3, dtype=int),
             positions=np.array([[0.0, 0.0], [np.nan, 1.0], [1.0, 1.0]]))
    with pytest.raises(ValueError, match=r"bad.npz: positions contain NaN"):
        load_trajectory(p)
