"""k-means++ seeding for many clusters: scikit-learn's greedy k-means++, computing only the
distances that can matter.

scikit-learn's ``kmeans_plusplus`` (the ``init="k-means++"`` of ``KMeans``) picks every new centre
among ``2 + ln(k)`` candidates drawn in proportion to each row's squared distance to its closest
centre so far, and keeps the candidate that lowers the sum of those distances most.  Each pick
computes the distance from every candidate to every row: ``k x trials x T x D`` multiply-adds,
most of K-means' time with hundreds of clusters (MiniGrid FourRooms: 450).

:class:`PrunedPlusPlus` draws the same random numbers and makes the same choices, but computes a
candidate's distance to a row only when the triangle inequality allows it to be below the row's
closest distance (to every row where more than :data:`ALL_ROWS` of them may be): with ``m`` the
row's closest centre, ``d(c, x) >= d(c, m) - d(x, m)``, so where ``d(c, m) > 2 d(x, m)`` the row
keeps its closest distance (a margin covers the rounding of the distances).  The distances it does compute are scikit-learn's formula on a product over at least
:data:`PRODUCT_ROWS` rows, whose entries OpenBLAS rounds as in the product over all rows: the
centres are scikit-learn's, bit for bit (checked on FourRooms' views, seeds 0-7, and in the
tests).  A BLAS that rounds a product's entries by the number of its rows could break an exact
tie between two candidates the other way (a pair of rows far from every centre is one).
"""

from __future__ import annotations

import numpy as np
from sklearn.utils.extmath import row_norms

__all__ = ["PrunedPlusPlus", "MIN_CLUSTERS", "PRUNED_CLUSTERS", "PRODUCT_ROWS", "ALL_ROWS"]

#: from this many clusters on, phase 1 iterates K-means by Elkan's algorithm and looks for views
#: it cut in two (:mod:`topomap.core.phase1.clustering`)
MIN_CLUSTERS = 100
#: from this many clusters on, phase 1 seeds K-means with :class:`PrunedPlusPlus` (the same
#: centres).  Measured (CPU time of ``KMeans(n_init=3)``, 10,000 steps, seed 0, under load):
#: MiniGrid Empty-8x8's 86 clusters of 147 features 0.70x scikit-learn's seeding, the crossing's
#: 137 0.72x; at 4-20 clusters of 4-15 features (the grid rooms, the random graph, the office)
#: the seeding is a small part of K-means and the pruned one no faster (0.9-1.3x)
PRUNED_CLUSTERS = 50
#: the fewest rows a candidates' distance product is computed over: OpenBLAS computes products
#: of a few rows with its small-matrix kernels, whose entries round otherwise than the product of
#: all rows scikit-learn computes (seen below about 200 rows at 8 candidates x 147 features)
PRODUCT_ROWS = 512
#: the share of the rows above which a candidates' distances are computed to every row (no
#: gather of the rows within reach, no scatter of their distances).  CPU s of the seeding
#: (medians of 3-5, one BLAS thread) at 0.25 / 0.5 / 0.75 / never: FourRooms' views (200
#: clusters) 0.180 / 0.137 / 0.125 / 0.145, the aliased walk's 20,000 rows of 15 features
#: (100 clusters) 0.044 / 0.043 / 0.047 / 0.061, 450 clusters of uniform 15-D centres 0.341 /
#: 0.354 / 0.536 / 0.628
ALL_ROWS = 0.5
#: the margin of the pruning test, relative to the largest row norm (the squared distances'
#: rounding is about 1e-16 of the squared norms, i.e. 1e-8 of the norms)
_MARGIN = 1e-6


def _squared_distances(A, B, B_sq):
    """Squared distances from the rows of ``A`` to those of ``B`` (norms ``B_sq``), by the formula
    and in the order of scikit-learn's ``euclidean_distances`` (``-2 A B' + |a|^2 + |b|^2``,
    clipped at 0), without its input checks."""
    d = -2 * (A @ B.T)
    d += row_norms(A, squared=True)[:, None]
    d += B_sq[None, :]
    return np.maximum(d, 0, out=d)


def _rows_within_reach(centre_dist, owner, closest, margin):
    """Rows ``x`` for which some candidate ``k`` has ``centre_dist[k, owner[x]] <= 2 sqrt(closest[x])
    + margin``: the rows whose closest distance a candidate may lower (in increasing order)."""
    nearest = centre_dist.min(axis=0)  # each centre's nearest candidate
    return np.flatnonzero(nearest[owner] <= 2.0 * np.sqrt(closest) + margin)


class PrunedPlusPlus:
    """A ``KMeans(init=...)`` callable: k-means++ seeding as scikit-learn's, with pruned
    distances (module docstring).  ``sample_weight`` (the rows' weights, or None) must be the
    one ``KMeans.fit`` is given: scikit-learn does not pass it to a callable."""

    def __init__(self, sample_weight=None):
        self.sample_weight = sample_weight

    def __call__(self, X, n_clusters, random_state):
        T = X.shape[0]
        weight = (np.ones(T, dtype=X.dtype) if self.sample_weight is None
                  else np.asarray(self.sample_weight, dtype=X.dtype))
        x_sq = row_norms(X, squared=True)
        trials = 2 + int(np.log(n_clusters))
        centres = np.empty((n_clusters, X.shape[1]), dtype=X.dtype)
        centre_sq = np.empty(n_clusters, dtype=X.dtype)
        first = random_state.choice(T, p=weight / weight.sum())
        centres[0], centre_sq[0] = X[first], x_sq[first]
        closest = _squared_distances(centres[:1], X, x_sq)
        potential = closest @ weight
        closest = closest[0]
        owner = np.zeros(T, dtype=np.int64)
        margin = _MARGIN * float(np.sqrt(x_sq.max()))
        dist = np.empty((trials, T), dtype=X.dtype)
        for c in range(1, n_clusters):
            draws = random_state.uniform(size=trials) * potential
            ids = np.searchsorted(np.cumsum(weight * closest), draws)
            np.clip(ids, None, T - 1, out=ids)
            cand = X[ids]
            centre_dist = np.sqrt(_squared_distances(cand, centres[:c], centre_sq[:c]))
            rows = _rows_within_reach(centre_dist, owner, closest, margin)
            if rows.size > ALL_ROWS * T:  # most rows: all of them, as scikit-learn does
                dist = _squared_distances(cand, X, x_sq)
            else:
                if rows.size < PRODUCT_ROWS:  # a product over few rows may round otherwise
                    rows = np.union1d(rows, np.arange(min(T, PRODUCT_ROWS)))
                dist[:] = closest
                if rows.size:
                    dist[:, rows] = _squared_distances(cand, X[rows], x_sq[rows])
            np.minimum(closest, dist, out=dist)
            pots = dist @ weight.reshape(-1, 1)
            best = int(np.argmin(pots))
            potential = pots[best]
            owner[dist[best] < closest] = c
            closest = dist[best].copy()
            centres[c], centre_sq[c] = X[ids[best]], x_sq[ids[best]]
        return centres
