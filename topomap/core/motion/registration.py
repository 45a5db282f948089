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
The steps run compiled, :data:`STOP_EVERY` scans a call (:func:`_steps`, which releases the
GIL), and a walk of more than :data:`HALVES` scans as two halves on two threads.

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

import numpy as np
import scipy.sparse as sp
from numba import njit, typeof
from numba.typed import List

from ..split.threads import in_threads, rows_in_threads
from . import scans as S
from .icp import (CAUCHY_M, ICP_ITERATIONS, MAX_PAIR_M, NORMAL_GAP_M, NORMAL_HALF, _register_pairs,
                  _register_starts, icp, keyframe_lines, register, register_each, scan_points)
from .reckoning import compose, forward_moves, reckon, relative_pose
from .turn_rivals import (RETRY_GAIN, TURN_CHECK, checked_index, checked_turn, clearance_ahead,
                          resolve_turns, rival_index, rival_of, turn_apart)

__all__ = ["scan_points", "keyframe_lines", "register", "register_each", "checked_turn",
           "resolve_turns", "scan_odometry", "scan_poses", "retry_yardstick", "KEYFRAME_TRAVEL",
           "KEYFRAME_TURN", "ICP_ITERATIONS", "CAUCHY_M", "MAX_PAIR_M", "RETRY_COST", "RETRY_GAIN",
           "RECENT", "SWEEP_BEAMS", "CLOSURE_COST", "CHAIN_SD_M", "CLOSURE_SD_M", "NORMAL_HALF",
           "POSITION_GATE_M", "NORMAL_GAP_M", "TURN_CHECK", "averaged_pose", "older_keyframes",
           "add_keyframe", "OLDER_KEYFRAMES", "AVERAGE_COST", "AVERAGE_TURN", "HALVES",
           "STOP_EVERY", "turn_apart", "rival_of"]

#: m: a new keyframe once the scan lies this far from the last one (0.10 put robot_alike@0.3333
#: seed 0 0.61 m off along the true headings, 0.05 0.55 m: no gain from fewer keyframes)
KEYFRAME_TRAVEL = 0.05
#: rad: a new keyframe once the scan has turned this far from the last (3.3 beams of 60; not tuned)
KEYFRAME_TURN = 0.35
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
#: thread.  A registration waits for the one before, 0.3 ms a scan: on a 2-hour walk (73,000
#: scans, ``robot_alike@0.3333`` seed 0, idle) 30 s in one run, 11.7-13.5 s (23-26 s of CPU)
#: in halves; closed by loops (:func:`scan_poses`) its poses lie 0.730 m from the truth after a
#: rigid alignment either way (0.728 m in one run).  Walks up to it keep the bits of one run.
HALVES = 40_000
#: scans registered in one compiled call between two asks of :func:`scan_odometry`'s ``stop``
#: (0.3 s at the 0.3 ms a scan of a 60-beam walk; speed alone, never the result)
STOP_EVERY = 1000


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
    """:func:`scan_odometry` of one run of scans ``X`` (T, B), float64, step after step: the
    compiled :func:`_steps` over :data:`STOP_EVERY` scans at a time, ``stop`` asked before each."""
    T, B = X.shape
    max_range -= 1e-9
    Xd = S.despike(X)
    turns = np.r_[0.0, S.scan_turns(Xd[:-1], Xd[1:])]
    sweep = 2 * np.pi * np.arange(0, B, SWEEP_BEAMS) / B
    # every scan's points once, the keyframe's lines once a keyframe (as :func:`register`)
    points, valid = scan_points(X, max_range)
    lines = keyframe_lines(points[0], valid[0])
    older, frames = older_keyframes(lines)
    poses, costs, rivals = np.zeros((T, 3)), np.zeros(T), np.zeros((T, 4))
    walk = (poses, costs, rivals, np.zeros(2, dtype=np.int64), np.zeros(3), np.zeros(3))
    for t in range(1, T, STOP_EVERY):
        if stop is not None and stop():
            return None
        lines, frames = _steps(points, valid, turns, sweep, walk, lines, older, frames,
                               t, min(T, t + STOP_EVERY))
    if alternatives is not None:
        alternatives += [(int(r[0]), r[1:].copy()) for r in rivals[:walk[3][1]]]
    return poses


@njit(cache=True, nogil=True)
def _steps(points, valid, turns, sweep, walk, lines, older, frames, t0, t1):
    """Steps ``t0`` to ``t1 - 1`` of :func:`_registered` in one compiled call: ``walk`` =
    ``(poses (T, 3), costs (T,), rivals (T, 4): t, pose, (key, rivals), rel, last)`` changed in
    place (``rel``: the step before's pose in the keyframe's frame; ``last``: the step before's
    move in its own frame), ``older`` too; the keyframe's ``lines`` and ``frames`` returned."""
    poses, costs, rivals, count, rel, last = walk
    starts, wide = np.zeros((3, 3)), np.zeros((len(sweep), 3))
    for t in range(t0, t1):
        starts[0] = compose(rel, np.array([last[0], last[1], turns[t]]))
        starts[1] = compose(rel, last)
        starts[2] = rel
        ms, _, cs = _register_starts(lines[0], lines[1], lines[2], points[t], valid[t], starts)
        k = checked_index(ms, cs, rel)
        m, cost = ms[k].copy(), cs[k]
        r = rival_index(ms, cs, m, cost)
        rival = ms[r].copy() if r >= 0 else None
        if t > 10 and cost > RETRY_COST * _yardstick(costs, t - 1):
            for j in range(len(sweep)):
                wide[j, 0], wide[j, 1], wide[j, 2] = rel[0], rel[1], rel[2] + sweep[j]
            ms, _, cs = _register_starts(lines[0], lines[1], lines[2], points[t], valid[t], wide)
            j = np.argmin(cs)  # NaN first in line, as numpy's
            if cs[j] < RETRY_GAIN * cost and np.hypot(ms[j, 0] - rel[0],
                                                      ms[j, 1] - rel[1]) < KEYFRAME_TRAVEL:
                rival = m if turn_apart(m, ms[j]) > TURN_CHECK else rival
                m, cost = ms[j].copy(), cs[j]
        costs[t - 1] = cost
        key = count[0]
        poses[t] = _averaged(compose(poses[key], m), cost, older, frames, points[t], valid[t])
        if len(frames):
            m = relative_pose(poses[key], poses[t])
        if rival is not None:
            rivals[count[1], 0] = t
            rivals[count[1], 1:] = compose(poses[key], rival)
            count[1] += 1
        last[:] = relative_pose(poses[t - 1], poses[t])
        rel[:] = m
        if np.hypot(m[0], m[1]) >= KEYFRAME_TRAVEL or abs(m[2]) >= KEYFRAME_TURN:
            frames = _add_keyframe(older, frames, poses[key], lines)
            count[0] = t
            rel[:] = 0.0
            lines = keyframe_lines(points[t], valid[t])
    return lines, frames


def averaged_pose(pose, cost: float, older, q, qv) -> np.ndarray:
    """(3,) pose (x [m], y [m], heading [rad]) of a scan (points ``q``, valid ``qv``) that its
    keyframe puts at ``pose`` at ``cost``: the mean of ``pose`` and its registrations from
    ``pose`` against the ``older`` keyframes (``(lines, frames)`` of :func:`older_keyframes`, in
    one compiled call, :func:`_register_older`) that cost at most :data:`AVERAGE_COST` times
    ``cost`` and lie within :data:`KEYFRAME_TRAVEL` and :data:`AVERAGE_TURN` of it."""
    return _averaged(np.asarray(pose, dtype=np.float64), float(cost), older[0], older[1], q, qv)


@njit(cache=True)
def _averaged(pose, cost, lines, frames, q, qv):
    """:func:`averaged_pose`, compiled; its sums in the order of ``np.add.reduce``'s: the x and y
    row after row, the turns from ``pose``'s each after the first (then added to it)."""
    if not len(frames):
        return pose
    e, c = _register_older(lines, frames, pose, q, qv)
    n, x, y, turn = 1, pose[0], pose[1], 0.0
    for k in range(len(c)):
        d = (e[k, 2] - pose[2] + np.pi) % (2 * np.pi) - np.pi
        if (c[k] <= AVERAGE_COST * cost and abs(d) < AVERAGE_TURN
                and np.hypot(e[k, 0] - pose[0], e[k, 1] - pose[1]) < KEYFRAME_TRAVEL):
            n, x, y, turn = n + 1, x + e[k, 0], y + e[k, 1], turn + d
    if n == 1:
        return pose
    return np.array([x / n, y / n, pose[2] + turn / n])


def older_keyframes(like) -> tuple:
    """No older keyframes (``(lines, frames)`` of :func:`averaged_pose`) whose lines are of the
    type of ``like`` (a :func:`keyframe_lines`); :func:`add_keyframe` adds one."""
    return List.empty_list(typeof(like)), np.zeros((0, 5))


def add_keyframe(older, pose, lines) -> tuple:
    """``older`` (:func:`older_keyframes`, changed in place) with the keyframe at ``pose`` (3,)
    [m, m, rad] of :func:`keyframe_lines` ``lines`` last, the first left out past
    :data:`OLDER_KEYFRAMES`."""
    return older[0], _add_keyframe(older[0], older[1], np.asarray(pose, dtype=np.float64), lines)


@njit(cache=True)
def _add_keyframe(older, frames, pose, lines):
    """:func:`add_keyframe` of the typed list ``older`` (changed in place) and its ``frames``
    (K, 5): x, y, heading, its cosine and sine; the new frames returned."""
    older.append(lines)
    if len(older) > OLDER_KEYFRAMES:
        older.pop(0)
    out = np.zeros((len(frames) + 1, 5))
    out[:-1] = frames
    out[-1] = np.array([pose[0], pose[1], pose[2], np.cos(pose[2]), np.sin(pose[2])])
    return out[-OLDER_KEYFRAMES:].copy()


def retry_yardstick(costs) -> float:
    """The cost a retry (:data:`RETRY_COST`) weighs a registration against: the lesser of the
    median of the last :data:`RECENT` of ``costs`` (the walk's so far, in order; ``np.median``'s
    value, NaN too) and the last one."""
    return float(_yardstick(np.asarray(costs, dtype=np.float64), len(costs)))


@njit(cache=True)
def _yardstick(costs, n):
    """:func:`retry_yardstick` of the first ``n`` of ``costs``, compiled."""
    recent = np.sort(costs[max(0, n - RECENT):n])
    if np.isnan(recent[-1]):  # sorted last
        return np.nan
    k = len(recent)
    median = recent[k // 2] if k % 2 else (recent[k // 2 - 1] + recent[k // 2]) / 2
    return costs[n - 1] if costs[n - 1] < median else median


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
               odometry=None, alternatives=None, closures=None) -> np.ndarray:
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
    room ahead (:func:`resolve_turns`; None: computed here).  ``closures``: the candidate
    closures of ``X`` (:func:`~.scans.loop_closures` of its :func:`~.scans.despike`; None:
    found here)."""
    X = np.asarray(X, dtype=np.float64)
    T, max_range = len(X), float(X.max()) if max_range is None else float(max_range)
    if odometry is None:
        odometry = scan_odometry(X, max_range, alternatives := [])
    if closures is None:
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
