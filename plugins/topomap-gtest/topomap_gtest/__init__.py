"""A split criterion for topomap: a G-test on the two candidate halves.

The paper splits the state of largest entropy gain.  The gain is a per-instance quantity, so a
state seen three times can out-score one seen three hundred times.  The G-test asks instead
whether the two halves found by the paper's bottom-up merge really differ in their ``(u, x')``
distribution: ``G = 2 * sum O ln(O / E)`` over the 2 x K contingency table, which equals
``2 ln 2 * N * gain`` (gain in bits).  A state whose split is not significant at level ``alpha`` is
not split at all; among the others the largest ``-log10 p`` wins.

    topomap split=gtest split.alpha=0.01
"""

import numpy as np
from scipy.stats import chi2

from topomap import Component, hookimpl
from topomap.core.split.criteria import EntropyCriterion


class GTestCriterion:
    """Score a split by the significance of a G-test between its two halves."""

    def __init__(self, alpha: float = 0.01):
        if not 0 < alpha < 1:
            raise ValueError(f"split.alpha must lie in (0, 1), got {alpha!r}")
        self.alpha = float(alpha)
        self._halves = EntropyCriterion()

    def propose(self, counts):
        proposal = self._halves.propose(counts)
        if proposal is None:
            return None
        side, gain = proposal
        counts = np.asarray(counts)
        table = np.stack([counts[~side].sum(axis=0), counts[side].sum(axis=0)])
        table = table[:, table.sum(axis=0) > 0]
        dof = table.shape[1] - 1
        if dof < 1:
            return None
        g = 2 * np.log(2) * counts.sum() * gain
        p = chi2.sf(g, dof)
        if p >= self.alpha:
            return None
        return side, float(-np.log10(max(p, 1e-300)))

    def __repr__(self):
        return f"GTestCriterion(alpha={self.alpha})"


@hookimpl
def topomap_register_components():
    # no config class: `split.alpha` is typed from GTestCriterion's signature
    return [Component("split", "gtest", GTestCriterion,
                      description="G-test between the two halves; split only if p < alpha")]


@hookimpl
def topomap_config_path():
    return "pkg://topomap_gtest.conf"
