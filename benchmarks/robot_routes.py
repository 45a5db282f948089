"""Research routes for robot logs (``bench_robots.py --routes ...``): places from poses, states
place x heading sector, in topomap's model class.

``oracle``      the TRUE poses (position and heading): what the rest of the route can reach
``odo_raw``     the wheel odometry as it drifts (no correction)
``odo_copies``  the wheel odometry corrected by copies of rotation-free view clusters: a step
                joins the nearest copy of its cluster within a gate of its pose, its position is
                pulled towards the copy and its heading turned by the rotation that aligns its
                scan with the copy's (circular cross-correlation)
``fft_views``   K-means on rotation-free views (the magnitudes of each scan's Fourier
                coefficients), 64 clusters, each held-out step at its nearest cluster (not in the
                model class: a yardstick of route (c))

From poses (x, y, heading): each scan is turned into the pose's frame (canonical views); places
are K-means on [canonical views / their spread, positions / their spread]; the states are place
x ``SECTORS`` heading sectors, each observed through its place's mean canonical view turned to
the sector's centre, with the place's pooled variance; transitions ``P(p', s' | p, s, u)`` are
``P(s' - s | u)`` (pooled over places) times ``P(p' | p, s, u)`` (counts pooled with the
neighbouring sectors, backed off to the place graph ``P(p' | p)`` with ``ALPHA`` pseudo-counts).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from sklearn.cluster import KMeans

from topomap.core.map.model import TopologicalMap
from topomap.evaluation.metres import map_scores, score_units

ROUTES = ("oracle", "odo_raw", "odo_copies", "fft_views")
SECTORS = 16
ALPHA = 5.0
POS_WEIGHT = 1.0
DESCRIPTORS = 16  # Fourier magnitudes kept


def rotate(X, angles):
    """Each scan (row, beams evenly round the circle) turned by ``angles`` (rad, anticlockwise):
    ``out[:, j] = X[:, j - angle / beam]`` by circular linear interpolation."""
    T, B = X.shape
    s = np.asarray(angles, dtype=np.float64) * B / (2 * np.pi)
    j = np.arange(B)[None, :] - s[:, None]
    j0 = np.floor(j).astype(np.int64)
    f = j - j0
    r = np.arange(T)[:, None]
    return (1 - f) * X[r, j0 % B] + f * X[r, (j0 + 1) % B]


def descriptors(X, n=DESCRIPTORS):
    return np.abs(np.fft.rfft(X, axis=1))[:, :n] / np.sqrt(X.shape[1])


def sectors(heading, H):
    return np.floor((np.mod(heading, 2 * np.pi) / (2 * np.pi)) * H + 0.5).astype(np.int64) % H


@njit(cache=True)
def _best_turn(scan, ref, max_shift):
    """Sub-beam shift (beams) within +-max_shift that best aligns ``scan`` to ``ref``
    (ref[j] ~ scan[j - shift]), by least squares over integer shifts and a parabola."""
    B = scan.size
    best, arg = 1e300, 0
    costs = np.empty(2 * max_shift + 1)
    for k in range(-max_shift, max_shift + 1):
        c = 0.0
        for j in range(B):
            d = ref[j] - scan[(j - k) % B]
            c += d * d
        costs[k + max_shift] = c
        if c < best:
            best, arg = c, k
    i = arg + max_shift
    if 0 < i < 2 * max_shift:
        a, b, c = costs[i - 1], costs[i], costs[i + 1]
        den = a - 2 * b + c
        if den > 0:
            return arg + 0.5 * (a - c) / den
    return float(arg)


@njit(cache=True)
def _rot(scan, ang):
    B = scan.size
    out = np.empty(B)
    s = ang * B / (2 * np.pi)
    for j in range(B):
        x = j - s
        j0 = int(np.floor(x))
        f = x - j0
        out[j] = (1 - f) * scan[j0 % B] + f * scan[(j0 + 1) % B]
    return out


@njit(cache=True)
def _pose_filter(fsym, X, moves, gate, pull, turn_pull, max_shift, n_sym):
    T, B = X.shape
    M = np.zeros((T, 2))
    C = np.zeros((T, B))
    n = np.zeros(T)
    head = np.full(n_sym, -1)
    nxt = np.full(T, -1)
    n_copies = 0
    x, y, th = 0.0, 0.0, 0.0
    out = np.empty((T, 3))
    for t in range(T):
        f, l, dth = moves[t, 0], moves[t, 1], moves[t, 2]
        x += np.cos(th) * f - np.sin(th) * l
        y += np.sin(th) * f + np.cos(th) * l
        th += dth
        best, bd = -1, gate * gate
        c = head[fsym[t]]
        while c >= 0:
            d = (x - M[c, 0]) ** 2 + (y - M[c, 1]) ** 2
            if d < bd:
                bd, best = d, c
            c = nxt[c]
        if best >= 0:
            canon = _rot(X[t], th)
            shift = _best_turn(canon, C[best] / n[best], max_shift)
            th += turn_pull * shift * 2 * np.pi / B
            x += pull * (M[best, 0] - x)
            y += pull * (M[best, 1] - y)
            canon = _rot(X[t], th)
            n[best] += 1
            w = 1.0 / min(n[best], 50.0)
            M[best, 0] += w * (x - M[best, 0])
            M[best, 1] += w * (y - M[best, 1])
            C[best] += canon  # a sum: the copy's mean canonical scan is C / n
        else:
            best = n_copies
            n_copies += 1
            M[best, 0], M[best, 1] = x, y
            C[best] = _rot(X[t], th)
            n[best] = 1.0
            nxt[best] = head[fsym[t]]
            head[fsym[t]] = best
        out[t, 0], out[t, 1], out[t, 2] = x, y, th
    return out, n_copies


def odometry_moves(O):
    d = np.zeros_like(O)
    dx, dy = np.diff(O[:, 0]), np.diff(O[:, 1])
    c, s = np.cos(O[:-1, 2]), np.sin(O[:-1, 2])
    d[1:, 0] = c * dx + s * dy
    d[1:, 1] = -s * dx + c * dy
    d[1:, 2] = np.angle(np.exp(1j * np.diff(O[:, 2])))
    return d


def corrected_poses(X, O, seed=0, k=32, gate_runs=3.0, pull=0.2, turn_pull=0.5):
    """Poses from the odometry ``O`` corrected by copies of rotation-free view clusters; the gate
    is ``gate_runs`` times the distance driven over a mean run of one cluster, times 10."""
    F = descriptors(X)
    fsym = KMeans(k, n_init=2, random_state=seed).fit(F).labels_.astype(np.int64)
    moves = odometry_moves(O)
    run = len(fsym) / (1 + np.count_nonzero(np.diff(fsym)))
    step = np.median(np.hypot(moves[:, 0], moves[:, 1]))
    gate = gate_runs * 10 * run * step
    P, n_copies = _pose_filter(fsym, np.ascontiguousarray(X), np.ascontiguousarray(moves),
                               gate, pull, turn_pull, X.shape[1] // 6, k)
    return P, {"gate_m": round(float(gate), 3), "copies": int(n_copies)}


def structured_counts(places, sec, u, P, H, A, alpha=ALPHA, scale=1e9):
    a, p0, p1, s0, s1 = u[:-1], places[:-1], places[1:], sec[:-1], sec[1:]
    Ds = np.zeros((A, H))
    np.add.at(Ds, (a, (s1 - s0) % H), 1)
    Ds = (Ds + 0.1) / (Ds + 0.1).sum(1, keepdims=True)
    N = np.zeros((P, H, A, P))
    np.add.at(N, (p0, s0, a, p1), 1)
    Nk = N + 0.5 * (np.roll(N, 1, axis=1) + np.roll(N, -1, axis=1))
    G = N.sum(axis=(1, 2))
    PG = G / np.maximum(G.sum(1, keepdims=True), 1)
    Pp = (Nk + alpha * PG[:, None, None, :]) / (Nk.sum(-1, keepdims=True) + alpha)
    Tm = np.zeros((P, H, A, P, H))
    for d in range(H):
        for s in range(H):
            Tm[:, s, :, :, (s + d) % H] = Pp[:, s] * Ds[None, :, d, None]
    return np.round(Tm.reshape(P * H, A, P * H) * scale).astype(np.int64)


def place_map(X, u, n_actions, pos, heading, n_places, H=SECTORS, seed=0):
    """(map, labels): places x sectors from poses (see the module docstring)."""
    from dataclasses import replace

    Xw = rotate(X, heading)
    vs = np.sqrt(((Xw - Xw.mean(0)) ** 2).sum(1).mean())
    ps = np.sqrt(((pos - pos.mean(0)) ** 2).sum(1).mean())
    places = KMeans(n_places, n_init=3, random_state=seed).fit(
        np.hstack([Xw / vs, POS_WEIGHT * pos / ps])).labels_
    sec = sectors(heading, H)
    lab = places * H + sec
    B, S = X.shape[1], n_places * H
    cnt = np.maximum(np.bincount(places, minlength=n_places), 1)
    C = np.zeros((n_places, B))
    np.add.at(C, places, Xw)
    C /= cnt[:, None]
    means = np.zeros((S, B))
    for s in range(H):
        means[s::H] = rotate(C, np.full(n_places, -2 * np.pi * s / H))
    V = np.zeros(n_places)
    np.add.at(V, places, ((X - means[lab]) ** 2).mean(1))
    cov = np.repeat(V / cnt, H)[:, None] * np.ones((1, B)) + 1e-6
    m = TopologicalMap.from_labels(X, u, lab, state_symbol=np.arange(S), state_gds=np.full(S, -1),
                                   state_parent=np.full(S, -1), n_actions=n_actions,
                                   models=(means, cov))
    m = replace(m, transition_counts=structured_counts(places, sec, u, n_places, H, n_actions))
    return m, lab


def route(name, tw, hw, regions, seed, n_clusters, n_states):
    train, held = tw.traj, hw.traj
    X, u = train.observations, train.actions
    pair = (regions(train.positions), regions(held.positions))
    if name == "fft_views":
        km = KMeans(n_states, n_init=4, random_state=0).fit(descriptors(X))
        return score_units(km.labels_, train.positions, km.predict(descriptors(held.observations)),
                           held.positions, n_states, pair)
    extra = {}
    if name == "oracle":
        pos, heading = train.positions, tw.heading
    elif name == "odo_raw":
        pos, heading = tw.odometry[:, :2], tw.odometry[:, 2]
    elif name == "odo_copies":
        P, extra = corrected_poses(X, tw.odometry, seed=0)
        pos, heading = P[:, :2], P[:, 2]
    else:
        raise ValueError(f"unknown route {name!r}")
    m, lab = place_map(X, u, train.n_actions, pos, heading, n_states)
    return {"states": m.n_states, **extra, **map_scores(m, lab, train, held, regions)}
