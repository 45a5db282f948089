"""SQUAREM's cycles (``refine.accelerate=squarem``): the fixed point of plain EM in fewer
E-steps, and plain EM again wherever a jump would lower the likelihood."""

import numpy as np
import pytest
from sklearn.metrics import adjusted_rand_score

from topomap.core.refine.accelerate import squarem
from topomap.core.refine.clones import baum_welch, decode, make_layout, random_counts

#: a ring of 8 places showing 3 symbols: the four even places look alike, as do three odd ones;
#: only the distance to place 7 tells them apart
RING = np.array([0, 1, 0, 1, 0, 1, 0, 2])
CLONES = [4, 3, 1]  # one clone per place


def slipping_ring_walk(T, seed, slip=0.2):
    """Random walk on ``RING`` (action 0: forward, 1: back) whose moves fail with probability
    ``slip``: transitions are stochastic, so EM's tail is slow.  Returns symbols, actions,
    places."""
    rng = np.random.default_rng(seed)
    u = rng.integers(0, 2, T)
    step = np.where(rng.random(T) >= slip, np.where(u == 0, 1, -1), 0)
    places = np.concatenate([[0], np.cumsum(step[:-1])]) % RING.size
    return RING[places], u, places


@pytest.mark.parametrize("seed", range(3))
def test_squarem_reaches_the_fixed_point_of_plain_em_in_fewer_e_steps(seed):
    """From the same random counts both find every place (the clones decode to the ring's
    places); the counts agree to 1e-6 of their size, and SQUAREM needs fewer E-steps."""
    sym, u, places = slipping_ring_walk(3000, seed)
    lay = make_layout(sym, u, [3000], CLONES, 2)
    init = random_counts(lay, np.random.default_rng(seed))
    fits = {}
    for accelerate in ("none", "squarem"):
        counts, _, history = baum_welch(lay, init, 1e-3, False, max_iter=5000, tol=1e-9,
                                        accelerate=accelerate)
        path, _ = decode(lay, counts, 1e-3, False)
        assert adjusted_rand_score(places, path) == 1.0
        fits[accelerate] = counts, path, len(history)
    (plain, plain_path, plain_steps), (fast, fast_path, fast_steps) = fits.values()
    np.testing.assert_array_equal(fast_path, plain_path)
    np.testing.assert_allclose(fast, plain, rtol=0, atol=1e-6 * plain.max())
    assert fast_steps < plain_steps


def test_a_jump_that_lowers_the_likelihood_falls_back_to_plain_em():
    """A map halving its counts, whose log-likelihood peaks at 1.2: every jump lands on the
    fixed point 0 (exact for a linear map), where the likelihood (-1.44) is below that of the
    plain path's last point, so every jump is refused and the cycles end on the plain path,
    ``4 / 2^k``; they stop at the first plain step that loses likelihood."""
    def em_step(c):
        return c / 2, None, -float((c[0] - 1.2) ** 2)

    counts, _, history, state = squarem(em_step, np.array([4.0]), max_iter=100, tol=0.0,
                                        min_iter=0)
    assert state.jumps == 0 and state.refused >= 1
    k = np.log2(4.0 / counts[0])
    assert counts[0] > 0 and k == round(k)
    # E-steps on c = 4, 2 (plain), 0 (the jump from 4, 2, 1: refused), 1 (plain: 2 -> 1 gained),
    # 0 (the jump from 2, 1, 0.5: refused), 0.5 (plain: 1 -> 0.5 lost likelihood, stop)
    assert history == pytest.approx([-7.84, -0.64, -1.44, -0.04, -1.44, -0.49])
    assert counts[0] == 0.25


@pytest.mark.parametrize("rtol, steps", [(0.2, 2), (0.1, 4)])
def test_squarem_stops_by_a_relative_gain(rtol, steps):
    """``rtol``: a cycle's plain step that gains at most that share of the log-likelihood it
    started from ends the cycles.  A map halving its counts, log-likelihood ``-c - 10``: from
    4, the plain step 2 -> 1 gains 2 of 14 (a share of 0.143: the end at 0.2, not at 0.1);
    then the jump lands on the fixed point 0 (-10, kept) and the plain step from there gains
    nothing."""
    def em_step(c):
        return c / 2, None, -float(c[0]) - 10.0

    counts, _, history, _ = squarem(em_step, np.array([4.0]), max_iter=100, tol=np.inf,
                                    min_iter=0, rtol=rtol)
    assert history == [-14.0, -12.0, -10.0, -10.0][:steps]
    assert counts[0] == (1.0 if steps == 2 else 0.0)
