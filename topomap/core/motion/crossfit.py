"""The cross-fitted check: places against view clusters on a part of the log neither saw.

The last ``check.holdout`` share of the log is held out.  Places and view clusters are learned
again on the steps before it (:func:`~topomap.core.motion.places.cut_places`: view clusters,
moves, cell extent and the places from those steps' own odometric positions); each
decodes the held-out steps (:meth:`~topomap.core.map.model.TopologicalMap.predict`, as any new
walk) and puts every step at its state's position -- the mean, over the state's training steps,
of the pose graph of the learned part (:func:`~topomap.core.motion.posegraph.graph_positions`).
The held-out steps' own positions come from a pose graph of the held-out part alone, with the
moves learned on the first part: nothing of the odometry the places were cut from enters it, so
a place that follows the first part's drift gains nothing.  The two frames share the moves'
orientation and scale, not their origin: the held-out frame is moved by the median offset of
the placed steps from it.  The error of a map is then the median distance of the held-out steps
from their placed positions (cell extents), and the rule is one comparison: the places are kept
where their error is below the view clusters'.
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import pairwise_distances_argmin

from ..size import split_holdout
from .places import cut_places
from .posegraph import graph_positions
from .settings import MotionSettings

__all__ = ["translated_error", "state_positions", "cross_fitted"]


def translated_error(placed, frame) -> float:
    """The median distance between the rows of ``placed`` and of ``frame`` ((T, 2) each) after
    ``frame`` is moved by the median offset between them (the frames' origins differ)."""
    d = np.asarray(placed) - np.asarray(frame)
    d = d - np.median(d, axis=0)
    return float(np.median(np.linalg.norm(d, axis=1)))


def state_positions(labels, P) -> np.ndarray:
    """(S, 2) the mean of the rows of ``P`` in each state of ``labels``."""
    counts = np.maximum(np.bincount(labels), 1)[:, None]
    return np.column_stack([np.bincount(labels, weights=P[:, j]) for j in range(2)]) / counts


def _nearest_views(views, Z, cut: int) -> np.ndarray:
    """The view cluster of every step from ``cut`` on: the nearest centre of ``views`` (the
    clusters of the steps before ``cut``)."""
    k = int(views.max()) + 1
    centres = np.zeros((k, Z.shape[1]))
    np.add.at(centres, views, Z[:cut])
    centres /= np.maximum(np.bincount(views, minlength=k), 1)[:, None]
    return pairwise_distances_argmin(Z[cut:], centres)


def cross_fitted(settings: MotionSettings, X, Z, u, lengths, n_states: int, n_actions: int,
                 build, **kmeans) -> dict | None:
    """The check's figures: ``{"learned", "held_out", "places", "views"}`` -- the steps before
    the cut, after it, and each map's error (:func:`translated_error`, cell extents); None where
    the learned part gives no odometry.  ``build`` and ``kmeans`` (``n_init``,
    ``random_state``, ``method``, ``weight``) as
    :func:`~topomap.core.motion.check.choose_places`'s."""
    T = len(u)
    head, tail, cut = split_holdout(T, lengths, settings.check.holdout)
    part = cut_places(settings, Z[:cut], u[:cut], head, n_states, n_actions, **kmeans)
    if part.places is None:
        return None
    gate = settings.places.gates[len(settings.places.gates) // 2]
    learned = graph_positions(part.views, u[:cut], head, part.V, part.extent, gate,
                              settings.places.pull)
    held = graph_positions(_nearest_views(part.views, Z, cut), u[cut:], tail, part.V,
                           part.extent, gate, settings.places.pull)
    out = {"learned": cut, "held_out": T - cut}
    for name, labels in (("places", part.places), ("views", part.views)):
        decoded = build(X[:cut], u[:cut], labels, head, pooled=name == "views").predict(
            X[cut:], u[cut:], lengths=tail)
        out[name] = round(translated_error(state_positions(labels, learned)[decoded], held), 4)
    return out
