"""Whether a log's actions are turn commands, read off the odometry given with it.

A robot driven by turn commands (``forward`` / ``turn_left`` / ``turn_right`` / ``stop``) turns
as its commands say: its odometry turns left on ``turn_left`` steps, right on ``turn_right``
steps, hardly at all on the others.  A compass walker's commands (east, north, ...) name where it
goes, not how it turns: it turns left into ``north`` from ``east`` and right from ``west``, so
every command's mean turn is about the same.  :func:`turn_share` measures that on the given
odometry: the share of the variance of the per-step turns explained by the command taken (the
between-command sum of squares over the total, ``eta^2``).  A gyro bias shifts every command's
turns alike and explains nothing; heading drift changes no single step's turn.

The continuous path's own test -- whether walks that return to a view cancel their commands'
moves (:func:`~topomap.core.motion.odometry.action_vectors`) -- is made without odometry and can
pass turn commands: on ``robot_office`` (10 x 6 m, and a third of that) it passed them on five of
six walks, so the robot route was never tried there.  Measured (``benchmarks/notes/robots.md``,
2026-12-02, evening): the robots of ``benchmarks/bench_robots.py`` 0.26-0.32 on 15 walks of five
plans, the arena's ``actions=turns`` walker 0.51-0.64 on ten walks of five plans, its compass
walker 0.001-0.003 on the same ten.
"""

from __future__ import annotations

import numpy as np

__all__ = ["turn_share", "MIN_TURN_SHARE"]

#: share: a log whose commands explain at least this share of its odometry's turns is taken for
#: turn commands (compass walkers 0.001-0.003, turn commands 0.26-0.64; an order of magnitude
#: from either side)
MIN_TURN_SHARE = 0.03


def turn_share(odometry, u) -> float:
    """The share (0-1) of the variance of one walk's per-step turns (the wrapped difference of
    the heading column of ``odometry`` (T, 3), step ``t`` to ``t + 1``) explained by the command
    ``u[t]`` (or ``u[t + 1]``, for a log that records the command with the reading it led to:
    the larger of the two); 0 where the walk never turns."""
    O = np.asarray(odometry, dtype=np.float64)
    u = np.asarray(u, dtype=np.int64)
    if len(O) < 3:
        return 0.0
    d = np.angle(np.exp(1j * np.diff(O[:, 2])))
    total = float(((d - d.mean()) ** 2).sum())
    if total <= 0.0:
        return 0.0
    best = 0.0
    for a in (u[:-1], u[1:]):
        n = np.bincount(a)
        means = np.bincount(a, d) / np.maximum(n, 1)
        best = max(best, float((n * (means - d.mean()) ** 2).sum()) / total)
    return best
