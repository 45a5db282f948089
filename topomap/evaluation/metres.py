"""Scores in metres: where a map places the steps of a held-out walk, against where they were.

Whenever a world's positions are known, a map can be judged in metres rather than against
discrete places.  Each held-out step is decoded into a state (:meth:`TopologicalMap.predict`) and
*placed* at that state's mean TRAINING position (the mean position of the training steps labelled
with it); the scores are the median and the 90th percentile of the distances between the placed
and the true positions, and, given regions (rooms), the share of held-out steps placed in the
wrong region: a step is in the wrong region when the region most of its state's training steps
lie in is not the region it truly lies in.

Two yardsticks are computed the same way:

*the ceiling* (:func:`ceiling_scores`)
    the true places -- K-means on the true training positions WITHIN each region, so that no
    place straddles a wall, as many places as the map has states, shared among the regions by
    their shares of the training steps -- estimated in topomap's own model class
    (:meth:`TopologicalMap.from_labels`, each place observed through the K-means view symbol most
    of its steps have in the learned map), decoding the held-out walk.  Without regions the places
    are K-means on all positions, and may straddle walls.
*K-means on the views* (:func:`kmeans_view_scores`)
    as many clusters of the training observations as the map has states -- the view clusters
    a continuous log's map falls back to (:func:`topomap.core.phase1.clustering.view_clusters`)
    -- each held-out step taking the cluster of the nearest mean observation and placed at the
    cluster's mean training position.

``regions`` is None (no wrong-region share), a function ``positions -> (T,) region ids`` (such as
:meth:`topomap.worlds.arena.ArenaWorld.region_of`), or a pair ``(train_regions, heldout_regions)``
of region ids per step.
"""

from __future__ import annotations

import numpy as np

from ..core.map.model import TopologicalMap
from ..core.phase1.clustering import view_clusters
from ..core.stats import label_means

__all__ = ["placement_scores", "score_units", "map_scores", "true_places", "split_places",
           "ceiling_scores", "kmeans_view_scores", "kmeans_position_scores", "position_scores",
           "learner_map_scores", "learner_scores", "region_coverage", "VIEW_STARTS"]

#: k-means++ starts of the yardstick's view clusters: those of the view clusters a continuous
#: log's map falls back to (``MotionSettings().places.n_init``)
VIEW_STARTS = 4


def _positions(traj, which: str) -> np.ndarray:
    if traj.positions is None:
        raise ValueError(f"the {which} trajectory has no positions; scores in metres need them")
    return traj.positions


def _region_pair(regions, train, heldout):
    """``(train_regions, heldout_regions)`` as int arrays, or ``(None, None)``."""
    if regions is None:
        return None, None
    if callable(regions):
        pair = (regions(_positions(train, "training")), regions(_positions(heldout, "held-out")))
    else:
        pair = tuple(regions)
    if len(pair) != 2:
        raise ValueError("regions must be a function of positions or a pair (train_regions, "
                         "heldout_regions)")
    out = tuple(np.asarray(r, dtype=np.int64).ravel() for r in pair)
    for r, traj, which in zip(out, (train, heldout), ("training", "held-out")):
        if r.size != len(traj):
            raise ValueError(f"regions: {r.size} {which} region ids for {len(traj)} steps")
    return out


def region_coverage(names, train_regions, heldout_regions) -> dict:
    """How the two walks cover the regions ``names`` (region ids per step of each walk):
    ``regions`` -> ``{name: {"training": share, "heldout": share}}`` (shares of each walk's
    steps), ``unvisited``: the regions the held-out walk entered and the training walk never
    did, and ``heldout_unvisited``: the share of the held-out steps in them -- steps no map
    learned from the training walk can place in their region."""
    n = len(names)
    train = np.bincount(np.asarray(train_regions, dtype=np.int64), minlength=n)
    held = np.bincount(np.asarray(heldout_regions, dtype=np.int64), minlength=n)
    unseen = (train == 0) & (held > 0)
    return {"regions": {name: {"training": float(train[k] / max(train.sum(), 1)),
                               "heldout": float(held[k] / max(held.sum(), 1))}
                        for k, name in enumerate(names)},
            "unvisited": [name for k, name in enumerate(names) if unseen[k]],
            "heldout_unvisited": float(held[unseen].sum() / max(held.sum(), 1))}


def placement_scores(placed, truth, wrong=None) -> dict:
    """``median_error`` and ``p90_error`` (metres) of the distances between ``placed`` and
    ``truth`` ((T, 2 or 3) arrays, rows with NaN left out and counted in ``unplaced``), and
    ``wrong_region``, the mean of the boolean ``wrong`` (None without it)."""
    placed, truth = np.asarray(placed, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    ok = np.isfinite(placed).all(axis=1)
    d = np.sqrt(((placed[ok] - truth[ok]) ** 2).sum(axis=1))
    return {"median_error": float(np.median(d)) if d.size else None,
            "p90_error": float(np.percentile(d, 90)) if d.size else None,
            "wrong_region": None if wrong is None else float(np.mean(wrong)),
            "steps": int(placed.shape[0]), "unplaced": int((~ok).sum())}


def _majority(units: np.ndarray, values: np.ndarray, n_units: int) -> np.ndarray:
    """The most common value (ids >= 0) among every unit's steps, -1 for a unit without steps;
    ties go to the smallest value."""
    table = np.zeros((n_units, int(values.max()) + 1), dtype=np.int64)
    np.add.at(table, (units, values), 1)
    return np.where(table.sum(axis=1) > 0, table.argmax(axis=1), -1)


def score_units(train_units, train_positions, heldout_units, heldout_positions, n_units: int,
                region_pair=(None, None)) -> dict:
    """:func:`placement_scores` of held-out steps placed at their unit's (state's, place's,
    cluster's) mean training position; ``region_pair`` as in the module docstring."""
    tu, hu = np.asarray(train_units, dtype=np.int64), np.asarray(heldout_units, dtype=np.int64)
    placed = label_means(tu, train_positions, n_units)[hu]
    train_regions, heldout_regions = region_pair
    wrong = None
    if train_regions is not None:
        wrong = _majority(tu, train_regions, n_units)[hu] != heldout_regions
    return placement_scores(placed, heldout_positions, wrong)


def map_scores(tmap: TopologicalMap, train_labels, train, heldout, regions=None) -> dict:
    """Scores of ``tmap`` (learned from ``train``, its steps labelled ``train_labels``) on the
    held-out walk ``heldout`` (a :class:`~topomap.Trajectory` with positions)."""
    states = tmap.predict(heldout.observations, heldout.actions, heldout.gds, heldout.lengths)
    return score_units(train_labels, _positions(train, "training"), states,
                       _positions(heldout, "held-out"), tmap.n_states,
                       _region_pair(regions, train, heldout))


def split_places(counts, n_places: int) -> np.ndarray:
    """Places per region, in proportion to the regions' step ``counts``: each region's quota
    rounded down, then one more place at a time to the region farthest below its quota (the
    largest remainder); at least one place for every region with steps, never more than steps."""
    counts = np.asarray(counts, dtype=np.int64)
    have = counts > 0
    if not have.sum() <= n_places <= counts.sum():
        raise ValueError(f"n_places={n_places} must lie between the {int(have.sum())} regions "
                         f"with steps and the {int(counts.sum())} steps")
    quota = n_places * counts / counts.sum()
    share = np.minimum(np.where(have, np.maximum(np.floor(quota), 1), 0), counts).astype(np.int64)
    while share.sum() < n_places:
        share[np.argmax(np.where(share < counts, quota - share, -np.inf))] += 1
    while share.sum() > n_places:  # the one place every region gets took some from the others
        share[np.argmax(np.where(share > 1, share - quota, -np.inf))] -= 1
    return share


def true_places(positions, n_places: int, region_labels=None, random_state=0) -> np.ndarray:
    """Place ids ``(T,)``: K-means on the positions within each region (all together without
    regions), :func:`split_places` places per region."""
    from sklearn.cluster import KMeans

    P = np.asarray(positions, dtype=np.float64)
    regions = np.zeros(P.shape[0], dtype=np.int64) if region_labels is None else \
        np.asarray(region_labels, dtype=np.int64)
    share = split_places(np.bincount(regions), n_places)
    labels = np.empty(P.shape[0], dtype=np.int64)
    first = 0
    for r, k in enumerate(share.tolist()):
        if k == 0:
            continue
        rows = np.flatnonzero(regions == r)
        km = KMeans(n_clusters=k, n_init=4, random_state=random_state).fit(P[rows])
        labels[rows] = first + km.labels_
        first += k
    return labels


def ceiling_scores(tmap: TopologicalMap, train_labels, train, heldout, regions=None,
                   random_state=0, train_symbols=None) -> dict:
    """Scores of the true places in topomap's model class (see the module docstring);
    ``train_symbols`` (the K-means view symbol of each training step) defaults to the symbols of
    the states ``train_labels`` in ``tmap``."""
    labels = np.asarray(train_labels, dtype=np.int64)
    if train_symbols is None:
        n_sym = int(tmap.state_symbol.max()) + 1
        train_symbols = np.where(tmap.state_symbol >= 0, tmap.state_symbol,
                                 n_sym + tmap.state_gds)[labels]
        gds_base = n_sym
    else:
        train_symbols = np.asarray(train_symbols, dtype=np.int64)
        gds_base = int(train_symbols.max()) + 1
    pair = _region_pair(regions, train, heldout)
    S = tmap.n_states
    places = true_places(_positions(train, "training"), S, pair[0], random_state)
    model = _majority(places, train_symbols, S)
    place_map = TopologicalMap.from_labels(
        train.observations, train.actions, places, lengths=train.lengths,
        state_symbol=np.where(model < gds_base, model, -1),
        state_gds=np.where(model < gds_base, -1, model - gds_base),
        state_parent=np.full(S, -1), n_actions=tmap.n_actions)
    decoded = place_map.predict(heldout.observations, heldout.actions, heldout.gds,
                                heldout.lengths)
    return score_units(places, train.positions, decoded, _positions(heldout, "held-out"), S, pair)


def _cluster_scores(train_X, heldout_X, n_clusters: int, train, heldout, regions,
                    random_state, n_init: int) -> dict:
    """Scores of K-means on ``train_X`` (rows of the training steps), each held-out step (its
    row of ``heldout_X``) taking the cluster whose mean training row is nearest."""
    from sklearn.metrics import pairwise_distances_argmin

    clusters = view_clusters(train_X, n_clusters, n_init, random_state)
    centres = label_means(clusters, train_X, n_clusters)
    kept = np.flatnonzero(np.isfinite(centres).all(axis=1))  # clusters that hold a step
    nearest = kept[pairwise_distances_argmin(heldout_X, centres[kept])]
    return score_units(clusters, _positions(train, "training"), nearest,
                       _positions(heldout, "held-out"), n_clusters,
                       _region_pair(regions, train, heldout))


def kmeans_view_scores(n_clusters: int, train, heldout, regions=None, random_state=0,
                       n_init: int = VIEW_STARTS) -> dict:
    """Scores of K-means on the training observations with ``n_clusters`` clusters
    (:func:`~topomap.core.phase1.clustering.view_clusters`, ``n_init`` starts), each held-out
    step taking the cluster whose mean training observation is nearest."""
    return _cluster_scores(train.observations, heldout.observations, n_clusters, train, heldout,
                           regions, random_state, n_init)


def kmeans_position_scores(n_cells: int, train, heldout, regions=None, random_state=0,
                           n_init: int = VIEW_STARTS) -> dict:
    """Scores of K-means on the TRUE training positions with ``n_cells`` cells, each held-out
    step taking the cell nearest its TRUE position: where a map of as many states would place
    the walk if it knew where every step is (the "ideal" of ``docs/robot-logs.md``)."""
    return _cluster_scores(_positions(train, "training"), _positions(heldout, "held-out"),
                           n_cells, train, heldout, regions, random_state, n_init)


def position_scores(tmap: TopologicalMap, train_labels, train, heldout, regions=None,
                    random_state=0) -> dict:
    """``{"map": ..., "ceiling": ..., "kmeans_views": ...}``: the map's scores and both
    yardsticks' (each a :func:`placement_scores` dict), as many places and clusters as the map
    has states."""
    return {"map": map_scores(tmap, train_labels, train, heldout, regions),
            **_yardsticks(tmap, train_labels, train, heldout, regions, random_state)}


def _yardsticks(tmap: TopologicalMap, train_labels, train, heldout, regions,
                random_state) -> dict:
    """``{"ceiling": ..., "kmeans_views": ...}`` of a map of ``tmap.n_states`` states."""
    return {"ceiling": ceiling_scores(tmap, train_labels, train, heldout, regions, random_state),
            "kmeans_views": kmeans_view_scores(tmap.n_states, train, heldout, regions,
                                               random_state)}


def learner_map_scores(learner, train, heldout, regions=None) -> dict:
    """Scores of a fitted :class:`~topomap.MapLearner`'s map on the held-out walk, as
    ``topomap`` scores it: decoded on ``learner.map_`` (:func:`map_scores`), or -- a map of the
    robot route (``learner.robot_map_``) -- placed by :meth:`~topomap.MapLearner.predict` with
    the held-out walk's own odometry (``heldout.odometry``)."""
    if getattr(learner, "robot_map_", None) is None:
        return map_scores(learner.map_, learner.labels_, train, heldout, regions)
    placed = learner.predict(heldout.observations, heldout.actions, lengths=heldout.lengths,
                             odometry=heldout.odometry)
    return score_units(learner.labels_, _positions(train, "training"), placed,
                       _positions(heldout, "held-out"), learner.map_.n_states,
                       _region_pair(regions, train, heldout))


def learner_scores(learner, train, heldout, regions=None, random_state=0) -> dict:
    """:func:`position_scores` of a fitted :class:`~topomap.MapLearner` learned from ``train``,
    its map scored by :func:`learner_map_scores`, and K-means on the true positions
    (:func:`kmeans_position_scores`, ``"kmeans_positions"``) beside the two yardsticks."""
    m = learner.map_
    return {"map": learner_map_scores(learner, train, heldout, regions),
            **_yardsticks(m, learner.labels_, train, heldout, regions, random_state),
            "kmeans_positions": kmeans_position_scores(m.n_states, train, heldout, regions,
                                                       random_state)}
