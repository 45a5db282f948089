"""Research route for robot logs: a metric map from headings closed by loops, then an HMM over
(cell, heading) whose transitions carry the odometric displacement (``bench_robots.py --routes
headgraph_kf headgraph_kf_scans``).

``headgraph_kf``        with wheel odometry (rung 2)
``headgraph_kf_teleport`` the same, a teleport anywhere allowed at ``TELEPORT``
``headgraph_kf_scans``  without (rung 3): turns from the scans, each moving command one unit of
                        travel unless stopped (the log holds no speed; the unit is the same in
                        both walks)

Learning: every step's heading from :func:`topomap.core.motion.scans.scan_headings` (the
odometry's turns calibrated against the scans', or the scans' own, closed by scan-matched loop
closures); positions dead-reckoned along it (the odometry's forward travel); ``CELLS`` cells
on those positions (:func:`cells`); each cell's mean scan turned into the map frame, one pooled
variance; the cells' successor graph between keyframes (a keyframe every half cell spacing
travelled).

Placing a held-out walk: its keyframes' moves (forward, left, turn in the frame of the keyframe
before) from its own odometry (or commands and scan turns); Viterbi over (cell, heading bin, 60
bins = the beams): a move from cell ``c`` at heading ``h`` lands at ``centre_c + R(h) move``, each
successor cell weighted by a Gaussian of its distance from there (sd half a cell spacing); the
heading turns by the move's turn (+- ``HEADING_SD_BINS``); the emission is the scan against the
cell's mean scan turned to ``h``; a teleport anywhere costs ``log JUMP``.  Each held-out step gets
the place (one of ``n_states`` K-means places on the estimated positions) of its keyframe's cell.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from sklearn.cluster import KMeans

from topomap.core.motion import scans as S
from topomap.evaluation.metres import score_units
from topomap.core.stats import label_means

ROUTES = ("headgraph_kf", "headgraph_kf_teleport", "headgraph_kf_scans")
CELLS = 256
#: a teleport's probability: none (log -690); ``headgraph_kf_teleport`` 1e-4, where a held-out
#: stay of thousands of steps in one of two identical rooms drifts to the room trained on more
#: steps (its cells are denser, its scans fit a few nats a step better)
JUMP = 1e-300
TELEPORT = 1e-4
HEADING_SD_BINS = 0.5
STOP = 3  # forward, turn_left, turn_right, stop: the arena's TurnActions and data=rosbag


def forward_moves(O) -> np.ndarray:
    """(T, 3) each step's move (forward, left, turn) in the frame of the step before."""
    d = np.zeros((len(O), 3))
    dx, dy = np.diff(O[:, 0]), np.diff(O[:, 1])
    c, s = np.cos(O[:-1, 2]), np.sin(O[:-1, 2])
    d[1:, 0] = c * dx + s * dy
    d[1:, 1] = -s * dx + c * dy
    d[1:, 2] = np.angle(np.exp(1j * np.diff(O[:, 2])))
    return d


def reckon(moves, heading) -> np.ndarray:
    """(T, 3) poses: ``moves`` (forward, left) along ``heading`` (T,), from (0, 0)."""
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    dx = c * moves[1:, 0] - s * moves[1:, 1]
    dy = s * moves[1:, 0] + c * moves[1:, 1]
    xy = np.vstack([[0.0, 0.0], np.column_stack([np.cumsum(dx), np.cumsum(dy)])])
    return np.column_stack([xy, heading])


def command_poses(X, u) -> np.ndarray:
    """(T, 3) poses of a log without odometry: one unit forward a step unless the command is
    ``stop`` (``STOP``), headings summed from the scans' turns."""
    Xd = S.despike(X)
    turns = np.r_[0.0, S.scan_turns(Xd[:-1], Xd[1:])]
    moves = np.column_stack([(np.asarray(u) != STOP).astype(float), np.zeros(len(u)), turns])
    return reckon(moves, np.cumsum(turns))


def keyframes(O, delta, max_steps=50) -> np.ndarray:
    """Indices of keyframes: a new one each ``delta`` of travel or ``max_steps`` steps."""
    step = np.r_[0.0, np.hypot(*np.diff(O[:, :2], axis=0).T)]
    ks, acc = [0], 0.0
    for t in range(1, len(O)):
        acc += step[t]
        if acc >= delta or t - ks[-1] >= max_steps:
            ks.append(t)
            acc = 0.0
    return np.array(ks)


def emission(X, M, var) -> np.ndarray:
    """(T, N, B) log N(x_t; M_c turned to heading bin h, var I), by the FFT."""
    T, B = X.shape
    FX, FM = np.fft.rfft(X, axis=1), np.fft.rfft(M, axis=1)
    x2, m2 = (X ** 2).sum(1), (M ** 2).sum(1)
    out = np.empty((T, len(M), B), dtype=np.float32)
    for a in range(0, T, 500):
        b = min(T, a + 500)
        corr = np.fft.irfft(np.conj(FX[a:b, None, :]) * FM[None], n=B, axis=2)
        out[a:b] = -0.5 * (x2[a:b, None, None] + m2[None, :, None] - 2 * corr) / var
    return out


@njit(cache=True)
def _step(delta, cent, nb_ptr, nb_idx, move, sd, logK, jump, new, arg):
    """One keyframe of the Viterbi recursion: ``new`` (N, B) best score, ``arg`` its origin;
    ``move`` (forward, left, turn in heading bins)."""
    f, lft, s0 = move[0], move[1], int(move[2])
    N, B = delta.shape
    W = (logK.size - 1) // 2
    best_all, arg_all = -1e300, 0
    for c in range(N):
        for h in range(B):
            if delta[c, h] > best_all:
                best_all, arg_all = delta[c, h], c * B + h
    new[:, :] = best_all + jump
    arg[:, :] = arg_all
    inv2 = 1.0 / (2 * sd * sd)
    for c in range(N):
        for h in range(B):
            v0 = delta[c, h]
            if v0 < best_all - 200:
                continue
            a = 2 * np.pi * h / B
            px = cent[c, 0] + np.cos(a) * f - np.sin(a) * lft
            py = cent[c, 1] + np.sin(a) * f + np.cos(a) * lft
            tot = -1e300
            for q in range(nb_ptr[c], nb_ptr[c + 1]):
                d2 = (cent[nb_idx[q], 0] - px) ** 2 + (cent[nb_idx[q], 1] - py) ** 2
                lp = -d2 * inv2
                tot = max(tot, lp) + np.log1p(np.exp(-abs(tot - lp)))
            for q in range(nb_ptr[c], nb_ptr[c + 1]):
                c2 = nb_idx[q]
                d2 = (cent[c2, 0] - px) ** 2 + (cent[c2, 1] - py) ** 2
                v1 = v0 - d2 * inv2 - tot
                for j in range(-W, W + 1):
                    h2 = (h + s0 + j) % B
                    v = v1 + logK[j + W]
                    if v > new[c2, h2]:
                        new[c2, h2], arg[c2, h2] = v, c * B + h


@njit(cache=True)
def viterbi(E, moves, cent, nb_ptr, nb_idx, sd, logK, log_init, jump):
    """Best (cell, heading bin) per keyframe: E (K, N, B) emissions; moves (K, 3) into
    keyframe k in the frame of k - 1; cent (N, 2); successors in CSR (nb_ptr, nb_idx)."""
    K, N, B = E.shape
    delta = np.empty((N, B))
    for c in range(N):
        delta[c] = log_init[c] + E[0, c]
    back = np.empty((K, N, B), dtype=np.int32)
    new = np.empty((N, B))
    arg = np.empty((N, B), dtype=np.int32)
    for k in range(1, K):
        move = np.array([moves[k, 0], moves[k, 1], np.floor(moves[k, 2] * B / (2 * np.pi) + 0.5)])
        _step(delta, cent, nb_ptr, nb_idx, move, sd, logK, jump, new, arg)
        delta[:, :] = new + E[k]
        back[k] = arg
        delta -= delta.max()
    pc = np.empty(K, dtype=np.int64)
    ph = np.empty(K, dtype=np.int64)
    i = np.argmax(delta)
    pc[K - 1], ph[K - 1] = i // B, i % B
    for k in range(K - 1, 0, -1):
        a = back[k, pc[k], ph[k]]
        pc[k - 1], ph[k - 1] = a // B, a % B
    return pc, ph


def cells(xy, n, seed):
    """(labels, centres) of ``n`` K-means cells on the squares of a grid a quarter of a cell wide
    that the walk entered, each once: cells as dense where the walk went once as where it went
    often (K-means on the steps makes the rooms visited longer finer, and their scans then fit
    better, a few nats a step: enough to pull a held-out walk into the wrong one of two alike
    rooms)."""
    side = np.sqrt(np.prod(xy.max(0) - xy.min(0)) / n) / 4
    km = KMeans(n, n_init=2, random_state=seed).fit(np.unique(np.round(xy / side), axis=0) * side)
    return km.predict(xy), km.cluster_centers_


def successors(cells_kf, n):
    """CSR of each cell's successors between consecutive keyframes, itself included."""
    A = np.eye(n, dtype=bool)
    A[cells_kf[:-1], cells_kf[1:]] = True
    ptr = np.r_[0, np.cumsum(A.sum(1))]
    return ptr, np.nonzero(A)[1].astype(np.int64)


def _poses(tw, name, X):
    if name != "headgraph_kf_scans":
        O = tw.odometry
        return reckon(forward_moves(O), S.scan_headings(X, O[:, 2]))
    P = command_poses(X, tw.traj.actions)
    return reckon(forward_moves(P), S.scan_headings(X))


def _held_poses(hw, name, X):
    return hw.odometry if name != "headgraph_kf_scans" else command_poses(X, hw.traj.actions)


def route(name, tw, hw, regions, seed, n_clusters, n_states):
    train, held = tw.traj, hw.traj
    X, Xh = S.despike(train.observations), S.despike(held.observations)
    P = _poses(tw, name, train.observations)
    cell, cent = cells(P[:, :2], CELLS, seed)
    M = label_means(cell, S.rotate_scans(X, P[:, 2]), CELLS)
    var = float(((S.rotate_scans(X, P[:, 2]) - M[cell]) ** 2).mean())
    spacing = float(np.median(np.sort(np.linalg.norm(cent[:, None] - cent[None], axis=2), 1)[:, 1]))
    ptr, idx = successors(cell[keyframes(P, spacing / 2)], CELLS)
    places = KMeans(n_states, n_init=2, random_state=seed).fit(P[:, :2]).labels_
    votes = np.zeros((CELLS, n_states))
    np.add.at(votes, (cell, places), 1)
    Oh = _held_poses(hw, name, held.observations)
    kh = keyframes(Oh, spacing / 2)
    k = np.arange(-3, 4)
    logK = -0.5 * (k / HEADING_SD_BINS) ** 2
    logK -= np.log(np.exp(logK).sum())
    prior = np.log(np.bincount(cell, minlength=CELLS) / len(cell))
    pc, _ = viterbi(emission(Xh[kh], M, var), forward_moves(Oh[kh]), cent, ptr, idx,
                    spacing / 2, logK, prior,
                    np.log(TELEPORT if name == "headgraph_kf_teleport" else JUMP))
    held_places = votes.argmax(1)[pc[np.searchsorted(kh, np.arange(len(Xh)), "right") - 1]]
    pair = (regions(train.positions), regions(held.positions))
    return {"states": CELLS, **score_units(places, train.positions, held_places, held.positions,
                                           n_states, pair)}
