"""Phase 1's repair of a view K-means cut in two.

With many clusters, K-means can settle where one view (one blob of observations) holds two
clusters whose centres nearly coincide, while two other views share one cluster: MiniGrid
Empty-16x16 at 50,000 steps, seed 2, cuts its open-floor view into two clusters 0.016 apart
with an rms spread of 0.090, so 12.9 % of the steps carry the other symbol of their place.

:func:`repair_cut_views` looks for such pairs -- two centres closer than :data:`CUT_RATIO` times
the smaller of their clusters' rms spreads (the rms distance of a cluster's rows to its centre) --
joins every group of them into one cluster, gives each freed cluster to the cluster whose 2-means
cut lowers the inertia most, and when the rows so parted already have an inertia at least
:data:`MIN_GAIN` below the first K-means' (a fraction of it), runs K-means again from those
centres (which can only lower it further).  Otherwise, and where no pair is that close, the first
K-means is returned untouched (the same object: the same centres and labels).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.distance import pdist, squareform
from sklearn.cluster import KMeans

__all__ = ["CUT_RATIO", "MIN_GAIN", "rms_spreads", "cut_pairs", "repair_cut_views"]

#: two centres closer than this fraction of the smaller rms spread of their clusters are taken
#: for one view cut in two
CUT_RATIO = 0.5
#: the repair is kept only when it lowers K-means' inertia by at least this fraction
MIN_GAIN = 0.01


def _weights(Z, weight):
    return np.ones(Z.shape[0]) if weight is None else np.asarray(weight, dtype=np.float64)


def rms_spreads(Z, labels, centres, weight=None) -> np.ndarray:
    """(k,) the rms distance of each cluster's rows to its centre (weighted; 0 when empty)."""
    w = _weights(Z, weight)
    k = centres.shape[0]
    sq = _sq(Z, centres[labels])
    total = np.bincount(labels, weights=w * sq, minlength=k)
    mass = np.bincount(labels, weights=w, minlength=k)
    return np.sqrt(np.divide(total, mass, out=np.zeros(k), where=mass > 0))


def cut_pairs(centres, spreads, ratio: float = CUT_RATIO) -> np.ndarray:
    """(P, 2) the pairs ``i < j`` of clusters whose centres are closer than ``ratio`` times the
    smaller of their two spreads."""
    dist = squareform(pdist(centres))  # no (k, k, D) differences: k is 100 or more here
    limit = ratio * np.minimum(spreads[:, None], spreads[None, :])
    i, j = np.nonzero(np.triu(dist < limit, k=1))
    return np.stack([i, j], axis=1)


def _joined(pairs, k):
    """(k,) the group of every cluster (connected pairs form one group) and each group's
    surviving cluster (its lowest id); the other ids of a group are freed."""
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
    _, group = connected_components(graph, directed=False)
    keeper = np.full(group.max() + 1, k)
    np.minimum.at(keeper, group, np.arange(k))
    return keeper[group]


def _sq(Z, c):
    return np.einsum("ij,ij->i", Z - c, Z - c)


def _two_means(Zc, wc, iterations: int = 30):
    """(inertia gain, the two centres, the rows nearer the second) of a 2-means cut of one
    cluster's rows: Lloyd's iterations from the row farthest from the mean and the row farthest
    from that one (a cheap, seedless start); a gain of 0 and no centres for one point."""
    if Zc.shape[0] < 2:
        return 0.0, None, None
    mean = np.average(Zc, axis=0, weights=wc)
    sq = _sq(Zc, mean)
    a = Zc[np.argmax(sq)]
    pair = np.stack([a, Zc[np.argmax(_sq(Zc, a))]])
    side = None
    for _ in range(iterations):
        new_side = _sq(Zc, pair[1]) < _sq(Zc, pair[0])
        if not new_side.any() or new_side.all():
            return 0.0, None, None  # every row is one point
        if side is not None and np.array_equal(side, new_side):
            break
        side = new_side
        pair = np.stack([np.average(Zc[side == s], axis=0, weights=wc[side == s])
                         for s in (False, True)])
    side = _sq(Zc, pair[1]) < _sq(Zc, pair[0])
    cut = np.where(side, _sq(Zc, pair[1]), _sq(Zc, pair[0]))
    return float(wc @ sq) - float(wc @ cut), pair, side


def _start(Z, labels, centres, w, pairs):
    """``(centres, inertia)`` K-means starts again from: each group of cut pairs joined at its
    rows' mean, each freed cluster's centre given to the cluster whose 2-means cut gains most;
    the inertia of the rows so parted about those centres (K-means can only lower it)."""
    k = centres.shape[0]
    keeper = _joined(pairs, k)
    freed = np.flatnonzero(keeper != np.arange(k))
    part = keeper[labels]
    start = centres.copy()
    for c in np.unique(keeper[freed]):
        rows = part == c
        start[c] = np.average(Z[rows], axis=0, weights=w[rows])
    cuts = []
    for c in np.flatnonzero(keeper == np.arange(k)):
        rows = np.flatnonzero(part == c)
        gain, pair, side = _two_means(Z[rows], w[rows])
        if pair is not None:
            cuts.append((-gain, int(c), pair, rows[side]))
    cuts.sort(key=lambda cut: cut[:2])
    for f, (_, c, pair, second) in zip(freed, cuts):
        start[c], start[f] = pair
        part[second] = f
    return start, float(w @ _sq(Z, start[part]))


def repair_cut_views(km: KMeans, Z: np.ndarray, weight=None, random_state=0,
                     ratio: float = CUT_RATIO, min_gain: float = MIN_GAIN):
    """``(km, info)``: ``km`` (fitted on ``Z`` with ``weight``) or, when it cut views in two and
    the repaired start already lowers its inertia by at least ``min_gain`` (a fraction), the
    K-means run again from that start (module docstring); ``info`` is None where no pair of
    centres is that close, else ``{"pairs", "inertia", "start", "repaired", "kept"}``: the
    inertias of ``km``, of the start and of the K-means run from it (None when not run)."""
    w = _weights(Z, weight)
    centres, labels = km.cluster_centers_, km.labels_
    pairs = cut_pairs(centres, rms_spreads(Z, labels, centres, w), ratio)
    if not len(pairs):
        return km, None
    start, inertia = _start(Z, labels, centres, w, pairs)
    info = {"pairs": len(pairs), "inertia": float(km.inertia_), "start": inertia,
            "repaired": None, "kept": False}
    if inertia > (1.0 - min_gain) * km.inertia_:
        return km, info
    again = KMeans(centres.shape[0], init=start, n_init=1, random_state=random_state,
                   algorithm=km.algorithm).fit(Z, sample_weight=weight)
    info.update(repaired=float(again.inertia_),
                kept=bool(again.inertia_ <= (1.0 - min_gain) * km.inertia_))
    return (again if info["kept"] else km), info
