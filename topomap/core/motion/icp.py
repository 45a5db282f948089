"""Point-to-line ICP of one scan on a keyframe's lines, its nearest points searched exactly.

:func:`icp` pairs each point of a scan with the nearest point of the keyframe that carries a
line (valid, a nonzero normal), if nearer than a pair distance, again at every Gauss-Newton
iteration, while the scan's points move by millimetres.  :func:`_pair_points` searches every
keyframe point where a scan point stands (its anchor) and keeps the :data:`NEAREST_KEPT`
nearest: until the point has moved half the gap between the nearest and the next one after
those from its anchor, the nearest is among those kept (the triangle inequality).  Every
distance is the same float64 arithmetic as a search over every point (index order, a strict
``<``, the first of equally near ones), and a margin (:data:`SAFETY`) far beyond its rounding
keeps a point left out strictly farther: the points paired, and so the registration's bits,
are those of a search over every point.  A cache (:func:`pairing`) serves every registration
of scans with the same number of beams on one keyframe.

Measured (``benchmarks/notes/robots.md``, 2026-12-03; 60 beams, 18,000-step walks): a full
search in 9.6 % of the pairings within one registration (every point's first), against all.
The loss is summed once, after the last iteration (the iterations need only its weights): the
same bits, and :func:`~.registration.scan_odometry` of 18,000 scans in 7.0-8.1 s against
8.8-9.6 s (2026-12-03, idle, ``robot_alike@0.3333`` seed 0, in turn with the version before).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["icp", "pairing", "NEAREST_KEPT", "SAFETY"]

# numba's cache of registration.py's kernels, which call these, is keyed by registration.py's
# own file alone: after an edit here, clear topomap/core/motion/__pycache__/*.nb[ic]

#: keyframe points kept by each scan point for its later pairings (1, 2, 3, 4, 6: a full search
#: in 21, 13, 10.6, 9.5, 8.6 % of 30,000 registrations' pairings; speed alone, never the result)
NEAREST_KEPT = 4
#: the margin of a kept nearest point, as a share of the distances it is weighed on: far beyond
#: float64 rounding (1e-16), so a point the triangle inequality leaves out is strictly farther
#: in the rounded distances too (speed alone, never the result; not tuned)
SAFETY = 1e-6


@njit(cache=True)
def pairing(P, Pv, N, B):
    """The nearest-point cache of keyframe points ``P`` (K, 2) [m] for scans of ``B`` points:
    the indices of those valid (``Pv``) and carrying a line (a nonzero row of ``N``), ascending,
    and their x and y; each scan point's anchor (B, 2) [m], its kept points (B,
    :data:`NEAREST_KEPT`), the squared move [m^2] they are kept for (B,), -1: none yet; and
    room for a search's :data:`NEAREST_KEPT` + 1 nearest distances and indices."""
    keep = np.zeros(P.shape[0], dtype=np.int64)
    n = 0
    for k in range(P.shape[0]):
        if Pv[k] and (N[k, 0] != 0.0 or N[k, 1] != 0.0):
            keep[n] = k
            n += 1
    keep = keep[:n].copy()
    return (keep, P[keep, 0].copy(), P[keep, 1].copy(), np.zeros((B, 2)),
            np.full((B, NEAREST_KEPT), -1, dtype=np.int64), np.full(B, -1.0),
            np.zeros(NEAREST_KEPT + 1), np.zeros(NEAREST_KEPT + 1, dtype=np.int64))


@njit(cache=True, inline="always")
def _search(cache, i, qx, qy):
    """Scan point ``i`` anchored at ``(qx, qy)`` [m]: every point of ``cache`` searched, its
    :data:`NEAREST_KEPT` nearest kept and the squared move they are kept for."""
    keep, xs, ys, anchor, near, safe, td, ta = cache
    K = NEAREST_KEPT
    td[:] = np.inf
    ta[:] = -1
    for a in range(len(keep)):
        d = (xs[a] - qx) ** 2 + (ys[a] - qy) ** 2
        if d < td[K]:
            p = K
            while p > 0 and d < td[p - 1]:
                td[p], ta[p] = td[p - 1], ta[p - 1]
                p -= 1
            td[p], ta[p] = d, a
    for m in range(K):
        near[i, m] = keep[ta[m]] if ta[m] >= 0 else -1
    anchor[i, 0], anchor[i, 1] = qx, qy
    # NaN (fewer points than kept, a point at infinity): never kept, always searched
    gap = 0.5 * (np.sqrt(td[K]) - np.sqrt(td[0])) - SAFETY * np.sqrt(td[K])
    safe[i] = gap * gap if gap > 0.0 else -1.0


@njit(cache=True)
def _pair_points(P, cache, Q, Qv, x, y, th, max_pair, qs, js):
    """Points ``Q`` (B, 2) [m] moved by ``(x, y, th)`` [m, m, rad] into ``qs`` (B, 2) and each valid
    one's nearest point of ``P`` nearer than ``max_pair`` [m] into ``js`` (B,), -1: none
    (the first of equally near ones, as a search over every point in index order finds)."""
    keep, xs, ys, anchor, near, safe, td, ta = cache
    c, s = np.cos(th), np.sin(th)
    for i in range(Q.shape[0]):
        js[i] = -1
        if not Qv[i]:
            continue
        qx = c * Q[i, 0] - s * Q[i, 1] + x
        qy = s * Q[i, 0] + c * Q[i, 1] + y
        qs[i, 0], qs[i, 1] = qx, qy
        if not (qx - anchor[i, 0]) ** 2 + (qy - anchor[i, 1]) ** 2 < safe[i]:   # NaN too
            _search(cache, i, qx, qy)
        best = max_pair * max_pair
        for m in range(NEAREST_KEPT):
            k = near[i, m]
            if k < 0:
                continue
            d = (P[k, 0] - qx) ** 2 + (P[k, 1] - qy) ** 2
            if d < best or (d == best and 0 <= js[i] and k < js[i]):
                best, js[i] = d, k


@njit(cache=True)
def icp(cache, P, N, Q, Qv, x0, iters, cauchy, max_pair):
    """The motion ``(x, y, turn)`` putting points ``Q`` on the lines through ``P`` (normals
    ``N``; ``cache``: :func:`pairing`'s of them), from ``x0``; the number of points paired at
    the end and the cost there: the sum of the Cauchy loss ``log(1 + (r / cauchy)^2)`` over the
    scan's points, an unpaired point costing as one ``max_pair`` from its line."""
    x, y, th = x0[0], x0[1], x0[2]
    B = Q.shape[0]
    used = 0
    qs, js = np.zeros((B, 2)), np.zeros(B, dtype=np.int64)
    H, g = np.zeros((3, 3)), np.zeros(3)
    for it in range(iters + 1):
        c, s = np.cos(th), np.sin(th)
        H[:] = 0.0
        g[:] = 0.0
        used = 0
        _pair_points(P, cache, Q, Qv, x, y, th, max_pair, qs, js)
        for i in range(B):
            j = js[i]
            if not Qv[i] or j < 0:
                continue
            nx, ny = N[j, 0], N[j, 1]
            r = nx * (qs[i, 0] - P[j, 0]) + ny * (qs[i, 1] - P[j, 1])
            w = 1.0 / (1.0 + (r / cauchy) ** 2)
            # d(qx, qy)/d th = (-s qx0 - c qy0, c qx0 - s qy0)
            dth = nx * (-s * Q[i, 0] - c * Q[i, 1]) + ny * (c * Q[i, 0] - s * Q[i, 1])
            J0, J1, J2 = nx, ny, dth
            H[0, 0] += w * J0 * J0
            H[0, 1] += w * J0 * J1
            H[0, 2] += w * J0 * J2
            H[1, 1] += w * J1 * J1
            H[1, 2] += w * J1 * J2
            H[2, 2] += w * J2 * J2
            g[0] += w * J0 * r
            g[1] += w * J1 * r
            g[2] += w * J2 * r
            used += 1
        if used < 3 or it == iters:
            break
        H[1, 0], H[2, 0], H[2, 1] = H[0, 1], H[0, 2], H[1, 2]
        for d in range(3):
            H[d, d] += 1e-9
        step = np.linalg.solve(H, -g)
        x, y, th = x + step[0], y + step[1], th + step[2]
    return np.array([x, y, th]), used, _cost(P, N, Q, Qv, qs, js, cauchy, max_pair)


@njit(cache=True, inline="always")
def _cost(P, N, Q, Qv, qs, js, cauchy, max_pair):
    """The cost of :func:`icp`'s last pairing (``qs``, ``js`` of :func:`_pair_points`): the sum of
    the Cauchy loss over the scan's valid points, an unpaired one costing as one ``max_pair``
    from its line (asked once, after the last iteration: the iterations need only the weights)."""
    unpaired = np.log(1.0 + (max_pair / cauchy) ** 2)
    cost = 0.0
    for i in range(Q.shape[0]):
        if not Qv[i]:
            continue
        j = js[i]
        if j < 0:
            cost += unpaired
            continue
        r = N[j, 0] * (qs[i, 0] - P[j, 0]) + N[j, 1] * (qs[i, 1] - P[j, 1])
        cost += np.log(1.0 + (r / cauchy) ** 2)
    return cost
