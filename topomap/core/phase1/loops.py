"""Views K-means cut in two, found by turn loops: a run of turns whose rotations add up to a full
circle (left then right, four lefts) ends at the pose it began at, so the symbols read at its
two ends are one view.

Where phase 1 asks for more clusters than the walk has views, K-means cuts the most frequent
views into two or three clusters, and each step of such a view is read as one of them at random
(MiniGrid FourRooms at 10,000 steps: 450 clusters for 403 views, 31 views cut, the symbols'
ARI against the views 0.75).  A map then holds two states for one pose.  Given the turns
(:class:`~topomap.core.phase1.heading.Turns`), :func:`loop_pairs` collects the two end symbols
of every run of 2 .. :data:`MAX_LOOP` turns that closes a circle, and :func:`join_loop_views`
joins two symbols when at least :data:`JOIN_SHARE` of the loops that touch the rarer of them
end at the other (and every group of symbols so linked).

Measured on the FourRooms walks of seeds 0-2 (10,000 and 50,000 steps, the benchmark's 450
clusters): every pair of symbols some loop links is one view (shares 0.09 to 1.0 of the rarer
symbol's loops), and every view K-means cut is joined (FourRooms 10,000, seed 0: 450 symbols
become 403).  A sensor that misreads one view as another in more than 5 % of the loops would
join them too; no such walk with turns has been measured.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["MAX_LOOP", "JOIN_SHARE", "loop_pairs", "join_loop_views"]

#: the longest run of turns taken for a loop (steps): four lefts, or left-left-right-right
MAX_LOOP = 8
#: the share of the rarer symbol's loops that must end at the other symbol to join the two: in
#: the FourRooms walks the views K-means cut give 0.09 or more
JOIN_SHARE = 0.05


def loop_pairs(sym, u, lengths, turns) -> tuple[np.ndarray, np.ndarray]:
    """``(first, last)``: the symbols at the two ends of every run of 2 .. :data:`MAX_LOOP`
    consecutive turns inside an episode whose rotations add up to a multiple of the circle."""
    sym, u = np.asarray(sym), np.asarray(u, dtype=np.int64)
    steps = np.asarray(turns.steps, dtype=np.int64)[u]
    turning = np.concatenate([[0], np.cumsum(steps != 0)])
    turned = np.concatenate([[0], np.cumsum(steps)])
    episode = np.repeat(np.arange(len(lengths)), lengths)
    first, last = [], []
    for k in range(2, min(MAX_LOOP, sym.size - 1) + 1):
        t = np.arange(sym.size - k)
        loop = ((turning[t + k] - turning[t] == k)
                & ((turned[t + k] - turned[t]) % turns.n_headings == 0)
                & (episode[t + k] == episode[t]))
        first.append(sym[t[loop]])
        last.append(sym[t[loop] + k])
    return np.concatenate(first), np.concatenate(last)


def join_loop_views(labels, ns: int, u, lengths, turns) -> tuple[np.ndarray, int, int]:
    """``(labels, ns, joined)``: ``labels`` (symbols ``0..ns-1``, then GDS states ``ns + g``)
    with every group of symbols the turn loops link (module docstring) made one symbol,
    numbered by their smallest member; the symbols left and how many were joined away."""
    labels = np.asarray(labels, dtype=np.int64)
    a, b = loop_pairs(labels, u, lengths, turns)
    keep = (a < ns) & (b < ns)
    a, b = a[keep], b[keep]
    touched = (np.bincount(a, minlength=ns) + np.bincount(b, minlength=ns)
               - np.bincount(a[a == b], minlength=ns))
    mixed = a != b
    low, high = np.minimum(a[mixed], b[mixed]), np.maximum(a[mixed], b[mixed])
    codes, counts = np.unique(low * ns + high, return_counts=True)
    low, high = codes // ns, codes % ns
    linked = counts >= JOIN_SHARE * np.minimum(touched[low], touched[high])
    if not linked.any():
        return labels, ns, 0
    graph = coo_matrix((np.ones(int(linked.sum())), (low[linked], high[linked])), shape=(ns, ns))
    n_groups, group = connected_components(graph, directed=False)
    out = np.where(labels < ns, group[np.minimum(labels, ns - 1)], labels - ns + n_groups)
    return out.astype(np.int64), int(n_groups), ns - int(n_groups)
