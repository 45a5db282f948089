"""The robot route (``MapLearner(motion="robot")``, :mod:`topomap.core.motion.robot`): the decoder
follows a known odometry across a tiny known map, the emission matches a scan at its rotation, and
a simulated robot's walk is learned and placed by its own odometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.motion.reckoning import command_poses, forward_moves, keyframes, reckon
from topomap.core.motion.robot import cells, successors
from topomap.core.motion.robot_decode import _BLOCK, emission, heading_kernel, viterbi
from topomap.core.motion.settings import motion_settings

# an L of five cells 0.1 m apart: east along y = 0, then north along x = 0.2
L_CELLS = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.2, 0.1], [0.2, 0.2]])
L_NEXT = [(0, 1), (1, 2), (2, 3), (3, 4)]


def _chain_successors(n, pairs):
    A = np.eye(n, dtype=bool)
    for a, b in pairs:
        A[a, b] = A[b, a] = True
    return np.r_[0, np.cumsum(A.sum(1))].astype(np.int64), np.nonzero(A)[1].astype(np.int64)


def _corner_walk(turn):
    """The decoder on the L: the scans place keyframes 0-3 in cells 0, 1, 2, 2 and say only
    "cell 1 or 3" at keyframe 4 and "cell 0 or 4" at keyframe 5 (alike cells); the moves are
    forward 0.1 m twice, ``turn`` on the spot, forward 0.1 m twice; 8 heading bins."""
    ptr, idx = _chain_successors(5, L_NEXT)
    moves = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [0, 0, turn], [0.1, 0, 0],
                      [0.1, 0, 0]], dtype=np.float64)
    E = np.full((len(moves), 5, 8), -50.0, dtype=np.float32)
    for k, alike in enumerate([(0,), (1,), (2,), (2,), (1, 3), (0, 4)]):
        E[k, list(alike)] = 0.0
    return viterbi(E, moves, L_CELLS, ptr, idx, 0.03, heading_kernel(0.5),
                   np.full(5, -np.log(5)), np.log(1e-300))


def test_the_decoder_follows_the_odometry_round_the_corner():
    """Turned left (north) at the corner the moves land exactly on cells 3 then 4; turned right
    (south) the nearest successor of cell 2 that the scans allow is 1, then 0: the same scans,
    placed apart by the odometry alone.  The heading turns by the odometry's quarter turn (2 of 8
    bins) at the corner: east then north exactly; south of east then south-west when turned
    right (bins 7 then 5: cell 1 then 0 lie 45 degrees off due south of cells 2 and 1, and the
    decoder bends the heading by one bin to land nearer them)."""
    cells_left, bins_left = _corner_walk(math.pi / 2)
    assert cells_left.tolist() == [0, 1, 2, 2, 3, 4]
    assert bins_left.tolist() == [0, 0, 0, 2, 2, 2]
    cells_right, bins_right = _corner_walk(-math.pi / 2)
    assert cells_right.tolist() == [0, 1, 2, 2, 1, 0]
    assert (np.diff(bins_right) % 8).tolist() == [0, 0, 6, 0, 0]


def _viterbi_by_hand(E, moves, cent, ptr, idx, sd, log_turn, log_init, jump):
    """The module docstring's recursion written out state by state (no pruning: every state of
    the small maps below lies within the prune of the best)."""
    K, N, B = E.shape
    W = (len(log_turn) - 1) // 2
    delta = log_init[:, None] + E[0].astype(np.float64)
    back = np.zeros((K, N, B), dtype=np.int64)
    for k in range(1, K):
        f, lft, s0 = moves[k, 0], moves[k, 1], int(np.floor(moves[k, 2] * B / (2 * np.pi) + 0.5))
        new = np.full((N, B), delta.max() + jump)
        arg = np.full((N, B), int(np.argmax(delta)))
        for c in range(N):
            for h in range(B):
                a = 2 * np.pi * h / B
                p = cent[c] + np.array([np.cos(a) * f - np.sin(a) * lft,
                                        np.sin(a) * f + np.cos(a) * lft])
                succ = idx[ptr[c]:ptr[c + 1]]
                lw = -((cent[succ] - p) ** 2).sum(1) / (2 * sd * sd)
                lw -= np.logaddexp.reduce(lw)
                for c2, w in zip(succ, lw):
                    for j in range(-W, W + 1):
                        v = delta[c, h] + w + log_turn[j + W]
                        if v > new[c2, (h + s0 + j) % B] + 1e-9:
                            new[c2, (h + s0 + j) % B] = v
                            arg[c2, (h + s0 + j) % B] = c * B + h
        delta, back[k] = new + E[k], arg
    cells, bins = np.zeros(K, dtype=np.int64), np.zeros(K, dtype=np.int64)
    cells[-1], bins[-1] = divmod(int(np.argmax(delta)), B)
    for k in range(K - 1, 0, -1):
        cells[k - 1], bins[k - 1] = divmod(int(back[k, cells[k], bins[k]]), B)
    return cells, bins


def test_the_decoder_is_its_recursion_written_out():
    """On a random map of 7 cells, 6 heading bins (turns that wrap round past bin 0 both ways)
    and random emissions, the compiled decoder's path is the recursion's, state by state."""
    rng = np.random.default_rng(3)
    cent = rng.uniform(0, 0.3, (7, 2))
    ptr, idx = successors(rng.integers(0, 7, 40), 7, cent, 0.15)
    moves = np.c_[rng.uniform(0, 0.1, 9), rng.uniform(-0.03, 0.03, 9),
                  rng.choice([-2.1, -1.0, 0.0, 1.0, 2.1], 9)]
    E = rng.uniform(-3, 0, (9, 7, 6)).astype(np.float32)
    args = (E, moves, cent, ptr, idx, 0.05, heading_kernel(0.5), np.full(7, -np.log(7)),
            np.log(1e-300))
    got, want = viterbi(*args), _viterbi_by_hand(*args)
    assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


def test_the_emission_peaks_at_the_scan_s_rotation():
    """A scan that is the mean scan turned by 3 beams fits it exactly at heading bin 3; at every
    bin the emission is -|x - M turned|^2 / 2 var."""
    rng = np.random.default_rng(0)
    M = rng.uniform(0.5, 3.0, (2, 12))
    x = np.roll(M[1], -3)  # x[j] = M[1, j + 3]
    E = emission(x[None], M, 0.5)
    assert E.shape == (1, 2, 12)
    assert int(np.argmax(E[0, 1])) == 3 and E[0, 1, 3] == pytest.approx(0.0, abs=1e-5)
    for h in range(12):
        assert E[0, 0, h] == pytest.approx(-np.sum((x - np.roll(M[0], -h)) ** 2) / 1.0, rel=1e-5)



def test_the_emission_of_many_scans_is_each_scan_s_own():
    """Scans beyond one block of keyframes (the blocks run on threads) get the emission each
    would get alone: at every heading bin -|x - M turned|^2 / 2 var."""
    rng = np.random.default_rng(1)
    M = rng.uniform(0.5, 3.0, (3, 10))
    X = rng.uniform(0.5, 3.0, (2 * _BLOCK + 7, 10))
    E = emission(X, M, 0.25)
    assert E.shape == (len(X), 3, 10)
    for t in (0, _BLOCK - 1, _BLOCK, 2 * _BLOCK + 6):
        for c in range(3):
            brute = [-np.sum((X[t] - np.roll(M[c], -h)) ** 2) / 0.5 for h in range(10)]
            np.testing.assert_allclose(E[t, c], brute, rtol=1e-5)

def test_heading_kernel_is_a_normalised_gaussian():
    k = heading_kernel(0.5, 2)
    assert np.exp(k).sum() == pytest.approx(1.0)
    assert k[1] - k[2] == pytest.approx(-0.5 * (1 / 0.5) ** 2)


def test_reckoning_and_keyframes_by_hand():
    """Poses of a square walked with moves; a keyframe each 0.25 m of travel (or 3 steps)."""
    O = np.array([[0, 0, 0], [1, 0, 0], [1, 0, math.pi / 2], [1, 1, math.pi / 2]], dtype=float)
    m = forward_moves(O)
    np.testing.assert_allclose(m, [[0, 0, 0], [1, 0, 0], [0, 0, math.pi / 2], [1, 0, 0]],
                               atol=1e-12)
    np.testing.assert_allclose(reckon(m, O[:, 2]), O, atol=1e-12)
    still = np.zeros((8, 3))
    still[:, 0] = [0, 0.1, 0.2, 0.3, 0.3, 0.3, 0.3, 0.3]
    assert keyframes(still, 0.25, max_steps=3).tolist() == [0, 3, 6]


def test_command_poses_move_a_unit_unless_stopped():
    """Scans that never turn: the command logged with a step moves the robot one unit east into
    it, none at ``stop`` (action 3)."""
    X = np.tile(np.arange(8.0), (4, 1))
    P = command_poses(X, np.array([0, 0, 3, 0]))
    np.testing.assert_allclose(P[:, :2], [[0, 0], [1, 0], [1, 0], [2, 0]], atol=1e-9)


def test_cells_keep_only_cells_with_steps_and_successors_include_themselves():
    xy = np.array([[0, 0], [0.01, 0], [1, 1], [1.01, 1]], dtype=float)
    labels, centres = cells(xy, 2, 0)
    assert sorted(set(labels.tolist())) == [0, 1] and labels[0] == labels[1] != labels[2]
    ptr, idx = successors(np.array([0, 1, 1, 0]), 2)
    assert ptr.tolist() == [0, 2, 4] and idx.tolist() == [0, 1, 0, 1]


def test_robot_is_a_motion_mode_and_bad_modes_name_it():
    assert motion_settings("robot").mode == "robot"
    with pytest.raises(ParameterError, match=r"motion.mode must be one of .*robot"):
        motion_settings({"mode": "robots"})


def _fake_log(T=300, B=12, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.5, 2.0, (T, B))
    u = rng.integers(0, 4, T)
    t = np.arange(T) * 0.01
    odo = np.column_stack([t, np.zeros(T), np.zeros(T)])
    return X, u, odo


def test_fit_in_robot_mode_without_odometry_is_one_line():
    X, u, _ = _fake_log()
    with pytest.raises(ParameterError, match=r"^odometry is required by motion mode 'robot'"):
        MapLearner(4, 6, motion="robot").fit(X, u)


def test_fit_in_robot_mode_takes_one_episode():
    X, u, odo = _fake_log()
    with pytest.raises(ParameterError, match=r"^lengths motion mode 'robot' learns from one"):
        MapLearner(4, 6, motion="robot").fit(X, u, lengths=[150, 150], odometry=odo)


def test_predict_in_robot_mode_needs_the_walk_s_odometry():
    """A map learned with ``motion="robot"`` places a walk by its odometry: without it, a one-line
    error naming ``odometry``; scans of another width name ``observations``."""
    X, u, odo = _fake_log()
    learner = MapLearner(4, 6, motion="robot", random_state=0).fit(X, u, odometry=odo)
    assert learner.motion_info_["chosen"] == "robot"
    with pytest.raises(ParameterError, match=r"^odometry is required to place a walk"):
        learner.predict(X, u)
    with pytest.raises(ParameterError, match=r"^observations must be finite \(T, 12\)"):
        learner.predict(X[:, :6], u, odometry=odo)
    placed = learner.predict(X, u, odometry=odo)
    assert placed.shape == (300,) and placed.max() < learner.map_.n_states


def _arena_robot(n_steps, heldout_steps, n_beams=60):
    """A robot (egocentric range finder, turn commands, wheel odometry) in two 1 m rooms joined
    by a door, a table in the south-west corner of each (turned by 180 degrees about the door
    the east one would stand in the west room's empty north-east corner: not point-symmetric)."""
    pytest.importorskip("ratinabox")
    from topomap.worlds.arena import ArenaWorld, RangeFinder, floorplan_from_dict

    plan = floorplan_from_dict({
        "boundary": [[0, 0], [2, 0], [2, 1], [0, 1]],
        "walls": [[[1, 0], [1, 0.35]], [[1, 0.65], [1, 1]]],
        "holes": [[[0.2, 0.2], [0.45, 0.2], [0.45, 0.4], [0.2, 0.4]],
                  [[1.15, 0.15], [1.35, 0.15], [1.35, 0.3], [1.15, 0.3]]],
        "regions": {"west": [[0, 0], [1, 0], [1, 1], [0, 1]],
                    "east": [[1, 0], [2, 0], [2, 1], [1, 1]]}}, "two furnished rooms")
    world = ArenaWorld(plan, sensor=RangeFinder(frame="egocentric", n_beams=n_beams),
                       actions="turns", odometry="wheel")
    return (plan, world.simulate(n_steps, None, np.random.default_rng(0)),
            world.simulate(heldout_steps, None, np.random.default_rng(1)))


def test_a_robot_walk_is_learned_placed_again_and_saved(tmp_path):
    """fit then predict on the same walk with its own odometry gives back most of its places
    (the steps near a boundary between two places may land on either side);
    the map's states are the places, and it saves and loads as any map."""
    _, walk, _ = _arena_robot(3000, 10)
    learner = MapLearner(8, 16, motion="robot", random_state=0).fit_trajectory(walk)
    assert learner.map_.n_states == 16 and learner.labels_.max() == 15
    again = learner.predict(walk.observations, walk.actions, odometry=walk.odometry)
    assert np.mean(again == learner.labels_) > 0.6  # measured 0.75; by chance 1 in 16
    from topomap import TopologicalMap

    saved = TopologicalMap.load(learner.map_.save(tmp_path / "map.json"))
    assert saved.n_states == 16 and saved.info["motion_info"]["chosen"] == "robot"
    learner.map_.to_graphml(tmp_path / "map.graphml")


@pytest.mark.slow
def test_a_robot_s_held_out_walk_is_placed_better_than_by_its_views():
    """8,000 steps learned, 2,000 held out: the held-out walk placed by its own odometry lies
    under half as far from the truth as K-means on the views places it, and fewer of its steps
    in the wrong room (measured: 0.230 m and 16 % against 0.551 m and 53 %).  The plan is all but
    point-symmetric (its map's mirror mismatch 3.7 times a neighbour's, just above
    ``SYMMETRY_RATIO``), so this also checks that the guard lets it through."""
    from topomap.evaluation.metres import kmeans_view_scores, score_units

    plan, walk, held = _arena_robot(8000, 2000)
    learner = MapLearner(8, 16, motion="robot", random_state=0).fit_trajectory(walk)
    placed = learner.predict(held.observations, held.actions, odometry=held.odometry)
    pair = (plan.region_of(walk.positions), plan.region_of(held.positions))
    ours = score_units(learner.labels_, walk.positions, placed, held.positions, 16, pair)
    views = kmeans_view_scores(16, walk, held, plan.region_of, random_state=0)
    assert ours["median_error"] < 0.5 * views["median_error"]
    assert ours["wrong_region"] < views["wrong_region"]
    assert learner.motion_info_["chosen"] == "robot"


def _grid_map(asymmetry):
    """A RobotMap of 8 x 4 cells 0.25 m apart over a 2 x 1 m plan centred on (1, 0.5); each cell's
    scan (16 beams) the projection of its offset from the centre on every beam's direction, plus
    ``asymmetry`` times its x offset (unchanged by the 180-degree turn, which the projection is
    not: it breaks the symmetry)."""
    from topomap.core.motion.robot import RobotMap

    xs, ys = np.meshgrid(np.arange(8) * 0.25 + 0.125, np.arange(4) * 0.25 + 0.125)
    C = np.column_stack([xs.ravel(), ys.ravel()])
    a = 2 * np.pi * np.arange(16) / 16
    off = C - [1.0, 0.5]
    M = 2 + off @ np.vstack([np.cos(a), np.sin(a)]) + asymmetry * off[:, :1]
    n = len(C)
    return RobotMap(C, M, 0.01, np.arange(n + 1), np.arange(n), 0.25, np.zeros(n),
                    np.zeros(n, dtype=np.int64))


def test_a_map_that_is_its_own_point_reflection_is_found():
    """Turned by 180 degrees about (1, 0.5) the symmetric map is itself (mismatch 0, ratio 0); the
    asymmetric one is not (each scan off by twice its x offset, a neighbour's by a quarter)."""
    from topomap.core.motion.symmetry import SYMMETRY_RATIO, point_symmetry

    same = point_symmetry(_grid_map(0.0))
    assert same["ratio"] == pytest.approx(0.0, abs=1e-9)
    assert same["centre"] == pytest.approx([1.0, 0.5])
    assert point_symmetry(_grid_map(1.0))["ratio"] > SYMMETRY_RATIO


def test_a_bent_point_reflection_is_found_within_the_reach():
    """The symmetric map bent: its top left quarter moved 0.3 m (1.2 cell spacings) right, its top
    right quarter 0.3 m left (no centre turns it into itself now).  Turned by 180 degrees about
    (1, 0.5) every cell lands 0.3 m from the cell whose scan is its own turned (a top cell's
    counterpart is a bottom one, which stayed), so within a reach of 1.5 spacings the mismatch
    is 0; matched with the nearest cell alone, at most half the cells find their counterpart."""
    from dataclasses import replace

    from topomap.core.motion.symmetry import SCAN_REACH, SYMMETRY_RATIO, point_symmetry

    m = _grid_map(0.0)
    top, left = m.centres[:, 1] > 0.5, m.centres[:, 0] < 1.0
    move = np.where(top, np.where(left, 0.3, -0.3), 0.0)
    bent = replace(m, centres=m.centres + move[:, None] * [1.0, 0.0])
    assert point_symmetry(bent, SCAN_REACH)["ratio"] == pytest.approx(0.0, abs=1e-9)
    assert point_symmetry(bent)["ratio"] > 0.1
    # the reach finds no reflection where there is none (each scan off by twice its x offset)
    assert point_symmetry(_grid_map(1.0), SCAN_REACH)["ratio"] > SYMMETRY_RATIO


def test_the_robot_map_file_places_a_walk_as_the_learner_does(tmp_path):
    """robot_map.npz keeps every field: a walk placed on the loaded map gets the places the
    learner gives it; a file missing a field, or whose arrays do not fit, is refused by name."""
    from topomap.core.motion.robot_fit import predict_robot
    from topomap.core.motion.robot_io import load_robot_map, save_robot_map

    _, walk, held = _arena_robot(3000, 600)
    learner = MapLearner(8, 16, motion="robot", random_state=0).fit_trajectory(walk)
    path = save_robot_map(learner.robot_map_, tmp_path / "robot_map.npz")
    loaded = load_robot_map(path)
    np.testing.assert_array_equal(loaded.scans, learner.robot_map_.scans)
    np.testing.assert_array_equal(
        predict_robot(loaded, held.observations, None, held.odometry),
        learner.predict(held.observations, held.actions, odometry=held.odometry))
    with np.load(path, allow_pickle=False) as f:
        fields = {k: f[k] for k in f.files}
    np.savez(tmp_path / "no_place.npz", **{k: v for k, v in fields.items() if k != "place"})
    with pytest.raises(ValueError, match="place is missing"):
        load_robot_map(tmp_path / "no_place.npz")
    np.savez(tmp_path / "short.npz", **dict(fields, log_prior=fields["log_prior"][:-1]))
    with pytest.raises(ValueError, match="log_prior has shape"):
        load_robot_map(tmp_path / "short.npz")
    (tmp_path / "text.npz").write_text("not a map")
    with pytest.raises(ValueError, match="not a robot map file"):
        load_robot_map(tmp_path / "text.npz")
    assert loaded.evidence == learner.robot_map_.evidence < 1
    # a file without the evidence weight weighs every beam fully; one outside (0, 1] is refused
    np.savez(tmp_path / "no_evidence.npz", **{k: v for k, v in fields.items() if k != "evidence"})
    assert load_robot_map(tmp_path / "no_evidence.npz").evidence == 1.0
    np.savez(tmp_path / "zero.npz", **dict(fields, evidence=np.float64(0.0)))
    with pytest.raises(ValueError, match="evidence 0.0 is not in"):
        load_robot_map(tmp_path / "zero.npz")


def test_the_evidence_weight_counts_independent_beams_and_keyframes():
    """Independent beams of one variance at independent keyframes weigh 1; one error shared by
    all ``B`` beams (covariance ``s^2 1 1^T``: participation ratio exactly 1) weighs ``1 / B``;
    every keyframe seen twice in a row (correlation 1/2 one keyframe apart, 0 beyond) weighs
    ``1 / (1 + 2 * 1/2) = 1/2``; half the beams without error (ratio ``B / 2``) weigh 1/2."""
    from topomap.core.motion.robot import evidence_weight

    rng = np.random.default_rng(0)
    K, B = 40_000, 8
    assert evidence_weight(rng.normal(0, 0.1, (K, B))) == pytest.approx(1.0, abs=0.03)
    shared = rng.normal(0, 0.1, (K, 1)) * np.ones(B)
    # (the lags' correlations, each 0 +- 1 / sqrt(K) and kept where above 0, lower it by up to 5 %)
    assert evidence_weight(shared) == pytest.approx(1 / B, rel=0.05)
    twice = np.repeat(rng.normal(0, 0.1, (K // 2, B)), 2, axis=0)
    assert evidence_weight(twice) == pytest.approx(0.5, abs=0.02)
    half = rng.normal(0, 0.1, (K, B)) * (np.arange(B) < B // 2)
    assert evidence_weight(half) == pytest.approx(0.5, abs=0.02)
    assert evidence_weight(np.zeros((1, B))) == 1.0


def test_headings_solved_early_are_those_solved_in_turn():
    # the heading graph started before phase 1 (early_headings) gives the numbers the route
    # solves itself, and starts only where the robot route may follow
    from topomap.core.data.trajectory import check_fit_data
    from topomap.core.motion.beams import in_route_frame
    from topomap.core.motion.robot_fit import early_headings
    from topomap.core.motion.scans import scan_headings

    X, u, odo = _fake_log()
    odo[:, 2] = np.cumsum(np.where(u == 1, 0.1, np.where(u == 2, -0.1, 0.0)))  # turns commanded
    data = check_fit_data(X, u, None, None, None, None, None)
    robot, auto = motion_settings("robot"), motion_settings("auto")
    solving = early_headings(robot, data, odo)
    order, headings = solving()
    assert np.array_equal(headings, scan_headings(in_route_frame(X, order), odo[:, 2]))
    assert all(np.array_equal(a, b) for a, b in zip(early_headings(auto, data, odo)(),
                                                     solving()))
    import copy
    import pickle

    assert pickle.loads(pickle.dumps(solving)) is None and copy.deepcopy(solving) is None
    assert early_headings(None, data, odo) is None  # no continuous path (a wider pass)
    assert early_headings(motion_settings("continuous"), data, odo) is None
    assert early_headings(auto, data, None) is None
    still = odo.copy()
    still[:, 2] = 0.0  # odometry that never turns: no turn commands, no robot route under auto
    assert early_headings(auto, data, still) is None and early_headings(robot, data, still)
    two = check_fit_data(X, u, None, [150, 150], None, None, None)
    assert early_headings(robot, two, odo) is None  # one episode only: the route refuses it


def test_learner_scores_place_a_robot_map_s_walk_by_its_own_odometry():
    """``learner_map_scores`` (what ``topomap`` and ``docs/examples/robot_bag.py`` report) places
    a held-out walk on a robot route's map by ``predict`` with the walk's own odometry, and
    decodes it on ``map_`` for any other map; ``learner_scores`` adds both yardsticks."""
    from topomap.evaluation.metres import (learner_map_scores, learner_scores, map_scores,
                                           score_units)

    plan, walk, held = _arena_robot(3000, 300)
    robot = MapLearner(8, 16, motion="robot", random_state=0).fit_trajectory(walk)
    placed = robot.predict(held.observations, held.actions, odometry=held.odometry)
    pair = (plan.region_of(walk.positions), plan.region_of(held.positions))
    assert learner_map_scores(robot, walk, held, plan.region_of) == score_units(
        robot.labels_, walk.positions, placed, held.positions, 16, pair)
    split = MapLearner(8, 16, motion="discrete", random_state=0).fit_trajectory(walk)
    assert learner_map_scores(split, walk, held, plan.region_of) == map_scores(
        split.map_, split.labels_, walk, held, plan.region_of)
    assert set(learner_scores(robot, walk, held, plan.region_of)) == {
        "map", "ceiling", "kmeans_views", "kmeans_positions"}
