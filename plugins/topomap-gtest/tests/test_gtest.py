import math

import numpy as np
import pytest
from scipy.stats import chi2

from topomap_gtest import GTestCriterion


def test_g_statistic_matches_the_textbook_formula():
    counts = np.array([[30, 0], [28, 2], [0, 30], [1, 29]])
    side, score = GTestCriterion(alpha=0.05).propose(counts)
    assert side.tolist() == [False, False, True, True]
    O = np.array([[58, 2], [1, 59]], dtype=float)
    E = O.sum(1, keepdims=True) * O.sum(0, keepdims=True) / O.sum()
    G = 2 * (O * np.log(O / E)).sum()
    assert score == pytest.approx(-math.log10(chi2.sf(G, 1)))


def test_insignificant_split_is_refused():
    counts = np.array([[5, 5], [4, 6]])
    assert GTestCriterion(alpha=0.01).propose(counts) is None


def test_alpha_is_checked():
    with pytest.raises(ValueError, match="split.alpha"):
        GTestCriterion(alpha=1.5)
