"""Odometry from egocentric range scans alone: scan-to-keyframe registration (point-to-line ICP).

A ring of ``B`` range beams fixed to the robot (beam ``k`` at ``2 pi k / B`` anticlockwise from
the heading) is a set of points in the robot's frame.  :func:`scan_odometry` registers every
scan against a *keyframe* (an earlier scan): the rigid motion ``(x, y, turn)`` that puts the
scan's points on the lines through the keyframe's neighbouring points (point-to-line ICP,
Gauss-Newton on the three parameters, each pair weighted by a Cauchy loss).  Three starts --
the step before's pose in the keyframe's frame, that plus the step before's own move (a
constant velocity), and the same with the turn read from the scans' circular cross-correlation
(:func:`~.scans.scan_turns`) -- and the least-cost result kept, unless it turns the scan by
over ``TURN_CHECK`` in one step at a cost near a result's that turns less (scans that look
alike turned round: that one kept, :func:`~.turn_rivals.checked_turn`); one costing over ``RETRY_COST``
times the lesser of the recent median and the step before's is tried again from every
``SWEEP_BEAMS``-th rotation (a sudden turn).  A new keyframe is taken once the scan has moved
``KEYFRAME_TRAVEL`` or turned ``KEYFRAME_TURN`` from the last, so the drift grows with
keyframes, not steps; each scan is registered against ``OLDER_KEYFRAMES`` keyframes before it
too, its pose the mean (:func:`averaged_pose`: the range noise of the keyframes' lines, which
sets the drift, averages out).  A beam at the range's maximum (no return) carries no point.

:func:`scan_poses` closes it by loops: its headings by :func:`~.scans.scan_headings` (as a wheel
odometry's), then its positions by a linear least-squares graph whose closures are registered
scan pairs that look alike (:func:`~.scans.loop_closures`).

Measured (``benchmarks/notes/robots.md``, 2026-12-03; 60 beams, 2 cm range noise, 1 cm a step,
1 m plans): the displacement over 200 steps 0.019-0.023 m from the truth (median; 0.063-0.078
m against the current keyframe alone), the range noise's share (noise-free scans 0.027-0.042 m
against one keyframe); closed by loops, ``robot_twin@0.3333`` seed 1's whole walk 0.022 m from
the truth after a rigid alignment (1.011 m against one keyframe).
"""

from __future__ import annotations

import math
import statistics

import numpy as np
import scipy.sparse as sp
from numba import njit, typeof
from numba.typed import List

from ..split.threads import in_threads, rows_in_threads
from . import scans as S
from .icp import icp, pairing
from .reckoning import compose, forward_moves, reckon, relative_pose
from .turn_rivals import (RETRY_GAIN, TURN_CHECK, checked_turn, clearance_ahead,
                          resolve_turns, rival_of, turn_apart)

__all__ = ["scan_points", "keyframe_lines", "register", "register_each", "checked_turn",
           "resolve_turns", "scan_odometry", "scan_poses", "retry_yardstick", "KEYFRAME_TRAVEL",
           "KEYFRAME_TURN", "ICP_ITERATIONS", "CAUCHY_M", "MAX_PAIR_M", "RETRY_COST", "RETRY_GAIN",
           "RECENT", "SWEEP_BEAMS", "CLOSURE_COST", "CHAIN_SD_M", "CLOSURE_SD_M", "NORMAL_HALF",
           "POSITION_GATE_M", "NORMAL_GAP_M", "TURN_CHECK", "averaged_pose", "older_keyframes",
           "add_keyframe", "OLDER_KEYFRAMES", "AVERAGE_COST", "AVERAGE_TURN", "HALVES"]

#: m: a new keyframe once the scan lies this far from the last one (0.10 put robot_alike@0.3333
#: seed 0 0.61 m off along the true headings, 0.05 0.55 m: no gain from fewer keyframes)
KEYFRAME_TRAVEL = 0.05
#: rad: a new keyframe once the scan has turned this far from the last (3.3 beams of 60; not tuned)
KEYFRAME_TURN = 0.35
#: Gauss-Newton iterations of one registration (not tuned: from the true motion the steps shrink
#: below 1e-6 m in a few)
ICP_ITERATIONS = 12
#: m: the Cauchy loss's scale of a point's distance from its line: the harness's range noise sd
#: (0.01 and 0.05 gave 7.5 and 6.9 mm from the true motion, 0.02 7.1, with lines through two
#: neighbours: it hardly matters)
CAUCHY_M = 0.02
#: m: a point farther than this from its nearest keyframe point has no pair (the spacing of 6-
#: degree beams at 1.4 m; not tuned)
MAX_PAIR_M = 0.15
#: times the lesser of the recent median cost (``RECENT`` registrations) and the step before's:
#: above it a registration is tried again from every ``SWEEP_BEAMS``-th rotation (a robot bounced
#: off a wall turns up to 2 rad in a step; with the median alone robot_twin@0.3333 seed 1 read a
#: turn of 1.47 rad as 0.11 and its closed headings lay 0.5 rad off, with the step before's 0.02)
RETRY_COST = 2.0
#: registrations whose costs set the retry's yardstick
RECENT = 100
#: beams between the rotations a retry starts from
SWEEP_BEAMS = 2
#: times the median cost of a registration of consecutive scans: a loop closure costing more
#: is left out.  robot_alike@0.3333 / robot_twin@0.3333 seed 0, whole walk after a rigid
#: alignment [m]: 1.2 0.167 / 1.111, 1.5 0.257 / 1.217, 2.0 0.279 / 1.087 (robot_twin's walk
#: had a heading wrong by pi then, mended since by resolve_turns)
CLOSURE_COST = 1.2
#: m: sd of one step's move in the positions' chain (0.002: 0.210 / 1.182 at a cost of 1.5,
#: against 0.257 / 1.217)
CHAIN_SD_M = 0.005
#: m: sd of a loop closure's displacement (0.02: 0.235 / 1.241, the same comparison)
CLOSURE_SD_M = 0.01
#: m: a closure disagreeing more with the positions so far is left out (0.2: 0.224 / 1.015,
#: the same comparison; not combined with the cost of 1.2)
POSITION_GATE_M = 0.1
#: beams either side whose points fit the line through a keyframe point (1, 2, 3: 6.5, 6.9,
#: 8.5 mm and 0.009, 0.010, 0.011 rad from the true motion)
NORMAL_HALF = 1
#: m: neighbours farther than this from the point are not on its line (not tuned)
NORMAL_GAP_M = 0.25
#: keyframes before the current one a scan is registered against too (:func:`averaged_pose`).
#: 200-step displacement error, median / 90th percentile [m], robot_twin@0.3333 s1 / robot_three
#: s2, steps 0-6,000: none 0.066 / 0.141, 0.077 / 0.164; 2 0.034 / 0.067, 0.043 / 0.090; 5 0.020
#: / 0.047, 0.027 / 0.062; 7 0.019 / 0.041, 0.023 / 0.062; 11 0.016 / 0.034, 0.020 / 0.053 (its
#: CPU 1, 1.3-2, 2.7-3, 3-4, 3.7-5.5x, load 6-9; the route's fit and predict 1.7-2.6x with 7)
OLDER_KEYFRAMES = 7
#: an older keyframe's registration counts where it costs at most this times the current one's
#: (1.5 / 4: 0.036 / 0.073, 0.034 / 0.064 against 0.034 / 0.067 m, 2 keyframes, twin s1 above)
AVERAGE_COST = 2.0
#: rad: ... and turns within this of the current one's answer (not tuned; a median turn 0.12 rad)
AVERAGE_TURN = 0.2
#: scans: a longer walk is registered as two halves at once (:func:`scan_odometry`), each on a
#: thread.  A registration waits for the one before, 0.4 ms a scan: on a 2-hour walk (73,000
#: scans, ``robot_alike@0.3333`` seed 0, idle) 30 s in one run, 17.3 s (31.9 s of CPU) in
#: halves; closed by loops (:func:`scan_poses`) its poses lie 0.730 m from the truth after a
#: rigid alignment either way (0.728 m in one run).  Walks up to it keep the bits of one run.
HALVES = 40_000


def scan_points(scan, max_range: float) -> tuple[np.ndarray, np.ndarray]:
    """``(points (B, 2), valid (B,))`` of one scan (B,) in the robot's frame [m]: beam ``k`` at
    ``2 pi k / B`` anticlockwise from the heading; a beam at ``max_range`` or more is no point.
    Scans (T, B): ``(points (T, B, 2), valid (T, B))``, each row as alone."""
    scan = np.asarray(scan, dtype=np.float64)
    B = scan.shape[-1]
    a = 2 * np.pi * np.arange(B) / B
    return np.stack([scan * np.cos(a), scan * np.sin(a)], axis=-1), scan < max_range


@njit(cache=True)
def _normals(P, valid, max_gap, half):
    """``(normals (B, 2), centres (B, 2))`` of the keyframe's points: the least-squares line
    through each point and its valid neighbours within ``half`` beams either side that lie
    within ``max_gap`` of it, its unit normal (0 where fewer than two points) and the point
    moved onto it (the range noise along the normal averaged over the neighbours)."""
    B = P.shape[0]
    N = np.zeros((B, 2))
    C = P.copy()
    for k in range(B):
        if not valid[k]:
            continue
        n, sx, sy, sxx, sxy, syy = 0, 0.0, 0.0, 0.0, 0.0, 0.0
        for o in range(-half, half + 1):
            j = (k + o) % B
            if valid[j] and (P[j, 0] - P[k, 0]) ** 2 + (P[j, 1] - P[k, 1]) ** 2 < max_gap ** 2:
                x, y = P[j, 0], P[j, 1]
                n += 1
                sx += x
                sy += y
                sxx += x * x
                sxy += x * y
                syy += y * y
        if n < 2:
            continue
        cxx, cxy, cyy = sxx / n - (sx / n) ** 2, sxy / n - sx * sy / n ** 2, syy / n - (sy / n) ** 2
        # the direction of least spread: the normal
        ang = 0.5 * np.arctan2(2 * cxy, cxx - cyy)  # the direction of most spread
        nx, ny = -np.sin(ang), np.cos(ang)
        N[k, 0], N[k, 1] = nx, ny
        off = nx * (P[k, 0] - sx / n) + ny * (P[k, 1] - sy / n)
        C[k, 0], C[k, 1] = P[k, 0] - off * nx, P[k, 1] - off * ny
    return N, C


@njit(cache=True)
def _icp(P, Pv, N, Q, Qv, x0, iters, cauchy, max_pair):
    """:func:`~.icp.icp` of points ``Q`` on the lines through ``P`` (valid ``Pv``, normals
    ``N``) from ``x0``, with a cache of its own: ``(motion, paired, cost)``."""
    return icp(pairing(P, Pv, N, Q.shape[0]), P, N, Q, Qv, x0, iters, cauchy, max_pair)


@njit(cache=True, nogil=True)
def _register_starts(N, C, cache, Q, Qv, starts):
    """``(motions (S, 3), paired (S,), costs (S,))``: :func:`~.icp.icp` of points ``Q`` on the
    keyframe's lines (``N``, ``C``, ``cache`` of :func:`keyframe_lines`) from each of ``starts``
    (S, 3)."""
    n = len(starts)
    out = np.zeros((n, 3))
    used = np.zeros(n, dtype=np.int64)
    cost = np.zeros(n)
    for k in range(n):
        m, u, c = icp(cache, C, N, Q, Qv, starts[k], ICP_ITERATIONS, CAUCHY_M, MAX_PAIR_M)
        out[k] = m
        used[k] = u
        cost[k] = c
    return out, used, cost


@njit(cache=True, nogil=True)
def _register_pairs(points, valid, i, j, starts):
    """``(motions (E, 3), costs (E,))``: scan ``j[e]`` registered against scan ``i[e]`` from
    ``starts[e]`` (:func:`register` with one start, every pair in one compiled loop);
    ``points``, ``valid``: :func:`scan_points` of all the scans."""
    n = len(i)
    out = np.zeros((n, 3))
    cost = np.zeros(n)
    for e in range(n):
        N, C = _normals(points[i[e]], valid[i[e]], NORMAL_GAP_M, NORMAL_HALF)
        m, _, c = _icp(C, valid[i[e]], N, points[j[e]], valid[j[e]], starts[e],
                       ICP_ITERATIONS, CAUCHY_M, MAX_PAIR_M)
        out[e] = m
        cost[e] = c
    return out, cost


@njit(cache=True, nogil=True)
def _register_older(lines, frames, pose, Q, Qv):
    """``(poses (K, 3), costs (K,))``: :func:`~.icp.icp` of points ``Q`` on each older
    keyframe's lines (``lines[k]``, :func:`keyframe_lines`) from ``pose`` [m, m, rad] in its
    frame (``frames[k]``, :func:`add_keyframe`'s; as :func:`~.reckoning.relative_pose`), the
    result put back in the frame of ``pose`` (as :func:`~.reckoning.compose`)."""
    out, cost, start = np.zeros((len(lines), 3)), np.zeros(len(lines)), np.zeros(3)
    for k in range(len(lines)):
        N, C, cache = lines[k]
        x, y, th, c, s = frames[k]
        dx, dy = pose[0] - x, pose[1] - y
        start[0], start[1], start[2] = c * dx + s * dy, -s * dx + c * dy, pose[2] - th
        m, _, cost[k] = icp(cache, C, N, Q, Qv, start, ICP_ITERATIONS, CAUCHY_M, MAX_PAIR_M)
        out[k, 0], out[k, 1] = x + c * m[0] - s * m[1], y + s * m[0] + c * m[1]
        out[k, 2] = th + m[2]
    return out, cost


def keyframe_lines(P, valid) -> tuple:
    """``(normals, centres, cache)`` of a keyframe's points ``P`` (B, 2) [m], ``valid`` (B,):
    :func:`_normals` and the nearest-point cache (:func:`~.icp.pairing`) every scan registered
    on it shares (each scan point's search kept where it stood; the same pairs as without)."""
    N, C = _normals(P, valid, NORMAL_GAP_M, NORMAL_HALF)
    return N, C, pairing(C, valid, N, len(P))


def register_each(ref, scan, max_range: float, starts=((0.0, 0.0, 0.0),),
                  iters: int = ICP_ITERATIONS) -> list[tuple[np.ndarray, int, float]]:
    """``[(motion, paired, cost)]`` of every one of ``starts`` (rows of x, y, turn): the pose
    ``(x [m], y [m], turn [rad])`` of ``scan`` in the frame of ``ref`` (both (B,) ranges) by
    point-to-line ICP from that start (:func:`_icp`), the points it paired and its cost."""
    P, Pv = scan_points(ref, max_range)
    Q, Qv = scan_points(scan, max_range)
    N, C = _normals(P, Pv, NORMAL_GAP_M, NORMAL_HALF)
    runs = (_icp(C, Pv, N, Q, Qv, start, iters, CAUCHY_M, MAX_PAIR_M)
            for start in np.atleast_2d(np.asarray(starts, dtype=np.float64)))
    return [(m, int(used), float(cost)) for m, used, cost in runs]


def register(ref, scan, max_range: float, starts=((0.0, 0.0, 0.0),),
             iters: int = ICP_ITERATIONS) -> tuple[np.ndarray, int, float]:
    """``(motion, paired, cost)``: the pose ``(x [m], y [m], turn [rad])`` of ``scan`` in the
    frame of ``ref`` (both (B,) ranges) by point-to-line ICP from each of ``starts`` (rows of
    x, y, turn), the one of least cost (:func:`_icp`), the points it paired and its cost."""
    return min(register_each(ref, scan, max_range, starts, iters), key=lambda r: r[2])


def scan_odometry(X, max_range: float | None = None, alternatives: list | None = None,
                  stop=None) -> np.ndarray | None:
    """(T, 3) poses (x [m], y [m], heading [rad]) of a walk of egocentric scans ``X`` (T, B) from
    ``(0, 0, 0)``, every scan registered against its keyframe (module docstring); ``max_range``:
    the range a beam with no return reads (None: the largest in ``X``).
    ``alternatives``: a list that gets ``(t, pose)`` for every step ``t`` whose registration had
    a rival turning it more than :data:`TURN_CHECK` otherwise at a cost within ``1 /
    RETRY_GAIN`` of the kept one's (or a retry's kept turn against the first): ``pose`` the
    rival's pose of step ``t`` (:func:`resolve_turns` chooses between them by the loops). ``stop``:
    a function without arguments asked before each step; None is returned once it is true.
    A walk of more than :data:`HALVES` scans is registered as two halves at once, on two
    threads, the second from the scan the first ends on (its poses put in that scan's pose)."""
    X = np.asarray(X, dtype=np.float64)
    max_range = float(X.max()) if max_range is None else float(max_range)
    h = len(X) // 2
    if len(X) <= HALVES:
        return _registered(X, max_range, alternatives, stop)
    rivals: tuple[list, list] = ([], [])
    first, second = in_threads(lambda k: _registered((X[:h + 1], X[h:])[k], max_range,
                                                     rivals[k], stop), (0, 1))
    if first is None or second is None:
        return None
    if alternatives is not None:
        alternatives += rivals[0] + [(t + h, compose(first[h], p)) for t, p in rivals[1]]
    return np.concatenate((first, [compose(first[h], p) for p in second[1:]]))


def _registered(X, max_range: float, alternatives: list | None, stop) -> np.ndarray | None:
    """:func:`scan_odometry` of one run of scans ``X`` (T, B), float64, step after step."""
    T, B = X.shape
    max_range -= 1e-9
    Xd = S.despike(X)
    turns = np.r_[0.0, S.scan_turns(Xd[:-1], Xd[1:])]
    sweep = 2 * np.pi * np.arange(0, B, SWEEP_BEAMS) / B
    poses, key = np.zeros((T, 3)), 0
    rel = np.zeros(3)      # the step before's pose in the keyframe's frame
    last = np.zeros(3)     # the step before's move in its own frame
    costs = []
    # every scan's points once, the keyframe's lines once a keyframe (as :func:`register`)
    points, valid = scan_points(X, max_range)
    lines = keyframe_lines(points[0], valid[0])
    older = older_keyframes(lines)   # the keyframes before ``key`` (:func:`averaged_pose`)
    for t in range(1, T):
        if stop is not None and stop():
            return None
        starts = np.array([compose(rel, np.array([last[0], last[1], turns[t]])),
                           compose(rel, last), rel])
        ms, used, cs = _register_starts(*lines, points[t], valid[t], starts)
        results = [(ms[k], int(used[k]), float(cs[k])) for k in range(len(cs))]
        m, _, cost = checked_turn(results, rel)
        rival = rival_of(results, m, cost)
        if len(costs) >= 10 and cost > RETRY_COST * retry_yardstick(costs):
            wide = np.column_stack([np.full(len(sweep), rel[0]), np.full(len(sweep), rel[1]),
                                    rel[2] + sweep])
            ms, _, cs = _register_starts(*lines, points[t], valid[t], wide)
            m2, cost2 = ms[np.argmin(cs)], float(cs.min())
            if cost2 < RETRY_GAIN * cost and np.hypot(*(m2[:2] - rel[:2])) < KEYFRAME_TRAVEL:
                rival = m if turn_apart(m, m2) > TURN_CHECK else rival
                m, cost = m2, cost2
        costs.append(cost)
        poses[t] = averaged_pose(compose(poses[key], m), cost, older, points[t], valid[t])
        m = relative_pose(poses[key], poses[t]) if len(older[1]) else m
        if alternatives is not None and rival is not None:
            alternatives.append((t, compose(poses[key], rival)))
        last = relative_pose(poses[t - 1], poses[t])
        rel = m
        if np.hypot(m[0], m[1]) >= KEYFRAME_TRAVEL or abs(m[2]) >= KEYFRAME_TURN:
            older = add_keyframe(older, poses[key], lines)
            key, rel = t, np.zeros(3)
            lines = keyframe_lines(points[t], valid[t])
    return poses


def averaged_pose(pose, cost: float, older, q, qv) -> np.ndarray:
    """(3,) pose (x [m], y [m], heading [rad]) of a scan (points ``q``, valid ``qv``) that its
    keyframe puts at ``pose`` at ``cost``: the mean of ``pose`` and its registrations from
    ``pose`` against the ``older`` keyframes (``(lines, frames)`` of :func:`older_keyframes`, in
    one compiled call, :func:`_register_older`) that cost at most :data:`AVERAGE_COST` times
    ``cost`` and lie within :data:`KEYFRAME_TRAVEL` and :data:`AVERAGE_TURN` of it."""
    if not len(older[1]):
        return pose
    e, c = _register_older(*older, pose, q, qv)
    ok = ((c <= AVERAGE_COST * cost) & (np.hypot(e[:, 0] - pose[0], e[:, 1] - pose[1])
                                         < KEYFRAME_TRAVEL)
          & (np.abs(S._wrap(e[:, 2] - pose[2])) < AVERAGE_TURN))
    if not ok.any():
        return pose
    f = np.concatenate((pose[None], e[ok]))
    # np.mean's sums and division, without its Python wrapper
    xy, turn = np.add.reduce(f[:, :2], axis=0) / len(f), np.add.reduce(S._wrap(f[:, 2] - pose[2]))
    return np.array([xy[0], xy[1], pose[2] + turn / len(f)])


def older_keyframes(like) -> tuple:
    """No older keyframes (``(lines, frames)`` of :func:`averaged_pose`) whose lines are of the
    type of ``like`` (a :func:`keyframe_lines`); :func:`add_keyframe` adds one."""
    return List.empty_list(typeof(like)), np.zeros((0, 5))


def add_keyframe(older, pose, lines) -> tuple:
    """``older`` (:func:`older_keyframes`, changed in place) with the keyframe at ``pose`` (3,)
    [m, m, rad] of :func:`keyframe_lines` ``lines`` last, the first left out past
    :data:`OLDER_KEYFRAMES`."""
    _push(older[0], lines, OLDER_KEYFRAMES)
    frame = [pose[0], pose[1], pose[2], np.cos(pose[2]), np.sin(pose[2])]  # numpy's, as compose
    return older[0], np.vstack((older[1], frame))[-OLDER_KEYFRAMES:]


@njit(cache=True)
def _push(items, item, most):
    """``item`` appended to the typed list ``items``, its first left out beyond ``most``."""
    items.append(item)
    if len(items) > most:
        items.pop(0)


def retry_yardstick(costs) -> float:
    """The cost a retry (:data:`RETRY_COST`) weighs a registration against: the lesser of the
    median of the last :data:`RECENT` of ``costs`` (the walk's so far, in order; ``np.median``'s
    value, NaN too, by :mod:`statistics`: 2x faster on a hundred floats) and the last one."""
    recent = costs[-RECENT:]
    median = np.nan if any(map(math.isnan, recent)) else statistics.median(recent)
    return min(float(median), float(costs[-1]))


def _solve_positions(T, i, j, d, sd, P, iters: int = 5):
    """(T, 2) positions minimising the Cauchy loss of ``(P[j] - P[i] - d) / sd`` over the edges
    (``d`` (E, 2) [m]), ``P[0]`` held; x and y apart (headings fixed, the problem is linear)."""
    m = len(i)
    A = sp.csr_matrix((np.r_[-np.ones(m), np.ones(m)], (np.r_[np.arange(m), np.arange(m)],
                                                        np.r_[i, j])), shape=(m, T))
    anchor = sp.csr_matrix(([1.0], ([0], [0])), shape=(T, T))
    P, normal = P.copy(), S.NormalEquations(T)
    for _ in range(iters):
        res = np.linalg.norm(P[j] - P[i] - d, axis=1)
        w = 1.0 / (1.0 + (res / sd / S.CAUCHY_SCALE) ** 2) / sd ** 2
        normal.reweight((A.T @ sp.diags(w) @ A + 1e6 * anchor).tocsc())
        for c in range(2):
            b = A.T @ (w * d[:, c])
            b[0] += 1e6 * P[0, c]
            P[:, c] = normal.solve(b)
    return P


def scan_poses(X, max_range: float | None = None, windows=S.WINDOWS,
               odometry=None, alternatives=None) -> np.ndarray:
    """(T, 3) poses (x [m], y [m], heading [rad]) of a walk of egocentric scans ``X`` (T, B)
    alone: :func:`scan_odometry`, its heading closed by loops (:func:`~.scans.scan_headings`),
    then its positions closed by loops: each candidate closure of
    :func:`~.scans.loop_closures` registered (:func:`register`, from the headings' turn) and
    kept where its cost is at most ``CLOSURE_COST`` times the median of the chain's; the
    positions closest to the chain's moves (sd ``CHAIN_SD_M`` a step) and the closures'
    (sd ``CLOSURE_SD_M``), those with a gap of at most each window admitted in turn where
    within ``POSITION_GATE_M`` of the positions so far.
    ``odometry``: :func:`scan_odometry`'s poses of ``X`` with the same ``max_range`` and its
    ``alternatives``, each turn the scans read either way settled first by the loops and the
    room ahead (:func:`resolve_turns`; None: computed here)."""
    X = np.asarray(X, dtype=np.float64)
    T, max_range = len(X), float(X.max()) if max_range is None else float(max_range)
    if odometry is None:
        odometry = scan_odometry(X, max_range, alternatives := [])
    closures = S.loop_closures(S.despike(X))
    O = resolve_turns(odometry, alternatives or [], closures, ahead=clearance_ahead(X))
    psi = S.scan_headings(X, O[:, 2], windows, closures)
    P = reckon(forward_moves(O), psi)
    ci, cj, _ = closures
    if T < 2 or not len(ci):  # no step to register, or no loop to close
        return P
    points, valid = scan_points(X, max_range - 1e-9)
    t = np.arange(1, T, max(1, T // 500))
    rel = np.array([relative_pose(P[a - 1], P[a]) for a in t]).reshape(-1, 3)
    _, chain_cost = _register_pairs(points, valid, t - 1, t, rel)
    limit = CLOSURE_COST * float(np.median(chain_cost))
    ci, cj = np.asarray(ci, dtype=np.int64), np.asarray(cj, dtype=np.int64)
    turn = np.column_stack([np.zeros((len(ci), 2)), psi[cj] - psi[ci]])
    m, cost = rows_in_threads(_register_pairs, (points, valid), ci, cj, turn)
    ok = (cost <= limit) & (np.hypot(m[:, 0], m[:, 1]) < MAX_PAIR_M)
    if not ok.any():
        return P
    ki, kj, m = ci[ok], cj[ok], m[ok]
    c, s = np.cos(psi[ki]), np.sin(psi[ki])
    d = np.column_stack([c * m[:, 0] - s * m[:, 1], s * m[:, 0] + c * m[:, 1]])
    gap = kj - ki
    chain = np.arange(T - 1)
    step = np.diff(P[:, :2], axis=0)
    xy = P[:, :2]
    for w in windows:
        sel = np.flatnonzero(gap <= w)
        sel = sel[np.linalg.norm(xy[kj[sel]] - xy[ki[sel]] - d[sel], axis=1) < POSITION_GATE_M]
        xy = _solve_positions(T, np.r_[chain, ki[sel]], np.r_[chain + 1, kj[sel]],
                              np.vstack([step, d[sel]]),
                              np.r_[np.full(T - 1, CHAIN_SD_M), np.full(len(sel), CLOSURE_SD_M)],
                              xy)
    return np.column_stack([xy, psi])
