"""Places of a continuous log: view clusters kept apart where odometry says they are far apart.

A log recorded at 10-50 Hz repeats one view for many samples and its alike rooms are told apart
only by the way in: the split's test on ``P(x'|x,u)`` is dominated by self-transitions there, and
EM loses room identity because it predicts almost nothing (which corridor end follows a room
visit).  :func:`cut_places` cuts places instead with K-means on each step's view *and* its
odometric positions (:mod:`topomap.core.motion.odometry`), all in units of one view cluster's
extent: where views differ they decide, where one view is seen in two rooms the positions do.
Beside them it keeps the plain view clusters (K-means on the views, as many as places), the map
:mod:`topomap.core.motion.check` falls back to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..phase1.clustering import (FixedClusters, cluster_observations, make_metric,
                                 view_clusters)
from .odometry import (action_vectors, cell_extent, dead_reckoning, odometric_positions,
                       reckoned_steps)
from .posegraph import pose_graph
from .settings import MotionSettings, mean_run

__all__ = ["Places", "cut_places", "graph_places", "log_view_clusters", "places_of",
           "place_features", "position_weight", "view_clusters"]

#: the least view spread (the views' unit): a floor against 0 for a log whose view clusters
#: are single points, whose views then keep their own scale
MIN_SPREAD = 1e-12


@dataclass
class Places:
    """What :func:`cut_places` finds: ``views`` -- K-means on the views, as many clusters as
    places; ``places`` -- the places (None without odometry); ``V`` -- the actions' learned
    displacements; ``extent`` -- the cell extent; ``frame`` -- (T, 2) odometric positions of the
    middle gate in cell extents (None without odometry); ``info`` -- what was measured."""

    views: np.ndarray
    places: np.ndarray | None
    V: np.ndarray
    extent: float
    frame: np.ndarray | None
    info: dict


def _kmeans(F, k, n_init, random_state, method):
    """K-means places; phase 1's repair of cut views is left out (it is measured on views
    that repeat, not on the continuous views places are cut from)."""
    return cluster_observations(F, FixedClusters(k), make_metric("euclidean"), n_init=n_init,
                                random_state=random_state, method=method, repair=False)[0]


def _view_spread(Z, fsym, k) -> float:
    """The rms distance of a view to its cluster's centre: one view cluster's extent in views."""
    centres = np.zeros((k, Z.shape[1]))
    np.add.at(centres, fsym, Z)
    centres /= np.maximum(np.bincount(fsym, minlength=k), 1)[:, None]
    return max(float(np.sqrt(np.mean(((Z - centres[fsym]) ** 2).sum(axis=1)))), MIN_SPREAD)


def place_features(views, positions, weight: float) -> np.ndarray:
    """(T, D + 2 G) what the places are cut from: ``views`` (in units of one view cluster's
    extent) beside the ``G`` odometric position estimates of ``positions`` (each (T, 2), in cell
    extents), the gates sharing ``weight``: two steps' squared distance is their views' plus
    ``weight**2`` times their positions' mean squared distance.  At 0.5 a view differing by one
    cluster's extent weighs as a position two cell extents off: drift of a cell or so inside a
    room leaves a step with its view, and alike rooms many cell extents apart stay apart."""
    w = weight / np.sqrt(len(positions))  # the gates share the positions' weight
    return np.hstack([views] + [w * P for P in positions])


def position_weight(settings: MotionSettings, ratios) -> float:
    """The positions' weight beside the views: ``places.loose_weight`` where the odometry
    closes loops loosely -- the largest of the return ratios of the directions it kept (the
    share of a random window's displacement that windows returning to their view cluster keep,
    :func:`~topomap.core.motion.odometry.action_vectors`; two in a plane, one on a line) above
    ``places.loose_return`` -- else ``places.weight``."""
    return float(settings.places.loose_weight if max(ratios) > settings.places.loose_return
                 else settings.places.weight)


def log_view_clusters(settings: MotionSettings, Z, n_states: int,
                      random_state: int = 0) -> tuple[np.ndarray, int]:
    """``(labels, k)``: the log's view clusters (:func:`view_clusters` of ``Z``), ``k`` of them --
    ``n_states``, or the number of distinct rows of ``Z`` where fewer."""
    k = min(int(n_states), int(np.unique(Z, axis=0).shape[0]))
    return view_clusters(Z, k, settings.places.n_init, random_state), k


def cut_places(settings: MotionSettings, Z, u, lengths, n_states: int, n_actions: int, *,
               n_init: int = 3, random_state: int = 0, method: str = "auto",
               weight: float | None = None) -> Places:
    """``n_states`` places for the steps of ``Z`` (observations in the metric's space), the view
    clusters beside them, and what was measured on the way (:class:`Places`): the view clusters,
    the actions' displacements learned from them, the cell extent, and for each gate of
    ``places.gates`` the copies of view clusters its positions kept.  ``weight``: the
    positions' weight (None: :func:`position_weight` of this log's odometry)."""
    lengths = np.asarray(lengths, dtype=np.int64)
    fsym, k = log_view_clusters(settings, Z, n_states, random_state)
    V, ratios = action_vectors(Z, fsym, u, lengths, n_actions, seed=random_state,
                               max_return=settings.places.max_return)
    info = {"mean_run": round(mean_run(fsym, lengths), 3), "view_clusters": k,
            "return_ratios": np.round(ratios, 4).tolist(),
            "action_vectors": np.round(V, 4).tolist()}
    if not V.any():  # no odometry: the places are the view clusters
        info["odometry"] = False
        return Places(fsym, None, V, 1.0, None, info)
    r = cell_extent(fsym, dead_reckoning(u, lengths, V), lengths)
    if weight is None:  # the directions kept: a plane, or a line (the first alone)
        weight = position_weight(settings, ratios if V[:, 1].any() else ratios[:1])
    views = Z / _view_spread(Z, fsym, k)
    return places_of(settings, views, fsym, u, lengths, V, r, info, weight=float(weight),
                     n_states=n_states, n_init=n_init, random_state=random_state, method=method)


def places_of(settings: MotionSettings, views, fsym, u, lengths, V, extent: float, info: dict,
              *, weight: float, n_states: int, n_init: int, random_state: int,
              method: str) -> Places:
    """The places of steps whose ``views`` (in units of one view cluster's extent) lie in view
    clusters ``fsym``, moved by the actions ``u`` (displacements ``V``, cell extent ``extent``):
    K-means on the views beside each gate's odometric positions at ``weight``; ``info`` (what
    was measured before) gains the cell extent, the copies of every gate and the weight."""
    steps = reckoned_steps(u, lengths, V)
    positions, copies = [], []
    for gate in settings.places.gates:
        P, _, n_copies = odometric_positions(fsym, steps, lengths, gate * extent,
                                             pull=settings.places.pull)
        positions.append(P / extent)
        copies.append(n_copies)
    F = place_features(views, positions, float(weight))
    info = dict(info, odometry=True, cell_extent=round(extent, 4), copies=copies,
                weight=float(weight))
    places = _kmeans(F, int(n_states), n_init, random_state, method)
    return Places(fsym, places, V, extent, positions[len(positions) // 2], info)


def graph_places(settings: MotionSettings, Z, part: Places, u, lengths, n_states: int, *,
                 n_init: int = 3, random_state: int = 0, method: str = "auto") -> np.ndarray:
    """(T,) places of the steps of ``Z`` cut as :func:`places_of` cuts them, with one position
    estimate instead of one per gate: a pose graph over the whole log
    (:func:`~topomap.core.motion.posegraph.pose_graph`) whose loop closures are the copies at
    ``places.graph_gate`` cell extents; the view clusters, moves, cell extent and positions'
    weight are ``part``'s (the filter's places of the same steps, :func:`cut_places`).  Where
    the moves are noisy against a cell -- Tanni's rat, 0.023 m of a 0.034 m step off its
    command's mean -- the filter at 2.5-3.5 cell extents closes few loops and drifts (0.70 m
    rms from the truth after an affine fit on its room with two pillars); the pose graph at 6
    closes them and stays within 0.13 m.  A gate that wide joins alike rooms: such places are
    the check's to weigh (:mod:`~topomap.core.motion.crossfit`)."""
    k = int(part.views.max()) + 1
    views = Z / _view_spread(Z, part.views, k)
    steps = reckoned_steps(u, lengths, part.V)
    _, copy, n_copies = odometric_positions(part.views, steps, lengths,
                                            settings.places.graph_gate * part.extent,
                                            pull=settings.places.pull)
    P = pose_graph(steps, copy, n_copies, lengths, part.extent)[0] / part.extent
    F = place_features(views, [P], float(part.info["weight"]))
    return _kmeans(F, int(n_states), n_init, random_state, method)
