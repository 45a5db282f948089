"""Odometry from egocentric scans alone: registration of a scan of a rectangular room."""

import numpy as np
import pytest

from topomap.core.motion import registration as R
from topomap.core.motion.reckoning import compose, relative_pose

W, H = 2.0, 1.2     # m: a rectangular room, wider than deep (no turn by 90 degrees maps it onto
B = 60              # itself, nor by 180 degrees about a point off its centre); beams
MAX_RANGE = 3.5


def _scan(x, y, heading, n=B):
    """(n,) exact ranges from ``(x, y)`` inside the room [0, W] x [0, H], beam ``k`` at
    ``heading + 2 pi k / n``: the nearest of the four walls along each beam."""
    a = heading + 2 * np.pi * np.arange(n) / n
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (W - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (H - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(np.minimum(tx, ty), MAX_RANGE)


def test_points_of_a_scan_drop_beams_with_no_return():
    scan = _scan(0.6, 0.5, 0.0)
    scan[[3, 40]] = MAX_RANGE
    P, valid = R.scan_points(scan, MAX_RANGE)
    assert not valid[3] and not valid[40] and valid.sum() == B - 2
    # beam 0 points along the heading (x), beam B / 4 to the left (y)
    assert P[0] == pytest.approx([W - 0.6, 0.0])
    assert P[B // 4] == pytest.approx([0.0, H - 0.5], abs=1e-12)


def test_compose_and_relative_undo_each_other():
    a, b = np.array([0.3, -0.2, 0.7]), np.array([0.05, 0.02, -0.3])
    np.testing.assert_allclose(relative_pose(a, compose(a, b)), b, atol=1e-12)


@pytest.mark.parametrize("move", [(0.03, 0.0, 0.0), (0.02, 0.01, 0.15), (-0.01, 0.02, -0.25)])
def test_registration_recovers_a_known_rigid_motion(move):
    # the robot at (0.7, 0.45) heading 0.3 rad moves by ``move`` in its own frame; the scan
    # there, registered against the first from no motion at all, gives that move.  Beams are
    # 6 degrees apart, points on the walls 0.05-0.15 m apart; a line through a point and its
    # neighbours is exact on a wall, wrong only for the 8 points of 60 beside the four corners,
    # whose line cuts the corner and lies up to ~1.5 cm off either wall: averaged over the 60
    # points, up to 8 x 1.5 / 60 = 2 mm of translation, and 2 mm over the mean range (0.6 m)
    # of turn.  A wrong match is off by centimetres and tenths of a radian.
    start = np.array([0.7, 0.45, 0.3])
    end = compose(start, np.array(move))
    m, paired, _ = R.register(_scan(*start), _scan(*end), MAX_RANGE - 1e-9)
    assert paired == B
    np.testing.assert_allclose(m[:2], move[:2], atol=2e-3)
    assert m[2] == pytest.approx(move[2], abs=2e-3 / 0.6)


def test_scan_odometry_follows_a_walk_and_a_sudden_half_turn():
    # 60 steps of 1 cm forward turning 0.02 rad a step, a sudden turn of 2 rad (a robot bounced
    # off a wall: beyond every start but the retry's sweep), then 30 more steps.  Every step's
    # pose from the scans alone, from (0, 0, 0) at the first step, is the true pose in the
    # first step's frame; a keyframe every 5 cm (and at the sudden turn), so at most 18
    # registrations chain, each within 2 mm and 2 mm / 0.6 m of turn (the test above): the
    # walk within 18 x 2 mm and 18 x 3.3e-3 rad.  Missing the sudden turn costs 2 rad.
    poses = [np.array([0.5, 0.4, 0.2])]
    for t in range(90):
        turn = 2.0 if t == 60 else 0.02
        poses.append(compose(poses[-1], np.array([0.01, 0.0, turn])))
    X = np.array([_scan(*p) for p in poses])
    est = R.scan_odometry(X, MAX_RANGE)
    truth = np.array([relative_pose(poses[0], p) for p in poses])
    np.testing.assert_allclose(est[:, :2], truth[:, :2], atol=18 * 2e-3)
    np.testing.assert_allclose(est[:, 2], truth[:, 2], atol=18 * 2e-3 / 0.6)


def test_scan_odometry_stops_when_asked_and_otherwise_reads_the_same_poses(monkeypatch):
    """``stop`` is asked before each run of ``STOP_EVERY`` steps (20 steps in runs of 3: 7
    asks): true at the fifth asking, no poses (None); never true, the poses read without it, to
    the bit; in runs of 3 or of 1 step, the same poses as in one run."""
    poses = [np.array([0.5, 0.4, 0.0])]
    for _ in range(20):
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 0.02])))
    X = np.array([_scan(*p) for p in poses])
    whole = R.scan_odometry(X, MAX_RANGE)
    monkeypatch.setattr(R, "STOP_EVERY", 3)
    asked = []
    assert R.scan_odometry(X, MAX_RANGE, stop=lambda: asked.append(1) or len(asked) == 5) is None
    assert len(asked) == 5
    asked = []
    np.testing.assert_array_equal(R.scan_odometry(X, MAX_RANGE, stop=lambda: asked.append(1)),
                                  whole)
    assert len(asked) == 7
    monkeypatch.setattr(R, "STOP_EVERY", 1)
    np.testing.assert_array_equal(R.scan_odometry(X, MAX_RANGE, stop=lambda: False), whole)


def test_a_walk_longer_than_halves_is_registered_as_two_halves_joined_at_the_middle_scan(
        monkeypatch):
    # the walk of the sudden half turn above, 91 scans, registered in halves from HALVES = 40
    # scans on: the first half (scans 0-45) as alone, the second (45-90) from scan 45 put in
    # the first half's pose of scan 45 -- and, as one run, within the chained keyframes'
    # error of the truth (18 of 2 mm above, one more for the keyframe the join starts)
    poses = [np.array([0.5, 0.4, 0.2])]
    for t in range(90):
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 2.0 if t == 60 else 0.02])))
    X = np.array([_scan(*p) for p in poses])
    first, second = R.scan_odometry(X[:46], MAX_RANGE), R.scan_odometry(X[45:], MAX_RANGE)
    monkeypatch.setattr(R, "HALVES", 40)
    monkeypatch.setattr(R, "STOP_EVERY", 1)
    est = R.scan_odometry(X, MAX_RANGE)
    np.testing.assert_array_equal(est[:46], first)
    np.testing.assert_array_equal(est[45:], [compose(first[45], p) for p in second])
    truth = np.array([relative_pose(poses[0], p) for p in poses])
    np.testing.assert_allclose(est[:, :2], truth[:, :2], atol=19 * 2e-3)
    np.testing.assert_allclose(est[:, 2], truth[:, 2], atol=19 * 2e-3 / 0.6)
    # stopped in either half: no poses
    asked = []
    assert R.scan_odometry(X, MAX_RANGE, stop=lambda: asked.append(1) or len(asked) > 60) is None


def test_the_halves_rivals_are_numbered_and_placed_in_the_whole_walk(monkeypatch):
    # each half's registration (faked: 1 m forward a step from its first scan, a rival pose
    # at its second step) is put in the walk: the second half's steps and poses after the
    # first half's pose of the scan they share (step 5 of 10, at (5, 0))
    def halve(X, max_range, alternatives, stop):
        alternatives.append((1, np.array([1.0, 1.0, 0.5])))
        return np.column_stack([np.arange(len(X), dtype=float), np.zeros((len(X), 2))])

    monkeypatch.setattr(R, "HALVES", 8)
    monkeypatch.setattr(R, "_registered", halve)
    rivals = []
    est = R.scan_odometry(np.ones((10, 4)), 2.0, alternatives=rivals)
    np.testing.assert_array_equal(est[:, 0], np.arange(10))
    assert [t for t, _ in rivals] == [1, 6]
    np.testing.assert_array_equal(rivals[1][1], [6.0, 1.0, 0.5])


def test_scan_odometry_reads_the_largest_range_as_no_return():
    poses = [np.array([0.5, 0.4, 0.0])]
    for _ in range(20):
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 0.0])))
    X = np.array([_scan(*p) for p in poses])
    X[:, 7] = 9.0  # one beam never returns: the largest reading, left out
    est = R.scan_odometry(X)
    # 4 keyframes of 5 cm, each within 2 mm (above)
    assert est[-1] == pytest.approx([0.2, 0.0, 0.0], abs=4 * 2e-3)


def test_a_turn_by_half_a_turn_where_the_scans_look_alike_turned_round_is_refused():
    # at the centre of the rectangular room a scan turned by pi is the same scan (the room is
    # point-symmetric about its centre), so a step that turns by 0.02 rad registers from a
    # start of 0.02 and from one of 0.02 + pi at the same cost: the registration cannot tell
    # them apart and the walk keeps the turn nearer the step before's pose (0.02, not pi)
    c = (W / 2, H / 2)
    ref, scan = _scan(*c, 0.3), _scan(*c, 0.32)
    results = R.register_each(ref, scan, MAX_RANGE - 1e-9, [(0.0, 0.0, 0.02 + np.pi),
                                                            (0.0, 0.0, 0.02)])
    (turned, _, cost_turned), (kept, _, cost_kept) = results
    assert abs(abs(turned[2] - kept[2]) - np.pi) < 1e-3
    assert cost_turned == pytest.approx(cost_kept, rel=1e-6)
    m, _, _ = R.checked_turn(results, np.zeros(3))
    assert m[2] == pytest.approx(0.02, abs=2e-3 / 0.6)


def test_a_turn_by_half_a_turn_that_fits_far_better_is_kept():
    # a turn beyond TURN_CHECK costing under RETRY_GAIN of the best smaller one is kept (a
    # robot bounced off a wall); at RETRY_GAIN or more it gives way to the smaller
    small = (np.array([0.01, 0.0, 0.05]), 60, 10.0)
    before = np.array([0.0, 0.0, 0.1])
    for cost, kept_turn in ((R.RETRY_GAIN * 10.0 - 0.01, 3.0), (R.RETRY_GAIN * 10.0, 0.05)):
        turned = (np.array([0.0, 0.0, 3.0]), 60, cost)
        assert R.checked_turn([turned, small], before)[0][2] == kept_turn
    # a turn of TURN_CHECK or less from the step before is no half turn: the least cost wins
    near = (np.array([0.0, 0.0, 0.1 + R.TURN_CHECK]), 60, 9.9)
    assert R.checked_turn([near, small], before) is near


def _walk_poses(T, turn_at=None, turn=np.pi):
    """(T, 3) poses of 1 cm steps turning 0.01 rad a step; ``turn`` more at step ``turn_at``."""
    poses = [np.zeros(3)]
    for t in range(1, T):
        poses.append(compose(poses[-1], np.array([0.01, 0.0, 0.01 + (turn if t == turn_at
                                                                          else 0.0)])))
    return np.array(poses)


def test_resolve_turns_takes_the_rival_the_loops_agree_with():
    # a walk whose registration turned wrongly by pi at step 50 (the truth turns 0.01 there):
    # closures across step 50 state the true turn between their ends; the rival pose of step 50
    # (the true one, as the registration's rival gives it) agrees with all of them and the
    # poses from step 50 on move with it, rigidly -- the truth again
    T = 120
    truth, wrong = _walk_poses(T), _walk_poses(T, turn_at=50)
    ci, cj = np.array([10, 30, 110]), np.array([60, 90, 20])
    closures = (ci, cj, truth[cj, 2] - truth[ci, 2])
    fixed = R.resolve_turns(wrong, [(50, truth[50])], closures)
    np.testing.assert_allclose(fixed, truth, atol=1e-9)
    # the rival is kept out where the closures agree with the poses as they are
    kept = R.resolve_turns(truth, [(50, wrong[50])], closures)
    np.testing.assert_allclose(kept, truth, atol=0)
    # and where no closure crosses the step (both ends before it)
    np.testing.assert_allclose(R.resolve_turns(wrong, [(50, truth[50])],
                                               (np.array([0]), np.array([40]), np.array([0.4]))),
                               wrong, atol=0)


def test_scan_points_of_many_scans_are_each_scans_own_and_pairs_register_as_alone():
    X = np.array([_scan(0.6, 0.5, 0.1), _scan(0.62, 0.5, 0.15), _scan(0.9, 0.7, -0.2)])
    P, valid = R.scan_points(X, MAX_RANGE - 1e-9)
    for k in range(3):
        Pk, vk = R.scan_points(X[k], MAX_RANGE - 1e-9)
        np.testing.assert_array_equal(P[k], Pk)
        np.testing.assert_array_equal(valid[k], vk)
    starts = np.array([[0.0, 0.0, 0.05], [0.0, 0.0, -0.3]])
    m, cost = R._register_pairs(P, valid, np.array([0, 0]), np.array([1, 2]), starts)
    for e, j in enumerate((1, 2)):
        one, _, c = R.register(X[0], X[j], MAX_RANGE - 1e-9, [starts[e]])
        np.testing.assert_array_equal(m[e], one)
        assert cost[e] == c


def test_the_retry_weighs_a_cost_against_the_lesser_of_the_recent_median_and_the_step_before():
    # a stretch of poor registrations (cost 40) then a good one (17.3): a wrong turn costing
    # 53.3 lies below twice the median (80) but above twice the step before (34.6)
    costs = [40.0] * 99 + [17.3]
    assert R.retry_yardstick(costs) == 17.3
    assert 53.3 > R.RETRY_COST * R.retry_yardstick(costs)
    # a step before dearer than the recent median: the median (10)
    assert R.retry_yardstick([10.0] * 50 + [30.0]) == 10.0
    # only the last RECENT costs make the median: 40 of 100 at 7, 60 at 5 -> 5
    assert R.retry_yardstick([100.0] * 200 + [7.0] * 40 + [5.0] * 59 + [50.0]) == 5.0



def _keyframe(pose):
    """An older keyframe's entry for :func:`R.averaged_pose`: its lines (normals, centres and
    nearest-point cache), of the exact scan at ``pose`` in the rectangular room."""
    P, valid = R.scan_points(_scan(*pose), MAX_RANGE - 1e-9)
    return R.keyframe_lines(P, valid)


def test_a_pose_off_by_a_centimetre_is_averaged_with_older_keyframes_that_see_it_right():
    # the scan at ``truth``; its keyframe's registration put it 1 cm east and 0.03 rad off.
    # Registered (exact scans) against two older keyframes at their true poses, each gives
    # the truth within 2 mm / 0.003 rad (the corners' lines, test above), so the mean of the
    # three lies a third of the error off: 3.3 mm and 0.01 rad, within 1.5 mm / 0.002 rad.
    truth = np.array([0.9, 0.55, 0.2])
    off = truth + [0.01, 0.0, 0.03]
    keys = [np.array([0.8, 0.5, 0.1]), np.array([0.85, 0.52, 0.15])]
    older = R.older_keyframes(_keyframe(keys[0]))
    for k in keys:
        older = R.add_keyframe(older, k, _keyframe(k))
    Q, Qv = R.scan_points(_scan(*truth), MAX_RANGE - 1e-9)
    got = R.averaged_pose(off, 100.0, older, Q, Qv)
    np.testing.assert_allclose(got[:2], truth[:2] + [0.01 / 3, 0.0], atol=1.5e-3)
    assert got[2] == pytest.approx(truth[2] + 0.01, abs=2e-3)
    # no older keyframe: the pose as it was
    none = R.older_keyframes(_keyframe(keys[0]))
    np.testing.assert_array_equal(R.averaged_pose(off, 100.0, none, Q, Qv), off)


def test_an_older_keyframe_costing_more_than_the_gate_allows_is_left_out():
    truth, key = np.array([0.9, 0.55, 0.2]), np.array([0.8, 0.5, 0.1])
    off = truth + [0.01, 0.0, 0.0]
    older = R.add_keyframe(R.older_keyframes(_keyframe(key)), key, _keyframe(key))
    Q, Qv = R.scan_points(_scan(*truth), MAX_RANGE - 1e-9)
    _, _, cost = R.register_each(_scan(*key), _scan(*truth), MAX_RANGE - 1e-9,
                                 [relative_pose(key, off)])[0]
    limit = cost / R.AVERAGE_COST
    np.testing.assert_array_equal(R.averaged_pose(off, 0.99 * limit, older, Q, Qv), off)
    got = R.averaged_pose(off, 1.01 * limit, older, Q, Qv)
    assert got[0] == pytest.approx(truth[0] + 0.005, abs=1.5e-3)


def test_the_older_keyframes_registered_in_one_call_are_each_ones_registration_to_the_bit():
    # nine keyframes added, the first two left out (OLDER_KEYFRAMES 7); each of the seven kept
    # gives the pose and cost of its own registration from relative_pose's start, put back by
    # compose (the per-keyframe route), bit for bit, in the order added
    keys = [np.array([0.6 + 0.05 * k, 0.4 + 0.02 * k, 0.1 * k - 0.3]) for k in range(9)]
    older = R.older_keyframes(_keyframe(keys[0]))
    for k in keys:
        older = R.add_keyframe(older, k, _keyframe(k))
    assert len(older[0]) == len(older[1]) == R.OLDER_KEYFRAMES == 7
    pose = np.array([0.93, 0.57, 0.21])
    Q, Qv = R.scan_points(_scan(0.9, 0.55, 0.2), MAX_RANGE - 1e-9)
    got, cost = R._register_older(*older, pose, Q, Qv)
    for k, key in enumerate(keys[2:]):
        m, _, c = R.register_each(_scan(*key), _scan(0.9, 0.55, 0.2), MAX_RANGE - 1e-9,
                                  [relative_pose(key, pose)])[0]
        np.testing.assert_array_equal(got[k], compose(key, m))
        assert cost[k] == c
