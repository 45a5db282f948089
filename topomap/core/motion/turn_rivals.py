"""A turn the scans read either way: the registration's rivals settled by the loops and by the
room the robot had to turn in.

Where a place's scans look alike turned round (a narrow passage, a point-symmetric plan), a
registration can read a step's turn two ways half a turn apart; :func:`~.registration.scan_odometry`
keeps one and records the other as a *rival*.  :func:`resolve_turns` takes the rival where the
loop closures across the step agree with it more -- unless the rival turns the robot by over
:data:`TURN_CHECK` in that one step while its scan saw no wall within
:data:`REVERSAL_CLEARANCE_M` ahead (:func:`clearance_ahead`): a robot turns about in one step
only by bouncing off what lies in front of it, and where nothing does the closures that side
with the half turn are a place matching its own reflection.
"""

from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from . import scans as S
from .reckoning import compose, relative_pose

__all__ = ["resolve_turns", "clearance_ahead", "checked_turn", "rival_of", "turn_apart",
           "checked_index", "rival_index",
           "TURN_CHECK", "RETRY_GAIN", "REVERSAL_CLEARANCE_M", "AHEAD_HALF_ANGLE"]

#: rad: a registration turning the scan more than this in one step (from the step before's pose)
#: is kept only where it costs under ``RETRY_GAIN`` of the least-cost one that turns less, as a
#: retry is: where the scans look alike turned round the two cost nearly the same, and the
#: turned one put a walk half a turn off (robot_twin@0.3333 seed 0, step 5669: 3.13 rad at 0.89
#: of the unturned one's cost, the true turn 0.15 rad).  The robot's true turns of over 1 rad in
#: one step (a bounce off a wall, 1 % of steps) cost 0.16-0.44 of the unturned one's (54 on that
#: walk's first 6,000 steps); a quarter turn is far beyond a step's ordinary turn (median 0.12
#: rad on a turn command)
TURN_CHECK = np.pi / 2
#: a retry's motion is kept where its cost is below this share of the first one's and it has
#: moved less than :data:`~.registration.KEYFRAME_TRAVEL` from the step before (a wrong match of a wide sweep moved
#: 0.47 m in one step at a cost 5 % below the right one's)
RETRY_GAIN = 0.8
#: rad: the beams within this of the heading are the robot's view ahead (10 beams either side of
#: 60: the nearest return there lay within 0.096 m before every one of the 1,772 true one-step
#: turns of over 2 rad on the 15 benchmark walks and their held-out walks; 5 beams either side
#: left 2 of them beyond 0.1 m, the heading's beam alone 51)
AHEAD_HALF_ANGLE = np.pi / 3
#: m: a rival turning the robot by over :data:`TURN_CHECK` in one step is refused where the scan
#: before it saw nothing within this ahead.  The true one-step turns of over 2 rad came at most
#: 0.096 m from a wall ahead (above; the harness's robots bounce where they meet one); of the 7
#: rivals the loops took on those 30 walks the 4 that turned the walk wrongly half round over
#: the next 300 steps lay 0.136-0.237 m from one, the 2 that mended a half turn the registration
#: missed 10 steps later 0.040 m (the seventh, a rival turning 0.32 rad against a kept 1.33,
#: is no reversal).  A faster robot reverses farther off now and then: at 0.2 m/s with a 0.3 m
#: wall margin 1 of 67 true reversals came 0.26 m from a wall ahead, the rest within 0.08 m
REVERSAL_CLEARANCE_M = 0.12


def clearance_ahead(X) -> np.ndarray:
    """(T,) m: the nearest range of each scan of ``X`` (T, B) among its beams within
    :data:`AHEAD_HALF_ANGLE` of the heading (beam ``k`` at ``2 pi k / B``)."""
    X = np.asarray(X, dtype=np.float64)
    B = X.shape[1]
    k = np.arange(B)
    ahead = np.minimum(k, B - k) * 2 * np.pi / B <= AHEAD_HALF_ANGLE + 1e-9
    return X[:, ahead].min(axis=1)


def _agree(turn, closure_turn) -> int:
    """How many of the ``turn`` s (rad) lie within :data:`~.scans.CLOSURE_GATE` of the closures'
    own (wrapped)."""
    return int(np.count_nonzero(np.abs(S._wrap(turn - closure_turn)) < S.CLOSURE_GATE))


def _reversal_without_room(poses, t, alt, ahead) -> bool:
    """Whether rival pose ``alt`` of step ``t`` turns from ``poses[t - 1]`` by over
    :data:`TURN_CHECK` where ``ahead[t - 1]`` (m, :func:`clearance_ahead`) exceeds
    :data:`REVERSAL_CLEARANCE_M`."""
    if ahead is None or t < 1:
        return False
    turn = abs(S._wrap(alt[2] - poses[t - 1, 2]))
    return bool(turn > TURN_CHECK and ahead[t - 1] > REVERSAL_CLEARANCE_M)


def resolve_turns(poses, alternatives, closures, window: int = S.WINDOWS[0],
                  ahead=None) -> np.ndarray:
    """(T, 3) ``poses`` (:func:`~.registration.scan_odometry`'s) with each step of
    ``alternatives`` (``(t, pose)``, in order) set to its rival pose where more of the loop
    ``closures`` ``(i, j, turn)`` of at most ``window`` steps across it agree with the rival
    (within :data:`~.scans.CLOSURE_GATE` of the poses' turn from ``i`` to ``j``): the steps
    after it move with it, rigidly (a turn the scans could read either way, settled by the scans
    seen before and after it).  A rival is the move it makes from ``poses[t - 1]``, put on the
    step before as settled so far: a rival taken earlier has moved it (weighed in ``poses``'
    frame instead, ``robot_twin@0.3333`` seed 0's second rival turned 0.1 rad where it undid
    a half turn, was left, and the closed headings stayed half a turn off for the last 8,200
    steps).  ``ahead``: (T,) m, :func:`clearance_ahead` of the walk's scans; a rival turning
    over :data:`TURN_CHECK` from the step before where the scan before saw nothing within
    :data:`REVERSAL_CLEARANCE_M` is refused (None: none refused)."""
    raw = np.asarray(poses, dtype=np.float64)
    P = raw.copy()
    ci, cj, cr = (np.asarray(c) for c in closures)
    lo, hi = np.minimum(ci, cj), np.maximum(ci, cj)
    sign = np.where(cj >= ci, 1.0, -1.0)
    for t, alt in alternatives:
        sel = (lo < t) & (hi >= t) & (hi - lo <= window)
        if not sel.any() or _reversal_without_room(raw, t, alt, ahead):
            continue
        if not np.array_equal(P[t - 1], raw[t - 1]):  # a rival taken before moved the walk
            alt = compose(P[t - 1], relative_pose(raw[t - 1], alt))
        delta = (alt[2] - P[t, 2] + np.pi) % (2 * np.pi) - np.pi
        turn = P[cj[sel], 2] - P[ci[sel], 2]
        if _agree(turn + delta * sign[sel], cr[sel]) > _agree(turn, cr[sel]):
            d = P[t:, :2] - P[t, :2]
            c, s = np.cos(alt[2] - P[t, 2]), np.sin(alt[2] - P[t, 2])
            P[t:, :2] = alt[:2] + np.column_stack([c * d[:, 0] - s * d[:, 1],
                                                   s * d[:, 0] + c * d[:, 1]])
            P[t:, 2] += alt[2] - P[t, 2]
    return P


def checked_turn(results, before) -> tuple[np.ndarray, int, float]:
    """The registration of ``results`` (``(motion, paired, cost)`` of one scan from several
    starts, :func:`~.icp.register_each`) a walk keeps, given ``before``, the step before's
    pose in the same keyframe's frame: the least-cost one, unless it turns more than
    :data:`TURN_CHECK` from ``before`` and costs at least ``RETRY_GAIN`` of the least-cost
    result that turns less -- then that one (a scan that looks alike turned round)."""
    motions, costs = _motions_costs(results)
    return results[checked_index(motions, costs, np.asarray(before, dtype=np.float64))]


def rival_of(results, m, cost):
    """The motion of the least-cost result of ``results`` turning more than :data:`TURN_CHECK`
    from the kept motion ``m`` at a cost below ``cost / RETRY_GAIN``; None where there is none."""
    motions, costs = _motions_costs(results)
    k = rival_index(motions, costs, np.asarray(m, dtype=np.float64), float(cost))
    return None if k < 0 else results[k][0]


def _motions_costs(results) -> tuple[np.ndarray, np.ndarray]:
    """``(motions (S, 3), costs (S,))`` of ``results`` (``(motion, paired, cost)``)."""
    return (np.array([r[0] for r in results], dtype=np.float64).reshape(-1, 3),
            np.array([r[2] for r in results], dtype=np.float64))


@register_jitable
def turn_apart(a, b) -> float:
    """rad: how far the turns of motions ``a`` and ``b`` lie apart (wrapped, 0 to pi)."""
    return abs((a[2] - b[2] + np.pi) % (2 * np.pi) - np.pi)


@register_jitable
def _least(costs, take) -> int:
    """The index of the least of ``costs`` among those ``take`` (bool) marks, the first of
    equal ones and a NaN first in line kept (as Python's ``min``); -1 where none is taken."""
    k = -1
    for i in range(len(costs)):
        if take[i] and (k < 0 or costs[i] < costs[k]):
            k = i
    return k


@register_jitable
def checked_index(motions, costs, before) -> int:
    """The row of ``motions`` (S, 3) at ``costs`` (S,) :func:`checked_turn` keeps."""
    near = np.array([turn_apart(m, before) <= TURN_CHECK for m in motions])
    best = _least(costs, np.ones(len(costs), dtype=np.bool_))
    other = _least(costs, near)
    if near[best] or other < 0:
        return best
    return best if costs[best] < RETRY_GAIN * costs[other] else other


@register_jitable
def rival_index(motions, costs, m, cost) -> int:
    """The row of ``motions`` (S, 3) at ``costs`` (S,) that is :func:`rival_of` the kept
    motion ``m`` at ``cost``; -1 where none is."""
    far = np.array([turn_apart(motions[k], m) > TURN_CHECK and costs[k] * RETRY_GAIN < cost
                    for k in range(len(costs))])
    return _least(costs, far)
