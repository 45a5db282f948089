"""Point-to-line ICP of one egocentric scan on another's lines, its nearest points searched exactly.

A ring of ``B`` range beams fixed to the robot (beam ``k`` at ``2 pi k / B`` anticlockwise from
the heading) is a set of points in the robot's frame (:func:`scan_points`; a beam at the range's
maximum, no return, carries no point).  :func:`register` finds the rigid motion ``(x, y,
turn)`` that puts one scan's points on the lines through a keyframe's neighbouring points
(:func:`keyframe_lines`): Gauss-Newton on the three parameters, each pair weighted by a Cauchy
loss, from one or more starts.  :mod:`~.registration` chains such registrations into odometry.

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

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

__all__ = ["icp", "pairing", "scan_points", "keyframe_lines", "register", "register_each",
           "NEAREST_KEPT", "SAFETY", "ICP_ITERATIONS", "CAUCHY_M", "MAX_PAIR_M", "NORMAL_HALF",
           "NORMAL_GAP_M"]

# numba's cache of registration.py's kernels, which call these, is keyed by registration.py's
# own file alone: after an edit here, clear topomap/core/motion/__pycache__/*.nb[ic]

#: keyframe points kept by each scan point for its later pairings (1, 2, 3, 4, 6: a full search
#: in 21, 13, 10.6, 9.5, 8.6 % of 30,000 registrations' pairings; speed alone, never the result)
NEAREST_KEPT = 4
#: the margin of a kept nearest point, as a share of the distances it is weighed on: far beyond
#: float64 rounding (1e-16), so a point the triangle inequality leaves out is strictly farther
#: in the rounded distances too (speed alone, never the result; not tuned)
SAFETY = 1e-6
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
#: beams either side whose points fit the line through a keyframe point (1, 2, 3: 6.5, 6.9,
#: 8.5 mm and 0.009, 0.010, 0.011 rad from the true motion)
NORMAL_HALF = 1
#: m: neighbours farther than this from the point are not on its line (not tuned)
NORMAL_GAP_M = 0.25

# LAPACK's dgesv as numba's np.linalg.solve calls it (scipy's cython_lapack), called by name
# from compiled code without numba's copies and checks around it: the same bits, 0.25 against
# 0.5 us a 3 x 3 solve, and 10 Gauss-Newton solves of 12 iterations a scan
llvm.add_symbol("topomap_dgesv", get_cython_function_address("scipy.linalg.cython_lapack",
                                                              "dgesv"))
_INT, _FLOAT = types.CPointer(types.int32), types.CPointer(types.float64)
_dgesv = types.ExternalFunction("topomap_dgesv", types.void(_INT, _INT, _FLOAT, _INT, _INT,
                                                            _FLOAT, _INT, _INT))


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
    lu, step = np.zeros((3, 3)), np.zeros(3)
    ints = np.array([3, 1, 3, 3, 0, 0, 0, 0], dtype=np.int32)
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
        step[0], step[1], step[2] = -g[0], -g[1], -g[2]
        _solve3(H, step, lu, ints)
        x, y, th = x + step[0], y + step[1], th + step[2]
    return np.array([x, y, th]), used, _cost(P, N, Q, Qv, qs, js, cauchy, max_pair)


@njit(cache=True, inline="always")
def _solve3(H, b, lu, ints):
    """``x`` with ``H x = b`` for a symmetric ``H`` (3, 3) (so its own column-major layout), by
    LAPACK's dgesv as ``np.linalg.solve`` calls it, the same errors raised; ``b`` becomes
    ``x``.  ``lu`` (3, 3): room for the factor; ``ints``: int32 ``[3, 1, 3, 3, info, pivots]``."""
    for i in range(3):
        for j in range(3):
            lu[i, j] = H[i, j]
            if not (np.isfinite(H[i, j]) and np.isfinite(b[i])):
                raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
    _dgesv(ints[0:].ctypes, ints[1:].ctypes, lu.ctypes, ints[2:].ctypes, ints[5:].ctypes,
           b.ctypes, ints[3:].ctypes, ints[4:].ctypes)
    if ints[4] > 0:
        raise np.linalg.LinAlgError("Matrix is singular to machine precision.")
    return b


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


@njit(cache=True)
def keyframe_lines(P, valid):
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
