"""Heading from egocentric scans: turns read from scans, and loop closures that remove drift."""

from types import SimpleNamespace

import numpy as np
import pytest

from topomap.core.motion import scans as S


def _room_scan(n=60, seed=0):
    """(n,) ranges of a smooth, asymmetric ring (a few Fourier terms)."""
    rng = np.random.default_rng(seed)
    a = 2 * np.pi * np.arange(n) / n
    return 1.5 + sum(rng.uniform(0.1, 0.3) * np.cos(k * a + rng.uniform(0, 2 * np.pi))
                     for k in (1, 2, 3))


@pytest.mark.parametrize("k", [-7, -1, 0, 3, 12])
def test_a_scan_turned_by_whole_beams_gives_that_turn_exactly(k):
    A = _room_scan()[None, :]
    B = np.roll(A, -k, axis=1)  # B[j] = A[j + k]: the robot turned k beams anticlockwise
    assert S.scan_turns(A, B)[0] == pytest.approx(2 * np.pi * k / 60, abs=1e-12)
    # turning the scans by their headings undoes the turn
    np.testing.assert_allclose(S.rotate_scans(B, [2 * np.pi * k / 60]), A, atol=1e-12)


def test_a_fractional_turn_is_read_below_a_beam():
    A = _room_scan()[None, :]
    B = S.rotate_scans(A, [-0.25 * 2 * np.pi / 60])  # a quarter beam anticlockwise
    assert S.scan_turns(A, B)[0] == pytest.approx(0.25 * 2 * np.pi / 60, abs=0.3 * 2 * np.pi / 60)


def test_despike_removes_a_dropout_beam():
    x = _room_scan()
    y = x.copy()
    y[17] = 3.5  # a beam that saw nothing reads the maximum range
    # the median of (x[16], 3.5, x[18]) is the larger neighbour, and 3.5 touches no other beam's
    # median but its neighbours', each by less than the ring's change over two beams
    d = S.despike(y[None])[0]
    assert d[17] == max(x[16], x[18])
    assert np.abs(d - S.despike(x[None])[0]).max() <= np.abs(x - np.roll(x, 2)).max()



def test_despike_is_the_median_of_each_beam_and_its_two_neighbours():
    rng = np.random.default_rng(3)
    X = rng.integers(0, 4, size=(50, 7)).astype(float)  # many ties among the three
    X[rng.random(X.shape) < 0.2] = 9.0
    triples = np.stack([np.roll(X, 1, 1), X, np.roll(X, -1, 1)])
    assert np.array_equal(S.despike(X), np.median(triples, axis=0))
    assert np.array_equal(S.despike(X), np.sort(triples, axis=0)[1])

def test_loop_closures_pair_a_scan_with_its_turned_copy():
    rng = np.random.default_rng(1)
    X = np.array([_room_scan(seed=s) for s in range(600)]) + rng.normal(0, 1e-3, (600, 60))
    X[500] = np.roll(X[0], -5)
    i, j, turn = S.loop_closures(X, every=1, neighbours=1, min_gap=300)
    hit = (i == 0) & (j == 500)
    assert hit.sum() == 1
    assert turn[hit][0] == pytest.approx(2 * np.pi * 5 / 60, abs=1e-12)


def test_one_closure_spreads_a_loops_drift_as_least_squares_says():
    # the robot stands still (true heading 0) but every step reads a turn b; a closure says
    # step n is at step 0's heading.  Least squares: every step's turn is b / (1 + n s^2 / c^2).
    n, b = 99, 1e-5
    turns = np.r_[0.0, np.full(n, b)]
    psi = S.heading_graph(turns, (np.array([0]), np.array([n]), np.array([0.0])), windows=(n,))
    shrink = 1 + n * S.TURN_SD ** 2 / S.CLOSURE_SD ** 2
    np.testing.assert_allclose(psi, np.arange(n + 1) * b / shrink, rtol=1e-3, atol=1e-12)


@pytest.mark.parametrize("large", [False, True])
def test_a_large_graph_is_solved_by_its_own_factor_to_the_same_headings(monkeypatch, large):
    # the drift spread by one closure (the case above, solved by hand) is the same whichever
    # factor solves it: SuperLU's up to LARGE_GRAPH steps, qdldl's LDL^T above
    n, b = 99, 1e-5
    monkeypatch.setattr(S, "LARGE_GRAPH", n if large else n + 1)
    used, lu, ldl = [], S.spl.splu, S.qdldl.Solver
    monkeypatch.setattr(S.spl, "splu", lambda N, permc_spec: used.append(permc_spec) or
                        lu(N, permc_spec=permc_spec))
    monkeypatch.setattr(S.qdldl, "Solver", lambda N: used.append("LDL") or ldl(N))
    turns = np.r_[0.0, np.full(n, b)]
    psi = S.heading_graph(turns, (np.array([0]), np.array([n]), np.array([0.0])), windows=(n,))
    shrink = 1 + n * S.TURN_SD ** 2 / S.CLOSURE_SD ** 2
    np.testing.assert_allclose(psi, np.arange(n + 1) * b / shrink, rtol=1e-3, atol=1e-12)
    # one LDL^T factor for the window's five passes; a SuperLU factor a pass
    assert used == (["LDL"] if large else [S.ORDERING] * 5)


def _ring_graph(n, seed):
    """Normal equations of a chain of ``n`` steps with random weights and closures, the first
    step anchored (as :func:`~topomap.core.motion.scans.heading_graph` builds them)."""
    rng = np.random.default_rng(seed)
    i = np.r_[np.arange(n - 1), rng.integers(0, n // 2, 40)]
    j = np.r_[np.arange(1, n), rng.integers(n // 2, n, 40)]
    m = len(i)
    A = S.sp.csr_matrix((np.r_[-np.ones(m), np.ones(m)], (np.r_[np.arange(m), np.arange(m)],
                                                          np.r_[i, j])), shape=(m, n))
    anchor = S.sp.csr_matrix(([1e6], ([0], [0])), shape=(n, n))
    return lambda w: (A.T @ S.sp.diags(w) @ A + anchor).tocsc(), A, m, rng


def test_a_large_graph_reweighted_is_solved_by_its_factor_updated():
    # a large graph's later passes update the first pass's LDL^T factor (its ordering kept) to
    # the new weights: the direct solution of the reweighted equations, not of the first ones
    normal, A, m, rng = _ring_graph(500, 4)
    w0 = rng.uniform(1, 100, m)
    w1 = w0 * rng.uniform(0.5, 2, m)   # reweighted, as a Cauchy loss does between passes
    b = A.T @ (w1 * rng.normal(size=m))
    equations = S.NormalEquations(S.LARGE_GRAPH + 1)
    equations.reweight(normal(w0))
    before = equations.factor
    equations.reweight(normal(w1))
    x = equations.solve(b)
    assert equations.factor is before
    np.testing.assert_allclose(x, S.spl.spsolve(normal(w1), b), rtol=0, atol=1e-9)
    assert np.abs(x - S.spl.spsolve(normal(w0), b)).max() > 1e-3


def test_a_large_graph_reweighted_from_the_pass_before_is_solved_by_preconditioned_gradients(
        monkeypatch):
    # given the pass before's solution, a later pass is solved by conjugate gradients
    # preconditioned by the first pass's factor, which stays as it was: the reweighted
    # equations' solution to their tolerance; gradients that do not get there in
    # CG_ITERATIONS give way to the factor brought up to the pass (the direct solution)
    normal, A, m, rng = _ring_graph(500, 4)
    w0 = rng.uniform(1, 100, m)
    w1 = w0 * rng.uniform(0.5, 2, m)
    b = A.T @ (w1 * rng.normal(size=m))
    want = S.spl.spsolve(normal(w1), b)
    for most, updated in ((S.CG_ITERATIONS, False), (1, True)):
        monkeypatch.setattr(S, "CG_ITERATIONS", most)
        equations = S.NormalEquations(S.LARGE_GRAPH + 1)
        equations.reweight(normal(w0))
        start = equations.solve(A.T @ (w0 * rng.normal(size=m)))
        calls, factor = [], equations.factor
        equations.factor = SimpleNamespace(solve=factor.solve,
                                           update=lambda N: calls.append(1) or factor.update(N))
        equations.reweight(normal(w1))
        x = equations.solve(b, start)
        assert bool(calls) is updated
        np.testing.assert_allclose(x, want, rtol=0, atol=1e-9 * np.abs(want).max())


def test_closures_remove_a_gyro_bias_from_a_wandering_walk():
    rng = np.random.default_rng(2)
    T = 3000
    true = np.cumsum(np.r_[0.0, rng.normal(0, 0.1, T - 1)])
    turns = np.r_[0.0, np.diff(true) + 0.001]  # 0.001 rad a step of bias: 3 rad over the walk
    i = np.arange(0, T - 300, 10)
    j = i + 300
    psi = S.heading_graph(turns, (i, j, np.diff(true[np.c_[i, j]], axis=1)[:, 0]))
    drift = np.abs(np.r_[0.0, np.cumsum(turns[1:])] - true).max()
    assert drift == pytest.approx(0.001 * (T - 1))
    assert np.abs(psi - true).max() < 0.1 * drift


def test_scan_headings_given_the_closures_found_already_solve_the_same():
    # closures found once and passed in (as ``registration.scan_poses`` does) give the headings
    # the search inside finds: the same closures of the despiked scans, the same graph
    rng = np.random.default_rng(3)
    X = np.array([np.roll(_room_scan(seed=s % 40), s % 7) for s in range(400)])
    X += rng.normal(0, 1e-3, X.shape)
    odo = np.cumsum(rng.normal(0, 0.05, 400))
    closures = S.loop_closures(S.despike(X))
    np.testing.assert_array_equal(S.scan_headings(X, odo, closures=closures),
                                  S.scan_headings(X, odo))
