"""A pose graph over the steps of a log: the odometry's drift removed by its loop closures.

The copies filter (:func:`~topomap.core.motion.odometry.odometric_positions`) corrects dead
reckoning as it goes, forward only: a loop closed late pulls the step that closes it, not the
steps before.  A pose graph weighs the whole log at once: an unknown position for every step
and every copy of a view cluster; every move between two steps of an episode is a factor
``x[t] - x[t-1] = step[t]`` (standard deviation :data:`STEP_SD` of a mean step), every step a
factor ``x[t] = copy[c(t)]`` to the copy it joined (standard deviation one cell extent, the
spread over which one view is seen).  Both are linear in the positions, so the most probable
positions are one sparse linear least-squares solve (scipy's sparse LU on the normal
equations), exact -- no iterations, no starting point.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from .odometry import odometric_positions, reckoned_steps

__all__ = ["STEP_SD", "ANCHOR_SD", "pose_graph", "graph_positions"]

#: reckoned moves (rms 1 by construction, :func:`~topomap.core.motion.odometry.action_vectors`):
#: the standard deviation of one move's error, against one cell extent for a step's distance
#: to its copy.  The frame's rms distance from the truth after an affine fit, filter alone /
#: pose graph at 0.2, 0.35, 0.5, 1 (seed 0, 2026-12-02): Tanni's rat path in its room with two
#: pillars, copies at 6 cell extents, 0.226 / 0.131, 0.123, 0.129, 0.158 m; at 3 cell extents
#: 0.703 / 0.316, 0.364, 0.402, 0.477 m; ``two_rooms`` at 3 and 6, 0.13 / 0.072, 0.055, 0.050,
#: 0.051 m.  0.35 is within 0.05 m of the best of the four everywhere.
STEP_SD = 0.35
#: cell extents: the first step of every episode is held at 0 this loosely -- it only fixes
#: where an episode that shares no copy with another sits, not its shape.
ANCHOR_SD = 1e3
#: the rms move of a log without one (the moves' unit), and the least a move's standard
#: deviation may be (the moves' unit): floors against 0, so that every factor has a weight
NO_MOVE = 1.0
MIN_SD = 1e-12


def pose_graph(steps, copy, n_copies: int, lengths, cell: float,
               step_sd: float = STEP_SD) -> tuple[np.ndarray, np.ndarray]:
    """``(x, m)``: the least-squares positions of the steps ((T, 2)) and of the copies
    ((n_copies, 2)) given the moves ``steps`` ((T, 2), 0 at an episode's first step: see
    :func:`~topomap.core.motion.odometry.reckoned_steps`), each step's ``copy`` (its closure)
    and the episodes' ``lengths``; a move's factor has standard deviation ``step_sd`` times the
    rms move (1 for learned moves), a closure's ``cell`` (both in the moves' unit)."""
    steps = np.asarray(steps, dtype=np.float64)
    T = steps.shape[0]
    first = np.cumsum(lengths) - np.asarray(lengths)
    inner = np.setdiff1d(np.arange(T), first)
    move = float(np.sqrt(np.mean(np.sum(steps[inner] ** 2, axis=1)))) if inner.size else NO_MOVE
    w_step, w_close = 1.0 / max(step_sd * move, MIN_SD), 1.0 / cell
    n_odo = inner.size
    rows = np.concatenate([np.arange(n_odo), np.arange(n_odo), n_odo + np.arange(T),
                           n_odo + np.arange(T), n_odo + T + np.arange(first.size)])
    cols = np.concatenate([inner, inner - 1, np.arange(T), T + np.asarray(copy), first])
    vals = np.concatenate([np.full(n_odo, w_step), np.full(n_odo, -w_step), np.full(T, w_close),
                           np.full(T, -w_close), np.full(first.size, 1.0 / (ANCHOR_SD * cell))])
    A = sp.csr_matrix((vals, (rows, cols)), shape=(n_odo + T + first.size, T + n_copies))
    b = np.zeros((A.shape[0], 2))
    b[:n_odo] = w_step * steps[inner]
    x = spsolve((A.T @ A).tocsc(), np.asarray(A.T @ b))
    x = np.asarray(x).reshape(T + n_copies, 2)
    return x[:T], x[T:]


def graph_positions(fsym, u, lengths, V, extent: float, gate: float,
                    pull: float) -> np.ndarray:
    """(T, 2) the pose graph's positions, in cell extents, of the steps whose view clusters are
    ``fsym``, moved by the actions ``u`` (displacements ``V``), their closures the copies of the
    filter at ``gate`` cell extents of ``extent`` (see
    :func:`~topomap.core.motion.odometry.odometric_positions`)."""
    steps = reckoned_steps(u, lengths, V)
    _, copy, n_copies = odometric_positions(fsym, steps, lengths, gate * extent, pull=pull)
    return pose_graph(steps, copy, n_copies, lengths, extent)[0] / extent
