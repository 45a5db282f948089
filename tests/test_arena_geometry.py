"""Ray casting and the range finder against ranges computed by hand."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("ratinabox")

from topomap.worlds.arena import Layout, RangeFinder, builtin_layout  # noqa: E402
from topomap.worlds.arena.geometry import ray_distances  # noqa: E402
from topomap.worlds.arena.kinematics import Motion  # noqa: E402
from topomap.worlds.arena.world import Arena  # noqa: E402

SQUARE = Layout("square", [[0, 0], [1, 0], [1, 1], [0, 1]])
E, NE, N, W, S = 0.0, np.pi / 4, np.pi / 2, np.pi, 3 * np.pi / 2


def test_from_the_centre_of_a_unit_square_every_wall_is_half_a_metre_away():
    R = ray_distances([[0.5, 0.5]], [E, N, W, S], SQUARE.segments, max_range=5.0)
    assert np.allclose(R, 0.5)


def test_a_diagonal_beam_meets_the_corner():
    R = ray_distances([[0.5, 0.5], [0.25, 0.25]], [NE], SQUARE.segments, max_range=5.0)
    assert np.allclose(R[:, 0], [np.sqrt(0.5), 0.75 * np.sqrt(2)])


def test_a_wall_in_the_way_cuts_the_beam_and_the_nearest_wall_counts():
    walled = Layout("walled", SQUARE.boundary, walls=[[[0.75, 0.0], [0.75, 1.0]]])
    R = ray_distances([[0.5, 0.5], [0.9, 0.5]], [E, W], walled.segments, max_range=5.0)
    assert np.allclose(R, [[0.25, 0.5], [0.1, 0.15]])


def test_a_door_lets_the_beam_through_and_max_range_caps_it():
    rooms = builtin_layout("four_rooms")  # walls x=1 and y=1, doors of 0.3 m at 0.5 and 1.5
    R = ray_distances([[0.5, 0.5], [0.5, 0.2]], [E, N], rooms.segments, max_range=1.6)
    assert np.allclose(R, [[1.5, 1.5], [0.5, 1.6]])  # (0.5, 0.2) north: 1.8 through the door


def test_per_step_angles_and_a_beam_along_a_wall():
    # a beam running along the wall y=0 from (0.5, 0) meets the side wall x=1, not the floor wall
    R = ray_distances([[0.5, 0.0], [0.5, 0.5]], [[E], [S]], SQUARE.segments, max_range=5.0)
    assert np.allclose(R[:, 0], [0.5, 0.5])


def motion_at(points, headings) -> Motion:
    P = np.asarray(points, dtype=float)
    zeros = np.zeros(len(P))
    return Motion(times=zeros, positions=P, velocity=np.zeros_like(P),
                  heading=np.asarray(headings, dtype=float), rotational_velocity=zeros, dt=0.1)


def test_range_finder_compass_and_egocentric():
    arena = Arena.build(SQUARE)
    m = motion_at([[0.5, 0.2], [0.5, 0.2]], [0.0, N])
    compass = RangeFinder(n_beams=4, max_range=5.0).sense(arena, m)
    assert np.allclose(compass, [[0.5, 0.8, 0.5, 0.2]] * 2)  # east, north, west, south
    ego = RangeFinder(n_beams=4, max_range=5.0, frame="egocentric").sense(arena, m)
    assert np.allclose(ego, [[0.5, 0.8, 0.5, 0.2], [0.8, 0.5, 0.2, 0.5]])  # ahead, left, ...


def test_a_beam_that_never_sees_a_wall_is_an_error_naming_max_range():
    arena = Arena.build(SQUARE)
    with pytest.raises(ValueError, match=r"^max_range=0.3 m is too short: beam 0 \(0 degrees"):
        RangeFinder(n_beams=4, max_range=0.3).sense(arena, motion_at([[0.5, 0.5]], [0.0]))
    # near the east wall beam 0 sees it, but beam 1 (north) sees nothing anywhere on the path
    with pytest.raises(ValueError, match=r"beam 1 \(90 degrees, compass\) sees no wall"):
        RangeFinder(n_beams=4, max_range=0.3).sense(arena, motion_at([[0.9, 0.5], [0.5, 0.1]],
                                                                     [0.0, 0.0]))


@pytest.mark.parametrize("kwargs, match", [
    ({"n_beams": 0}, "n_beams must be a positive integer"),
    ({"max_range": -1.0}, "max_range must be a positive number"),
    ({"frame": "polar"}, "frame must be one of compass, egocentric"),
])
def test_range_finder_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RangeFinder(**kwargs)
