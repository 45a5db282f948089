"""The share of steps whose symbol phase 1 may misread (``symbol_ambiguity``) and the gate it
sets on :class:`EMRefinement`'s rough first stage (``first="auto"``)."""

import numpy as np
import pytest
from scipy.stats import norm

from test_refine import RING, ring_walk
from test_refine_first_stage import ring
from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.phase1.ambiguity import symbol_ambiguity
from topomap.core.refine import first_stage
from topomap.core.refine.methods import EMRefinement


def two_gaussians(distance, T=40_000, seed=0):
    """Half the steps from N(0, 1), half from N(distance, 1), in one dimension."""
    rng = np.random.default_rng(seed)
    symbols = np.repeat([0, 1], T // 2)
    X = rng.normal(size=(T, 1)) + distance * symbols[:, None]
    return X, symbols, np.array([[0.0], [float(distance)]]), np.ones((2, 1))


def test_well_separated_symbols_are_never_ambiguous():
    """20 standard deviations apart: the other symbol's posterior is below e^-40 at every step."""
    assert symbol_ambiguity(*two_gaussians(20.0)) < 1e-12


@pytest.mark.parametrize("distance", [1.0, 2.0, 3.0])
def test_two_overlapping_symbols_are_ambiguous_by_their_overlap(distance):
    """Equal weights, unit variances ``d`` apart: the Bayes error Phi(-d/2) (0.309, 0.159,
    0.067) is the expected ``1 - max posterior``; the sample of 20,000 steps (of 40,000) has a
    standard error below 0.004."""
    assert symbol_ambiguity(*two_gaussians(distance)) == pytest.approx(norm.cdf(-distance / 2),
                                                                      abs=0.01)


def test_the_sample_is_seeded_and_gds_steps_are_left_out():
    X, symbols, means, cov = two_gaussians(2.0)
    a = symbol_ambiguity(X, symbols, means, cov, random_state=3)
    assert a == symbol_ambiguity(X, symbols, means, cov, random_state=3)
    assert a != symbol_ambiguity(X, symbols, means, cov, random_state=4)
    # every step of symbol 1 marked as a GDS step: symbol 0 alone is left, with weight 1
    gds = np.where(symbols == 1, 2, symbols)
    assert symbol_ambiguity(X, gds, means, cov) < 1e-12
    # no more steps than the sample: every step counts, the posterior by hand (equal weights)
    X, symbols = X[::400], symbols[::400]
    density = norm.pdf(X, means.T, 1)
    by_hand = np.mean(1 - density.max(1) / density.sum(1))
    assert symbol_ambiguity(X, symbols, means, cov, sample=200) == pytest.approx(by_hand)


def fit(ambiguity=None, **growth):
    """``refine=em``'s record of the ring with the ``growth`` settings given."""
    seq, _ = ring(0)
    return EMRefinement(growth=growth).fit(seq, np.arange(6), 0, ambiguity=ambiguity).info_


def test_the_first_stage_is_rough_only_below_the_bar():
    """Stage 1 on 2,000 of 3,200 steps: below ``AMBIGUITY_BAR`` it is rough (at most 25
    E-steps, recorded); at the bar, above it or without an estimate it is the plain one."""
    bar = first_stage.AMBIGUITY_BAR
    plain = fit(first="plain")
    rough = fit(0.0)
    assert rough["first"] == "rough" and rough["stages"][0][2] <= 25 < plain["stages"][0][2]
    assert fit(bar / 2)["stages"] == rough["stages"]
    for ambiguity in (None, bar, 0.3):
        assert fit(ambiguity) == plain


def test_first_rough_and_plain_ignore_the_estimate():
    assert fit(0.3, first="rough")["first"] == "rough"
    assert "first" not in fit(0.0, first="plain")
    assert "first" not in fit(0.0, first_factor=0, first_iter=0)  # the rough settings off


@pytest.mark.parametrize("ambiguity", [1.5, -0.1, "high"])
def test_a_bad_estimate_is_refused_by_name(ambiguity):
    with pytest.raises(ValueError, match=r"^ambiguity: must be a number in \[0, 1\]"):
        fit(ambiguity)


def test_a_bad_first_is_refused_by_name():
    with pytest.raises(ParameterError, match="^growth.first must be one of auto, rough, plain"):
        fit(first="yes")


def ring_learner(sigma, **growth):
    """The ring's 6 symbols as one-hot observations with Gaussian noise ``sigma``."""
    sym, u, places = ring_walk(3200, RING, 0)
    X = np.eye(6)[sym] + np.random.default_rng(0).normal(0, sigma, (sym.size, 6))
    learner = MapLearner(n_clusters=6, n_states=8, refine=EMRefinement(growth=growth))
    return learner.fit(X, u, n_actions=2)


def test_the_learner_hands_its_estimate_to_the_refinement():
    """Noise 0.05 leaves every symbol exact (rough); 0.4 (the one-hot corners 1.41 apart, 1.77
    standard deviations from the midpoint) misreads some (plain); with ``first="plain"`` the
    estimate is not computed."""
    clean = ring_learner(0.05)
    assert clean.symbol_ambiguity_ < 1e-9 and clean.refine_info_["first"] == "rough"
    noisy = ring_learner(0.4)
    assert noisy.symbol_ambiguity_ > 0.01 and "first" not in noisy.refine_info_
    assert not hasattr(ring_learner(0.05, first="plain"), "symbol_ambiguity_")
