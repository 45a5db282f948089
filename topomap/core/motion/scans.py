"""Heading from egocentric range scans: scan-to-scan turns and a heading graph closed by loops.

A ring of ``B`` range beams fixed to the robot (beam ``k`` at ``2 pi k / B`` anticlockwise from
the heading) sees the same walls turned when the robot turns: a turn by ``r`` rad shifts the scan
by ``r B / 2 pi`` beams.  :func:`scan_turns` reads that shift by circular cross-correlation (the
FFT) and refines it below a beam with a parabola; :func:`despike` first takes the circular median
of three beams, as a beam that drops out reads the maximum range (on the robots of
``benchmarks/robot_harness.py``, 1 % dropouts, 18 % of steps were off by over 0.2 rad without it,
0.3-0.9 % with it; then the median error is 0.016-0.022 rad a step, unbiased).

Summed, these turns (or a wheel odometry's) drift: 0.4-0.75 rad a minute on those robots.
:func:`heading_graph` corrects them as one least-squares problem over every step's heading: a
chain of the per-step turns and *loop closures*, pairs of steps far apart in time whose scans look
alike once the rotation is taken out (:func:`loop_closures`: nearest neighbours on the magnitudes
of the scans' Fourier coefficients, which a rotation leaves unchanged), each stating the turn
between them.  Closures are admitted in growing windows of time, each only if it agrees within
``CLOSURE_GATE`` with the headings solved so far, and weighted by a Cauchy loss (iteratively
reweighted, :class:`NormalEquations`).  Measured (``benchmarks/robot_slam.py``): wheel
odometry calibrated against the scans and closed this way is 0.025 rad from the true heading on
1 m alike rooms (0.78 rad before); positions dead-reckoned along it 0.083 m (0.64 m).
"""

from __future__ import annotations

import numpy as np
import qdldl
import scipy.sparse as sp
import scipy.sparse.linalg as spl
from sklearn.neighbors import NearestNeighbors

__all__ = ["despike", "scan_turns", "rotate_scans", "descriptors", "loop_closures",
           "heading_graph", "scan_headings"]

TURN_SD = 0.005        # rad: sd of one step's turn in the chain (wheel odometry: 0.002 median)
CLOSURE_SD = 0.05      # rad: sd of a loop closure's turn (scans seen from nearby places)
CLOSURE_GATE = 0.4     # rad: a closure disagreeing more with the headings so far is left out
CAUCHY_SCALE = 3.0     # residuals in sds where the Cauchy loss halves an edge's weight
WINDOWS = (600, 1200, 2400, 4800, 9600)  # steps: closures admitted up to this gap, in turn
DESCRIPTORS = 16       # Fourier magnitudes describing a scan without its rotation
#: SuperLU's column ordering for the normal equations of graphs of up to :data:`LARGE_GRAPH`
#: steps (symmetric: a chain plus closures): minimum degree on ``N + N.T`` solves the
#: 18,000-step graph of a 30-minute walk in 0.055 s of CPU where SuperLU's default (COLAMD)
#: takes 0.17 s (25 solves a fit); the headings agree within 5e-11 rad
ORDERING = "MMD_AT_PLUS_A"
#: steps: graphs of more steps than this are solved by a sparse LDL^T factor (qdldl, its
#: approximate minimum degree ordering found once a graph and kept through the reweighted
#: passes), whose time grows with the steps where SuperLU's with :data:`ORDERING` grows faster
#: (the heading graph's 25 solves on a 2-hour walk's first steps: 1.4 s at 18,000 steps, 8.0 s
#: at 45,000, 31.7 s at 63,000).  On that walk's 73,000 scans ``scan_poses`` takes 9.6 s
#: against 27.8 s with SuperLU (COLAMD, its factor kept as conjugate gradients' preconditioner),
#: the headings within 2e-9 rad (``benchmarks/notes/robots.md``).  Graphs up to it keep
#: SuperLU's bits and the maps made with them (qdldl is faster there too, ``scan_poses`` on
#: 18,000 scans 1.7 s against 3.2-3.6 s, but its positions differ by up to 0.6 mm, which can
#: move a closure across its gate).
LARGE_GRAPH = 40_000
#: relative residual at which the conjugate gradients of a large graph's later passes stop
#: (:class:`NormalEquations`).  On the 2-hour walk above the heading graph's 25 solves take
#: 2.5 s against 8.1 s with a new factor a pass (qdldl's ``update``, 0.25 s each), 5-12
#: iterations a solve, the headings within 5.7e-9 rad of the direct solves (4.4e-8 at 1e-10)
CG_TOLERANCE = 1e-12
#: most iterations of those conjugate gradients before the factor is brought up to the pass
#: (at most 12 needed on that walk)
CG_ITERATIONS = 50

MIN_GAP = 100          # steps: closures nearer in time are left to the chain; of six walks
                       # two ended 0.67 and 1.06 rad off with 300, 0.013 and 0.099 with 100


class NormalEquations:
    """The normal equations (sparse, symmetric positive definite) of one graph of ``n`` steps,
    solved pass after pass of an iterative reweighting: :meth:`reweight` with each pass's
    matrix, then :meth:`solve` for each right-hand side.  Up to :data:`LARGE_GRAPH` steps each
    pass gets a SuperLU factor (:data:`ORDERING`).  A larger graph gets an LDL^T factor (qdldl)
    on its first pass only; the later passes are solved by conjugate gradients preconditioned
    by it from the pass before's solution (scipy's ``cg``, to a relative residual of
    :data:`CG_TOLERANCE`; the factor brought up to this pass's matrix, qdldl's ``update``, where
    they do not get there in :data:`CG_ITERATIONS`)."""

    def __init__(self, n: int):
        self.large, self.factor, self.fresh, self.N = n > LARGE_GRAPH, None, False, None

    def reweight(self, N) -> None:
        """The matrix ``N`` of this pass (CSC, the pattern of the graph's earlier passes)."""
        self.N, self.fresh = N, not self.large or self.factor is None
        if not self.large:
            self.factor = spl.splu(N, permc_spec=ORDERING)
        elif self.factor is None:
            self.factor = qdldl.Solver(N)

    def solve(self, b, x0=None) -> np.ndarray:
        """``x`` with ``N x = b`` for this pass's ``N``; ``x0``: the pass before's solution,
        where the gradients of a large graph start (None: the factor brought up to the pass).
        The heading graph gives it; the position graph does not: its factor is cheap to bring
        up (its five windows' 50 solves 1 s on the 2-hour walk) and the gradients need 26
        iterations a solve there (3.3 s)."""
        if not self.fresh and x0 is not None:
            M = spl.LinearOperator(self.N.shape, matvec=self.factor.solve, dtype=np.float64)
            x, info = spl.cg(self.N, b, x0=x0, rtol=CG_TOLERANCE, atol=0.0,
                             maxiter=CG_ITERATIONS, M=M)
            if info == 0:
                return x
        if not self.fresh:
            self.factor.update(self.N)
            self.fresh = True
        return self.factor.solve(b)


def despike(X) -> np.ndarray:
    """(T, B) each beam replaced by the median of itself and its two neighbours (circular)."""
    X = np.asarray(X, dtype=np.float64)
    a, c = np.roll(X, 1, 1), np.roll(X, -1, 1)
    # the middle of three values, as ``np.median`` of the three gives it (the same numbers, a
    # tenth of its time: it sorts every triple)
    return np.maximum(np.minimum(a, X), np.minimum(np.maximum(a, X), c))


def scan_turns(A, B) -> np.ndarray:
    """(N,) rad: the anticlockwise turn from each scan of ``A`` (N, beams) to the same row of
    ``B``: ``B[:, j] ~ A[:, j + r beams / 2 pi]``; the shift of the circular cross-correlation's
    peak, refined by a parabola through it and its neighbours."""
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    B = np.atleast_2d(np.asarray(B, dtype=np.float64))
    n = A.shape[1]
    FA = np.fft.rfft(A - A.mean(1, keepdims=True), axis=1)
    FB = np.fft.rfft(B - B.mean(1, keepdims=True), axis=1)
    C = np.fft.irfft(np.conj(FB) * FA, n=n, axis=1)  # C[k] = sum_j B[j] A[j + k]
    k = np.argmax(C, axis=1)
    r = np.arange(len(C))
    a, b, c = C[r, (k - 1) % n], C[r, k], C[r, (k + 1) % n]
    den = a - 2 * b + c
    s = k + np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    s = np.where(s > n / 2, s - n, s)
    return s * 2 * np.pi / n


def rotate_scans(X, angles) -> np.ndarray:
    """(T, B) each scan as seen ``angles`` (rad, anticlockwise) further round: ``out[:, j] =
    X[:, j - angle B / 2 pi]``, linear between beams.  Scans turned by their headings are in
    one frame (what :func:`scan_turns` measures is undone)."""
    X = np.asarray(X, dtype=np.float64)
    T, n = X.shape
    j = np.arange(n)[None, :] - np.asarray(angles, dtype=np.float64)[:, None] * n / (2 * np.pi)
    j0 = np.floor(j).astype(np.int64)
    f = j - j0
    r = np.arange(T)[:, None]
    return (1 - f) * X[r, j0 % n] + f * X[r, (j0 + 1) % n]


def descriptors(X, n: int = DESCRIPTORS) -> np.ndarray:
    """(T, n) the magnitudes of each scan's first ``n`` Fourier coefficients: unchanged by a
    rotation of the scan by whole beams."""
    X = np.asarray(X, dtype=np.float64)
    return np.abs(np.fft.rfft(X, axis=1))[:, :n] / np.sqrt(X.shape[1])


def loop_closures(X, every: int = 3, neighbours: int = 6, min_gap: int = MIN_GAP):
    """Candidate loop closures ``(i, j, turn)``: every ``every``-th scan paired with its
    ``neighbours`` nearest scans by :func:`descriptors` that lie ``min_gap`` steps or more away
    in time, each with the turn from scan ``i`` to scan ``j`` (:func:`scan_turns`)."""
    idx = np.arange(0, len(X), every)
    k = min(neighbours + 1, len(idx))
    _, nb = NearestNeighbors(n_neighbors=k).fit(descriptors(X[idx])).kneighbors(
        descriptors(X[idx]))
    i = np.repeat(idx, k - 1)
    j = idx[nb[:, 1:].ravel()]
    keep = np.abs(i - j) >= min_gap
    i, j = i[keep], j[keep]
    return i, j, scan_turns(X[i], X[j])


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _solve(T, i, j, d, sd, psi, iters: int = 5):
    """Headings minimising the Cauchy loss of ``(psi[j] - psi[i] - d) / sd`` over the edges,
    ``psi[0]`` held; each edge's target wrapped to the nearest turn of the current solution."""
    m = len(i)
    A = sp.csr_matrix((np.r_[-np.ones(m), np.ones(m)], (np.r_[np.arange(m), np.arange(m)],
                                                        np.r_[i, j])), shape=(m, T))
    anchor = sp.csr_matrix(([1.0], ([0], [0])), shape=(T, T))
    normal = NormalEquations(T)
    for _ in range(iters):
        pred = psi[j] - psi[i]
        target = d + 2 * np.pi * np.round((pred - d) / (2 * np.pi))
        w = 1.0 / (1.0 + ((pred - target) / sd / CAUCHY_SCALE) ** 2) / sd ** 2
        N = (A.T @ sp.diags(w) @ A + 1e6 * anchor).tocsc()
        b = A.T @ (w * target)
        b[0] += 1e6 * psi[0]
        normal.reweight(N)
        psi = normal.solve(b, psi)
    return psi


def heading_graph(turns, closures, windows=WINDOWS, turn_sd: float = TURN_SD) -> np.ndarray:
    """(T,) rad: the headings (``[0] = 0``) closest to the per-step ``turns`` (``turns[t]`` from
    step ``t - 1`` to ``t``; ``turns[0]`` unused) and the ``closures`` ``(i, j, turn)``, those
    with a gap of at most each window admitted in turn when within ``CLOSURE_GATE`` of the
    headings solved so far."""
    turns = np.asarray(turns, dtype=np.float64)
    T = len(turns)
    psi = np.r_[0.0, np.cumsum(turns[1:])]
    ci, cj, cr = (np.asarray(c) for c in closures)
    gap = np.abs(cj - ci)
    chain = np.arange(T - 1)
    for w in windows:
        sel = np.flatnonzero(gap <= w)
        sel = sel[np.abs(_wrap(psi[cj[sel]] - psi[ci[sel]] - cr[sel])) < CLOSURE_GATE]
        psi = _solve(T, np.r_[chain, ci[sel]], np.r_[chain + 1, cj[sel]],
                     np.r_[turns[1:], cr[sel]],
                     np.r_[np.full(T - 1, turn_sd), np.full(len(sel), CLOSURE_SD)], psi)
    return psi


def scan_headings(X, odometry_heading=None, windows=WINDOWS, closures=None) -> np.ndarray:
    """(T,) rad: every step's heading from egocentric scans ``X`` (T, B) and, where given, the
    wheel odometry's heading (T,): the odometry's turns calibrated against the scans' (a
    straight-line fit, steps where both agree within 0.1 rad), or the scans' own turns, then
    :func:`heading_graph` with :func:`loop_closures` (``closures``: those of ``X`` found
    already; None: found here)."""
    X = despike(X)
    turns = np.r_[0.0, scan_turns(X[:-1], X[1:])]
    if odometry_heading is not None:
        odo = np.r_[0.0, _wrap(np.diff(np.asarray(odometry_heading, dtype=np.float64)))]
        ok = np.abs(turns - odo) < 0.1
        coef = np.linalg.lstsq(np.column_stack([np.ones(ok.sum()), odo[ok]]), turns[ok],
                               rcond=None)[0]
        turns = np.r_[0.0, coef[0] + coef[1] * odo[1:]]
    return heading_graph(turns, loop_closures(X) if closures is None else closures, windows)
