"""Odometry learned from the data, and positions that keep alike places apart.

A continuous log says nothing of what an action does; but in a plane every command moves the
robot by roughly the same displacement wherever it is, and that displacement shows twice in the
data:

* in the views: inside a small view cluster ``k`` the views change linearly with position, so the
  mean view change of the steps of ``k`` taking action ``a`` is ``J_k v_a`` (``J_k`` the cluster's
  Jacobian, ``v_a`` the action's displacement): stacked over clusters, a matrix of rank 2 whose row
  space holds the ``v_a`` (:func:`view_change_basis`);
* in the returns: a walk that leaves a view cluster and comes back to it within a few dozen steps
  has moved by (almost) nothing, so the counts of its actions ``c`` satisfy ``sum_a c_a v_a ~ 0``
  (:func:`action_vectors` picks, within the first basis, the two directions that vanish on returns
  relative to random windows: a generalised eigenproblem).

Summing the learned displacements is dead reckoning; it drifts.  :func:`odometric_positions`
corrects it with the views: every view cluster keeps *copies* (landmarks), each a position; a step
joins the nearest copy of its cluster when it lies within a gate of the reckoned position (and
pulls that position towards it), else it starts a new copy.  One view seen in two rooms thus
becomes two copies far apart, and the rooms get apart positions: history, integrated.  The gate
is a multiple of the cell extent, the spread of reckoned positions over which one cluster is seen
(:func:`cell_extent`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.linalg import eigh

from .settings import PlaceSettings

__all__ = ["view_change_basis", "action_vectors", "reckoned_steps", "dead_reckoning",
           "cell_extent", "odometric_positions"]

# Set when the learned odometry was written and not varied since (benchmarks/notes/continuous.md
# records no run that changes them); each says why it is what it is.
#: directions of the action space kept from the views' changes: the plane's 2, plus 1 for
#: views that change non-linearly with position (directions)
BASIS_DIM = 3
#: a (view cluster, action) pair enters the basis once seen this often (steps; rarer pairs
#: weigh nothing)
MIN_PAIR_STEPS = 5
#: random windows whose action counts and returns fix the plane (windows; about 17 per step
#: of a 30-minute log at 10 Hz)
N_WINDOWS = 300_000
#: windows last up to this many mean runs of one view cluster (runs): long enough to leave a
#: cluster and come back ...
RETURN_RUNS = 6
#: ... and at least this many steps (steps)
MIN_LAG = 10
#: a line (one direction) is kept where its return share is at most this share of
#: ``max_return`` (share; 0.03 on a walk along a line, turn / forward commands 0.22-0.38)
LINE_RETURN = 0.5
#: the ridge added to the random windows' covariance, relative to its trace (share): keeps the
#: generalised eigenproblem defined where a direction never moves
RIDGE = 1e-12
#: a direction whose variance is below this share of the other's is none: a line (share) ...
DEGENERATE = 1e-12
#: ... and the smallest variance that share is taken of (a floor against 0)
TINY = 1e-300
#: the cell extent is measured on returns after this many mean runs of one view cluster, up to
#: twice as many: the motion has forgotten its direction, drift is still small (runs) ...
TAU_RUNS = 3
#: ... at least this many steps (steps) ...
MIN_TAU = 2
#: ... over this many lags between them (lags)
N_LAGS = 8
#: the cell extent of a log with no return to a view cluster (the moves' own unit) ...
NO_EXTENT = 1.0
#: ... and the least one measured (the moves' unit): a floor against 0
MIN_EXTENT = 1e-6
#: a copy's position is the running mean of the positions that joined it, over at most this
#: many (steps): old sightings, made with more drift, are forgotten
COPY_MEMORY = 50


def _inner(lengths) -> np.ndarray:
    """(T - 1,) whether step ``t`` and ``t + 1`` belong to one episode."""
    T = int(np.sum(lengths))
    inner = np.ones(max(T - 1, 0), dtype=bool)
    inner[np.cumsum(lengths)[:-1] - 1] = False
    return inner


def view_change_basis(Z, fsym, u, lengths, n_actions: int, dim: int = BASIS_DIM,
                      min_count: int = MIN_PAIR_STEPS) -> np.ndarray:
    """(A, dim) orthonormal basis of the action space that holds the actions' displacements.

    ``B[k, :, a]`` is the mean of ``Z[t + 1] - Z[t]`` over the steps of view cluster ``k`` taking
    action ``a`` (pairs seen ``min_count`` times or more, weighted by the square root of their
    count); its leading right singular vectors span the displacements (rank 2 in a plane, plus a
    component where views change non-linearly, hence ``dim`` = 3)."""
    K = int(fsym.max()) + 1
    t = np.flatnonzero(_inner(lengths))
    idx = fsym[t] * n_actions + u[t]
    dZ = Z[t + 1] - Z[t]
    cnt = np.bincount(idx, minlength=K * n_actions).astype(np.float64)
    sums = np.stack([np.bincount(idx, dZ[:, j], minlength=K * n_actions)
                     for j in range(Z.shape[1])], axis=1)
    w = np.where(cnt >= min_count, np.sqrt(cnt) / np.maximum(cnt, 1.0), 0.0)
    B = (sums * w[:, None]).reshape(K, n_actions, -1).transpose(0, 2, 1).reshape(-1, n_actions)
    _, _, vt = np.linalg.svd(B, full_matrices=False)
    return vt[:min(dim, vt.shape[0])].T


def _window_counts(fsym, u, lengths, n_actions, max_lag, n_pairs, rng):
    """Action counts of random windows ``[s, s + lag)`` inside episodes, and whether each window
    returns to its first view cluster."""
    T = fsym.size
    C = np.zeros((T + 1, n_actions))
    C[1:] = np.cumsum(np.eye(n_actions)[u], axis=0)
    episode = np.repeat(np.arange(len(lengths)), lengths)
    s = rng.integers(0, max(T - 2, 1), n_pairs)
    t = np.minimum(s + rng.integers(2, max_lag + 1, n_pairs), T - 1)
    keep = episode[s] == episode[t]
    s, t = s[keep], t[keep]
    return C[t] - C[s], fsym[s] == fsym[t]


def action_vectors(Z, fsym, u, lengths, n_actions: int, *,
                   max_return: float = PlaceSettings.max_return, max_lag: int | None = None,
                   n_pairs: int = N_WINDOWS, seed: int = 0):
    """``(V, ratios)``: (A, 2) displacement of every action, up to a rotation and mirror of the
    plane (which change no closed loop), scaled so that steps move alike in every direction, 1
    on average; and, for the two leading directions, the share of a random window's
    displacement that windows returning to their view cluster keep.

    Both directions are kept (a plane) where that share is at most ``max_return`` for both
    (0.17-0.27 with compass commands in the measured worlds; 0.42-0.82 for the second direction
    when the same walks are given turn / forward commands, whose displacement depends on the
    heading); else the first alone (a line) where its share is at most half that (0.03 on a walk
    along a line; turn / forward commands 0.22-0.38, refused); else none, and ``V`` is zero: no
    odometry.  Windows are 2 to ``max_lag`` steps long (None: :data:`RETURN_RUNS` x the mean
    run of one cluster, at least :data:`MIN_LAG`)."""
    Q = view_change_basis(Z, fsym, u, lengths, n_actions)
    if max_lag is None:  # windows long enough to leave a cluster and come back: 6 mean runs
        max_lag = max(int(round(RETURN_RUNS * fsym.size
                                / (1 + np.count_nonzero(np.diff(fsym))))), MIN_LAG)
    D, ret = _window_counts(fsym, u, lengths, n_actions, max_lag, n_pairs,
                            np.random.default_rng(seed))
    V = np.zeros((n_actions, 2))
    if ret.sum() < Q.shape[1] or Q.shape[1] < 2:
        return V, np.ones(2)
    Dq = D @ Q
    on_returns = Dq[ret].T @ Dq[ret] / ret.sum()
    overall = Dq.T @ Dq / len(Dq)
    lam, w = eigh(on_returns, overall + RIDGE * np.trace(overall) * np.eye(Q.shape[1]))
    if lam[1] <= max_return:
        kept = np.array([True, True])  # a plane
    else:
        kept = np.array([lam[0] <= max_return * LINE_RETURN, False])  # a line, or nothing
    V[:, kept] = (Q @ w[:, :2])[:, kept]
    return (_isotropic(V, u) if kept.any() else V), lam[:2]


def _isotropic(V, u) -> np.ndarray:
    """``V`` under the linear map that makes the mean step's covariance the identity / 2 (a step
    moves 1 on average, alike in every direction): the eigenproblem fixes the plane only up to
    a linear map, and a stretched plane would make the gate of the copies longer one way."""
    steps = V[u]
    cov = steps.T @ steps / max(len(u), 1)
    vals, vecs = np.linalg.eigh(cov)
    if vals[0] <= DEGENERATE * max(vals[1], TINY):  # a line: scale only
        scale = np.sqrt(vals[1])
        return V / scale if scale > 0 else V
    return V @ vecs @ np.diag(1.0 / np.sqrt(2.0 * vals)) @ vecs.T


def dead_reckoning(u, lengths, V) -> np.ndarray:
    """(T, 2) summed displacements, restarting at 0 with every episode."""
    P = np.cumsum(reckoned_steps(u, lengths, V), axis=0)
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    return P - P[starts]


def cell_extent(fsym, P, lengths) -> float:
    """The spread (rms per coordinate) of reckoned positions over which one view cluster is seen:
    from returns to a cluster after leaving it, lags between tau and 2 tau (tau = 3 x the mean run
    of one cluster): there the motion has forgotten its direction and drift is still small,
    ``E|P[t] - P[s]|^2 = 4 r^2``."""
    T = fsym.size
    inner = _inner(lengths)
    runs = T / (1 + np.count_nonzero(fsym[1:] != fsym[:-1]))
    tau = max(int(round(TAU_RUNS * runs)), MIN_TAU)
    episode = np.repeat(np.arange(len(lengths)), lengths)
    sq = []
    for lag in np.unique(np.linspace(tau, 2 * tau, N_LAGS).astype(np.int64)):
        s = np.arange(max(T - lag, 0))
        ret = (fsym[s] == fsym[s + lag]) & (episode[s] == episode[s + lag])
        sq.append(((P[s + lag] - P[s]) ** 2).sum(axis=1)[ret])
    sq = np.concatenate(sq) if sq else np.zeros(0)
    if sq.size == 0 or not inner.any():
        return NO_EXTENT
    return float(max(np.sqrt(sq.mean() / 4.0), MIN_EXTENT))


@njit(cache=True)
def _copies_filter(fsym, steps, starts, gate, pull, cap, n_sym):  # pragma: no cover - compiled
    T = fsym.size
    M = np.zeros((T, 2))
    n = np.zeros(T)
    head = np.full(n_sym, -1)
    nxt = np.full(T, -1)
    n_copies = 0
    P = np.zeros(2)
    out = np.empty((T, 2))
    joined = np.empty(T, dtype=np.int64)
    for t in range(T):
        if starts[t]:
            c = head[fsym[t]]  # a new episode starts at a copy of its first view, if any
            if c >= 0:
                P[0], P[1] = M[c, 0], M[c, 1]
        else:
            P[0] += steps[t, 0]
            P[1] += steps[t, 1]
        best, bd = -1, gate * gate
        c = head[fsym[t]]
        while c >= 0:
            d = (P[0] - M[c, 0]) ** 2 + (P[1] - M[c, 1]) ** 2
            if d < bd:
                bd, best = d, c
            c = nxt[c]
        if best >= 0:
            P[0] += pull * (M[best, 0] - P[0])
            P[1] += pull * (M[best, 1] - P[1])
            n[best] += 1
            w = 1.0 / min(n[best], cap)
            M[best, 0] += w * (P[0] - M[best, 0])
            M[best, 1] += w * (P[1] - M[best, 1])
        else:
            best = n_copies
            n_copies += 1
            M[best, 0], M[best, 1] = P[0], P[1]
            n[best] = 1.0
            nxt[best] = head[fsym[t]]
            head[fsym[t]] = best
        out[t, 0], out[t, 1] = P[0], P[1]
        joined[t] = best
    return out, joined, n_copies


def reckoned_steps(u, lengths, V) -> np.ndarray:
    """(T, 2) the move into every step: ``V[u[t - 1]]``, 0 at the first step of an episode."""
    steps = np.zeros((u.size, 2))
    steps[1:] = V[u[:-1]]
    steps[np.cumsum(lengths)[:-1]] = 0.0
    return steps


def odometric_positions(fsym, steps, lengths, gate: float, *,
                        pull: float = PlaceSettings.pull, cap: int = COPY_MEMORY):
    """``(P, copy, n_copies)``: (T, 2) positions from dead reckoning of the moves ``steps``
    (:func:`reckoned_steps`) corrected by copies of the view clusters, the copy every step
    joined, and the number of copies.  A step joins the nearest copy of its cluster within
    ``gate`` (the reckoned position moves ``pull`` of the way to it; the copy's position is the
    running mean of the positions that joined it, over at most the last ``cap``), else starts a
    new copy."""
    starts = np.zeros(fsym.size, dtype=np.bool_)
    starts[np.cumsum(lengths) - lengths] = True
    P, copy, n_copies = _copies_filter(np.ascontiguousarray(fsym, dtype=np.int64),
                                       np.ascontiguousarray(steps, dtype=np.float64), starts,
                                       float(gate), float(pull), float(cap),
                                       int(fsym.max()) + 1)
    return P, copy, int(n_copies)
