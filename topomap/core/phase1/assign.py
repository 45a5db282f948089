"""Every row's nearest K-means centre -- the labels ``KMeans.predict`` gives -- with most
distances never computed.

scikit-learn's ``predict`` computes every row's distance to every centre (a matrix product,
``T x ns x D`` multiply-adds: 1.5e10 at T = 10^7, ns = 100, D = 15).  :func:`nearest_centres`
finds the same labels by search.  A row starts from a guess, the centre nearest the middle of
its cell in a grid over the centres' three directions of largest spread; the triangle
inequality then rules out every centre farther from the guess than twice the row's distance
from it, and the centres left (the guess's neighbours, nearest first) are visited with each
distance summed feature by feature and abandoned once it exceeds the best so far.  A row whose
nearest and second-nearest centres are so close that the rounding of scikit-learn's own
arithmetic could order them either way (within :func:`margin`) is handed to ``km.predict``
itself, so every label is the one ``predict`` gives -- exact ties included (the first centre).

Where the search would not pay, ``predict`` labels the rows: below :data:`SEARCH_ROWS` rows (the
grid's set-up costs as much as the search saves), above :data:`SEARCH_CENTRES` centres (the
neighbour tables grow with their square), and where the first :data:`PROBE_ROWS` rows
visit more than :data:`VISIT_SHARE` of the centres each (clusters on top of one another).

Measured (``benchmarks/notes/scale.md``, "The nearest centre by search"): 10^7 rows of the
benchmark walk (15 features, 100 centres) in 0.5-0.7 s where ``predict`` took 1.6-1.7 s (two
cores, load 2-2.5; phase 1 1.19 s against 1.87 s idle), 1.4 other centres visited a row; a continuous log's views (12 beams, 32-300
centres) 0.9-11 others a row, about ``predict``'s time; the same labels on every test.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.spatial.distance import cdist

from ..split.threads import in_threads, pieces

__all__ = ["nearest_centres", "predict_chunked", "margin", "ROUNDING_FACTOR", "ROWS",
           "PREDICT_ROWS", "SEARCH_ROWS", "SEARCH_CENTRES", "PROBE_ROWS", "VISIT_SHARE",
           "GRID_AXES", "GRID_CELLS"]

#: how many times ``(D + 1) * eps * (|x|^2 + max |c|^2)`` two squared distances must differ by
#: for their order to be sure: a dot product of ``D`` terms is off by at most ``D * eps`` times
#: the sum of the absolute products (and ``predict`` computes ``|c|^2 - 2 x.c`` in the data's
#: precision), so two distances computed as ``predict`` does are each off by at most
#: ``2 (D + 1) eps s``, their difference by twice that: 4 bounds it, 8 leaves room for this
#: module's own float64 rounding
ROUNDING_FACTOR = 8.0
#: rows a compiled call labels (the calls spread over threads; the same labels whatever the
#: number of threads): 2^20 rows, 15 MB of 15 float64 features
ROWS = 1 << 20
#: rows ``predict`` labels at once: a multiple of scikit-learn's own blocks of 256 rows, so that
#: every row's label is the one a single ``predict`` over all rows gives, without its (T,)
#: temporaries (12 MB a block); each call costs scikit-learn's thread-pool set-up (about 30 ms
#: under load): 65,536-row blocks doubled phase 1 at T = 10^7, 2^20-row blocks add 10 calls
PREDICT_ROWS = 256 * 4096
#: rows from which the search is tried: at 10^5 rows of a continuous log's views the grid's
#: set-up (32^3 cells x the centres) took as long as the search saved (0.012-0.070 s against
#: ``predict``'s 0.015-0.061 s for 32-300 centres)
SEARCH_ROWS = 1 << 19
#: the most centres searched: every centre keeps its neighbours' order and distances, k - 1 of
#: each (k^2 x 16 bytes: 16 MB at 1,024 centres; at 5,000, 400 MB)
SEARCH_CENTRES = 1024
#: rows searched first, alone, to count the centres a row visits
PROBE_ROWS = 1 << 16
#: the share of the centres a probed row may visit on average for the search to go on: a
#: visited centre costs a scalar distance where ``predict`` computes all of them in a matrix
#: product several times as fast a distance (the benchmark walk: 0.014 of 100 centres, 3x
#: faster than ``predict``; views of two rooms, 32-300 centres: 0.036-0.070, about its time;
#: rows scattered round one point, 40 features, 30 centres: 0.97, 4x slower)
VISIT_SHARE = 0.125
#: directions of the grid that gives a row its first centre, and its cells along each: 32^3
#: cells start 97 % of the rows of the 10^7-step benchmark walk (100 centres, 15 features) at
#: their nearest centre (64^3: 98 %; 64^2 on two directions: 88 %), 77-94 % of a continuous
#: log's views (``two_rooms``, ``open``)
GRID_AXES = 3
GRID_CELLS = 32
#: relative slack of this module's float64 distances in the triangle inequality (a sum of 15
#: terms is off by under 1e-14)
SLACK = 1e-12


def predict_chunked(km, Z: np.ndarray) -> np.ndarray:
    """``km.predict(Z)`` as int64, :data:`PREDICT_ROWS` rows at a time."""
    out = np.empty(Z.shape[0], dtype=np.int64)
    for a in range(0, Z.shape[0], PREDICT_ROWS):
        out[a:a + PREDICT_ROWS] = km.predict(Z[a:a + PREDICT_ROWS])
    return out


def margin(dtype, n_features: int) -> float:
    """The relative margin two squared distances must differ by (times ``|x|^2 + max |c|^2``)
    for the order ``predict`` computes in ``dtype`` to be sure."""
    return ROUNDING_FACTOR * (n_features + 1) * float(np.finfo(dtype).eps)


@njit(cache=True, nogil=True)
def _grid_start(Z, t, grid, w0, w1, w2):
    """``(|x|^2, first centre)`` of row ``t``: its square norm and its (up to) three projections
    on ``w0``, ``w1``, ``w2`` in one pass over the features, the projections' grid cell's
    centre (``grid`` as :func:`_search`'s)."""
    _, low, scale, cells, G = grid
    xx = p0 = p1 = p2 = 0.0
    for d in range(Z.shape[1]):
        v = np.float64(Z[t, d])
        xx += v * v
        p0 += v * w0[d]
        p1 += v * w1[d]
        p2 += v * w2[d]
    cell = 0
    for e in range(grid[0].shape[0]):
        s = p0 if e == 0 else (p1 if e == 1 else p2)
        i = np.int64(np.floor((s - low[e]) * scale[e]))
        cell = cell * G + min(max(i, 0), G - 1)
    return xx, cells[cell]


@njit(cache=True, nogil=True)
def _search(Z, lo, hi, C, neighbours, grid, rel, labels, unsure):
    """Label rows ``lo:hi`` of ``Z`` by the centres ``C`` (k, D): a row starts from its grid
    cell's centre (``grid`` = ``(W, low, scale, cells, G)``: its projection on ``W`` (q, D), less
    ``low``, times ``scale``, indexes ``cells``, ``G`` a side), then visits that centre's
    neighbours (``neighbours`` = ``(near, gap)``: their indices and distances, nearest first)
    until the triangle inequality rules out the rest.  ``labels`` gets the nearest centre,
    ``unsure`` 1 where the two nearest are within the margin ``rel`` (:func:`margin`).  Returns
    how many centres beyond the first the rows visited."""
    near, gap = neighbours
    W = grid[0]
    cmax2 = 0.0
    for j in range(C.shape[0]):
        cmax2 = max(cmax2, np.sum(C[j] * C[j]))
    k, D = C.shape
    q = W.shape[0]
    w0, w1, w2 = W[0], W[min(1, q - 1)], W[min(2, q - 1)]
    visits = 0
    for t in range(lo, hi):
        xx, arg = _grid_start(Z, t, grid, w0, w1, w2)
        best = 0.0
        for d in range(D):
            diff = np.float64(Z[t, d]) - C[arg, d]
            best += diff * diff
        tol = rel * (xx + cmax2)
        start = arg
        # |x - c_j| >= |c - c_j| - r: c_j is farther than the start by more than the margin
        # once |c - c_j| (|c - c_j| - 2 r) exceeds it (shrunk by SLACK for the rounding)
        r = np.sqrt(best) * (1.0 + SLACK)
        second = np.inf
        for m in range(k - 1):
            g = gap[start, m] * (1.0 - SLACK)
            if g * (g - 2.0 * r) > tol:
                break
            j = near[start, m]
            visits += 1
            bound = best + tol
            s = 0.0
            for d in range(D):
                diff = np.float64(Z[t, d]) - C[j, d]
                s += diff * diff
                if s > bound:
                    break
            if s > bound:
                continue
            if s < best:
                second = best
                best = s
                arg = j
            elif s < second:
                second = s
        labels[t] = arg
        unsure[t] = 1 if second - best <= tol else 0
    return visits


@njit(cache=True)
def _cell_starts(P, low, width, G):
    """For each of the ``G ** q`` cells of the grid from ``low`` in steps of ``width`` (cell
    index ``i_0 G^(q-1) + ... + i_(q-1)``), the centre whose projection ``P`` (k, q) lies
    nearest the cell's middle (ties: the first)."""
    k, q = P.shape
    out = np.empty(G ** q, dtype=np.int64)
    middle = np.empty(q)
    for c in range(G ** q):
        rest = c
        for e in range(q - 1, -1, -1):
            middle[e] = low[e] + (rest % G + 0.5) * width[e]
            rest //= G
        best, arg = np.inf, 0
        for j in range(k):
            s = 0.0
            for e in range(q):
                g = middle[e] - P[j, e]
                s += g * g
            if s < best:
                best, arg = s, j
        out[c] = arg
    return out


def nearest_centres(km, Z: np.ndarray, *, search_rows: int = SEARCH_ROWS,
                    probe_rows: int = PROBE_ROWS) -> np.ndarray:
    """``km.predict(Z)`` (a fitted scikit-learn ``KMeans``) as int64, found by pruned search
    (``predict`` itself where the search would not pay, and for the rows whose two nearest
    centres are within :func:`margin`).  ``Z``: finite rows of ``km``'s features, float32 or
    float64, C order; ``search_rows`` and ``probe_rows``: :data:`SEARCH_ROWS` and
    :data:`PROBE_ROWS`."""
    T, D = Z.shape
    k = km.cluster_centers_.shape[0]
    if T < search_rows or not 2 <= k <= SEARCH_CENTRES:
        return predict_chunked(km, Z)
    centres = np.asarray(km.cluster_centers_, dtype=Z.dtype).astype(np.float64)
    # every centre's neighbours, nearest first
    between = cdist(centres, centres)
    order = np.argsort(between, axis=1, kind="stable")[:, 1:]
    near = np.ascontiguousarray(order)
    gap = np.ascontiguousarray(np.take_along_axis(between, order, axis=1))
    # a grid over the centres' directions of largest spread; a cell starts from the centre
    # nearest its middle there
    q = min(GRID_AXES, D, k - 1)
    W = np.ascontiguousarray(np.linalg.svd(centres - centres.mean(axis=0),
                                           full_matrices=False)[2][:q])
    P = np.ascontiguousarray(centres @ W.T)
    low, span = P.min(axis=0), np.ptp(P, axis=0)
    scale = np.where(span > 0, GRID_CELLS / np.where(span > 0, span, 1.0), 0.0)
    cells = _cell_starts(P, low, span / GRID_CELLS, GRID_CELLS)
    rel = margin(Z.dtype, D)
    labels = np.empty(T, dtype=np.int64)
    unsure = np.zeros(T, dtype=np.uint8)

    def search(lo, hi):
        return _search(Z, lo, hi, centres, (near, gap), (W, low, scale, cells, GRID_CELLS), rel,
                       labels, unsure)

    probe = min(probe_rows, T)
    if search(0, probe) > VISIT_SHARE * k * probe:
        labels[probe:] = predict_chunked(km, Z[probe:])
    else:
        in_threads(lambda p: search(probe + p.start, probe + p.stop), pieces(T - probe, ROWS),
                   steps=T)
    rows = np.flatnonzero(unsure)
    if rows.size:
        labels[rows] = km.predict(Z[rows])
    return labels
