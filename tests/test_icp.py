"""The registration's nearest-point pairing with its cache: the points a search over every point
pairs, whatever the points, ties and moves."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from topomap.core.motion import icp as I
from topomap.core.motion import registration as R


def _brute(P, Pv, N, qx, qy, max_pair):
    """The pair of a search over every point: the first of the nearest usable points, if its
    squared distance is below ``max_pair`` squared, else -1."""
    best, j = max_pair * max_pair, -1
    for k in range(len(P)):
        if Pv[k] and (N[k, 0] != 0.0 or N[k, 1] != 0.0):
            dx, dy = P[k, 0] - qx, P[k, 1] - qy
            d = dx * dx + dy * dy
            if d < best:
                best, j = d, k
    return j


def _pairs(P, cache, Q, max_pair):
    """Each of points ``Q`` (B, 2) paired through ``cache`` at the pose (0, 0, 0), which leaves
    them where they are."""
    qs, js = np.zeros((len(Q), 2)), np.zeros(len(Q), dtype=np.int64)
    I._pair_points(P, cache, Q, np.ones(len(Q), dtype=np.bool_), 0.0, 0.0, 0.0, max_pair, qs,
                   js)
    np.testing.assert_array_equal(qs, Q)
    return js


def test_a_kept_nearest_serves_a_move_within_half_the_gap_and_a_longer_move_searches_again():
    # from (0.1, 0) the nearest four are points 0-3 (0.1, 0.9, 1.005, 2.7 m); point 4 lies
    # 4.17 m off: a move below (4.17 - 0.1) / 2 keeps the anchor and pairs from those four
    P = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 2.0], [3.0, 3.0]])
    N = np.ones_like(P)
    cache = I.pairing(P, np.ones(5, dtype=np.bool_), N, 1)
    assert list(_pairs(P, cache, np.array([[0.1, 0.0]]), 0.15)) == [0]
    np.testing.assert_array_equal(cache[3][0], [0.1, 0.0])
    assert sorted(cache[4][0]) == [0, 1, 2, 3]
    assert list(_pairs(P, cache, np.array([[1.1, 0.0]]), 0.15)) == [1]
    np.testing.assert_array_equal(cache[3][0], [0.1, 0.0])    # kept: moved 1 m of 2.04
    assert list(_pairs(P, cache, np.array([[1.5, 0.0]]), 0.15)) == [-1]  # none near enough
    # 4.03 m from the anchor: searched again, point 4 (left out of the four) is the nearest
    assert list(_pairs(P, cache, np.array([[2.9, 2.9]]), 0.15)) == [4]
    np.testing.assert_array_equal(cache[3][0], [2.9, 2.9])


def test_equally_near_points_pair_with_the_first_and_an_unusable_point_never():
    # (0.5, 0) lies 0.5 from points 1 and 2 alike: the first; point 0 has no line (normal 0),
    # point 3 no return; a distance of exactly max_pair is no pair
    P = np.array([[0.5, 0.0], [0.0, 0.0], [1.0, 0.0], [0.5, 0.0]])
    N = np.array([[0.0, 0.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    Pv = np.array([True, True, True, False])
    cache = I.pairing(P, Pv, N, 1)
    assert list(_pairs(P, cache, np.array([[0.5, 0.0]]), 0.75)) == [1]
    assert list(_pairs(P, cache, np.array([[0.5, 0.0]]), 0.5)) == [-1]
    assert list(_pairs(P, cache, np.array([[0.75, 0.0]]), 0.5)) == [2]


_grid = st.integers(-8, 8).map(lambda v: v / 16)       # exact binary fractions: exact ties


@settings(max_examples=150, deadline=None)
@given(pts=st.lists(st.tuples(_grid, _grid, st.booleans(), st.booleans()), max_size=12),
       start=st.lists(st.tuples(_grid, _grid), min_size=1, max_size=5),
       moves=st.lists(st.tuples(st.integers(-40, 40), st.integers(-40, 40)), max_size=8),
       max_pair=st.sampled_from([0.125, 0.15, 0.25, 1.0]))
def test_pairs_through_the_cache_are_those_of_a_search_over_every_point(pts, start, moves,
                                                                      max_pair):
    P = np.array([p[:2] for p in pts], dtype=np.float64).reshape(-1, 2)
    Pv = np.array([p[2] for p in pts], dtype=np.bool_)
    N = np.array([[0.0, 1.0] if p[3] else [0.0, 0.0] for p in pts]).reshape(-1, 2)
    Q = np.array(start, dtype=np.float64)
    cache = I.pairing(P, Pv, N, len(Q))
    for step in [(0, 0)] + moves:   # every point moved alike by step / 256 m, then paired
        Q = Q + np.array(step) / 256
        want = [_brute(P, Pv, N, qx, qy, max_pair) for qx, qy in Q]
        assert list(_pairs(P, cache, Q, max_pair)) == want


def _room_scan(x, y, heading, n=60, w=2.0, h=1.2):
    """(n,) exact ranges from ``(x, y)`` inside the room [0, w] x [0, h]."""
    a = heading + 2 * np.pi * np.arange(n) / n
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (w - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (h - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)


def test_a_registration_through_a_shared_cache_equals_one_through_a_fresh_cache():
    # a keyframe's cache warmed by other scans and starts leaves each registration's bits
    key = _room_scan(0.8, 0.5, 0.1)
    P, Pv = R.scan_points(key, 10.0)
    N, C, shared = R.keyframe_lines(P, Pv)
    rng = np.random.default_rng(3)
    for pose in ([0.82, 0.5, 0.12], [0.9, 0.6, 0.3], [0.7, 0.45, -0.2]):
        Q, Qv = R.scan_points(_room_scan(*pose) + rng.normal(0, 0.01, 60), 10.0)
        for x0 in (np.zeros(3), np.array([0.05, 0.0, 0.1]), np.array([0.0, 0.0, 3.0])):
            fresh = I.icp(I.pairing(C, Pv, N, 60), C, N, Q, Qv, x0, 12, 0.02, 0.15)
            warm = I.icp(shared, C, N, Q, Qv, x0, 12, 0.02, 0.15)
            np.testing.assert_array_equal(warm[0], fresh[0])
            assert warm[1:] == fresh[1:]


def _loss_at(motion, C, Cv, N, Q, Qv, cauchy, max_pair):
    """The Cauchy loss of points ``Q`` moved by ``motion`` on the lines through ``C``, each paired
    by a search over every point, an unpaired one costing as one ``max_pair`` from its line."""
    x, y, th = motion
    c, s = np.cos(th), np.sin(th)
    total = 0.0
    for (qx0, qy0), ok in zip(Q, Qv):
        if not ok:
            continue
        qx, qy = c * qx0 - s * qy0 + x, s * qx0 + c * qy0 + y
        j = _brute(C, Cv, N, qx, qy, max_pair)
        r = max_pair if j < 0 else N[j, 0] * (qx - C[j, 0]) + N[j, 1] * (qy - C[j, 1])
        total += np.log(1.0 + (r / cauchy) ** 2)
    return total


@pytest.mark.parametrize("iters", [0, 1, 12])
def test_the_cost_is_the_loss_where_the_registration_ends(iters):
    # the cost and the points paired are those of the motion returned, after any iterations
    key = _room_scan(0.8, 0.5, 0.1)
    P, Pv = R.scan_points(key, 10.0)
    N, C, cache = R.keyframe_lines(P, Pv)
    ranges = _room_scan(0.85, 0.55, 0.2) + np.random.default_rng(5).normal(0, 0.01, 60)
    ranges[1::10] -= 0.5         # points in the open room, far from any line: unpaired
    Q, Qv = R.scan_points(ranges, 10.0)
    Qv[::3] = False
    m, used, cost = I.icp(cache, C, N, Q, Qv, np.zeros(3), iters, 0.02, 0.15)
    assert cost == pytest.approx(_loss_at(m, C, Pv, N, Q, Qv, 0.02, 0.15), rel=1e-12)
    assert 3 <= used <= Qv.sum() - 4   # 4 valid points moved off the lines
    if iters:
        assert cost < _loss_at(np.zeros(3), C, Pv, N, Q, Qv, 0.02, 0.15)


def test_a_scan_with_too_few_points_stops_and_costs_where_it_stands():
    # two usable points give no step: the start is returned with its loss
    key = _room_scan(0.8, 0.5, 0.1)
    P, Pv = R.scan_points(key, 10.0)
    N, C, cache = R.keyframe_lines(P, Pv)
    Q, Qv = R.scan_points(_room_scan(0.8, 0.5, 0.1), 10.0)
    Qv[2:] = False
    x0 = np.array([0.01, -0.02, 0.03])
    m, used, cost = I.icp(cache, C, N, Q, Qv, x0, 12, 0.02, 0.15)
    np.testing.assert_array_equal(m, x0)
    assert used <= 2
    assert cost == pytest.approx(_loss_at(x0, C, Pv, N, Q, Qv, 0.02, 0.15), rel=1e-12)


@settings(max_examples=200, deadline=None)
@given(costs=st.lists(st.one_of(st.integers(0, 5).map(float), st.floats(0, 100),
                                st.just(float("nan"))), min_size=1, max_size=130))
def test_the_retry_yardstick_is_the_lesser_of_numpy_s_median_and_the_last_cost(costs):
    want = min(float(np.median(costs[-R.RECENT:])), float(costs[-1]))
    got = R.retry_yardstick(costs)
    assert got == want or (np.isnan(got) and np.isnan(want))


def test_the_gauss_newton_solve_is_numpys_to_the_bit_and_refuses_what_numpy_refuses():
    # LAPACK's dgesv called by name gives np.linalg.solve's answer bit for bit on symmetric
    # positive definite 3 x 3 systems (a registration's normal equations), and raises as it
    # does on a NaN and on a singular matrix
    rng = np.random.default_rng(5)
    lu, ints = np.zeros((3, 3)), np.array([3, 1, 3, 3, 0, 0, 0, 0], dtype=np.int32)
    for _ in range(200):
        J = rng.normal(size=(60, 3)) * rng.uniform(0.01, 10, 3)
        H, g = J.T @ J + 1e-9 * np.eye(3), rng.normal(size=3)
        np.testing.assert_array_equal(I._solve3(H, g.copy(), lu, ints), np.linalg.solve(H, g))
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        I._solve3(np.where(np.eye(3) > 0, np.nan, 0.0), np.ones(3), lu, ints)
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        I._solve3(np.zeros((3, 3)), np.ones(3), lu, ints)
