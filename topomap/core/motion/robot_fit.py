"""The robot route behind :class:`topomap.MapLearner`: ``motion=MotionSettings(mode="robot")``
(``learner.motion.mode=robot``) for a robot's log of egocentric range scans and wheel odometry.

:func:`fit_robot` runs after phases 1 and 2 (the split map stays ``map_split_``): the map is
:func:`~topomap.core.motion.robot.learn_robot`'s places, as many as the split map has states,
each a state with its own Gaussian of the scans (``labels_`` the place of every step); the
metric map the places were cut on, which :meth:`MapLearner.predict
<topomap.MapLearner.predict>` places a new walk on with that walk's odometry, is kept as
``robot_map_`` (:class:`~topomap.core.motion.robot.RobotMap`; a run writes it as
``robot_map.npz``, :mod:`topomap.core.motion.robot_io`; a saved ``map.json`` alone decodes the
scans and actions).  :func:`predict_robot` is that ``predict``.

Where the cells' map is its own point reflection (:mod:`topomap.core.motion.symmetry`: the
walk's odometry then cannot tell a walk from the walk turned by 180 degrees) the map is K-means on
the views instead, with a :class:`~topomap.core.motion.learn.ContinuousFallbackWarning` and
``motion_info_["reason"]``, and ``predict`` decodes it as any map (the odometry checked, unused).
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from sklearn.cluster import KMeans

from ..checks import ParameterError
from ..map.model import TopologicalMap
from .bind import bind_places
from .inputs import check_odometry
from .robot import learn_robot, place_walk
from .symmetry import SYMMETRY_RATIO, point_symmetry

__all__ = ["fit_robot", "predict_robot", "MIN_BEAMS"]

#: beams a row must hold to be read as a ring of range beams (a beam and its two neighbours)
MIN_BEAMS = 3


def _check_log(data, odometry) -> None:
    """A one-line :class:`ParameterError` when ``data`` and ``odometry`` are no robot log the
    route learns from: one episode of plain steps with odometry and a ring of beams a row."""
    if odometry is None:
        raise ParameterError("odometry", "is required by motion mode 'robot': the robot's (T, 3) "
                                         "wheel odometry (x, y, heading)")
    if len(data.lengths) > 1:
        raise ParameterError("lengths", "motion mode 'robot' learns from one episode, got "
                                        f"{len(data.lengths)}")
    if np.any(data.gds >= 0):
        raise ParameterError("gds", "motion mode 'robot' learns from plain steps: gds must be "
                                    "all -1")
    if data.X.shape[1] < MIN_BEAMS:
        raise ParameterError("observations", f"motion mode 'robot' reads each row as a ring of "
                                             f"range beams: at least {MIN_BEAMS} columns, got "
                                             f"{data.X.shape[1]}")


def _places_map(learner, data, labels, pooled: float | None = None) -> TopologicalMap:
    """The map whose states are ``labels``' places, each its own symbol; ``pooled``: one
    variance for all, times this (:func:`~.learn.pooled_variances`, the view clusters')."""
    from .learn import pooled_variances

    S = int(labels.max()) + 1
    m = TopologicalMap.from_labels(
        data.X, data.u, labels, lengths=data.lengths, state_symbol=np.arange(S),
        state_gds=np.full(S, -1), state_parent=np.full(S, -1), n_actions=data.n_actions,
        covariance_type=learner.covariance_type, reg_covar=learner.reg_covar,
        action_names=data.action_names, gds_names=data.gds_names,
        split_history=learner.split_history_)
    return m if pooled is None else pooled_variances(m, data.X, labels, learner.reg_covar, pooled)


def _view_clusters(learner, data, settings, info: dict):
    """``(labels, map)`` of K-means on the views, as many clusters as the split map has states,
    where the robot route's map is its own point reflection; a warning says so."""
    from .learn import ContinuousFallbackWarning

    info.update(chosen="views", reason=(
        f"the robot route's map looks the same turned by 180 degrees about "
        f"{tuple(info['symmetry']['centre'])} (mirror mismatch {info['symmetry']['ratio']:.2f} "
        f"times a neighbour's, below {SYMMETRY_RATIO}): its odometry cannot tell a walk from "
        f"its point reflection"))
    warnings.warn(f"robot log: the map's states are the view clusters (K-means on the views), "
                  f"not places: {info['reason']}", ContinuousFallbackWarning, stacklevel=5)
    labels = KMeans(learner.map_split_.n_states, n_init=settings.places.n_init,
                    random_state=learner.random_state).fit(data.X).labels_
    return labels, _places_map(learner, data, labels, settings.places.fallback_variance)


def fit_robot(learner, data, settings, odometry) -> bool:
    """Replace ``learner``'s map and labels by the robot route's places and keep its metric map as
    ``robot_map_`` -- or, where that map is its own point reflection
    (:func:`~.symmetry.point_symmetry`), by the view clusters, with a
    :class:`~.learn.ContinuousFallbackWarning`; record ``motion_info_`` and the seconds in
    ``timings_["places"]``; True."""
    _check_log(data, odometry)
    start = time.perf_counter()
    model, labels, poses = learn_robot(data.X, odometry, learner.map_split_.n_states,
                                       learner.random_state)
    info = {"chosen": "robot", "cells": model.n_cells, "places": int(labels.max()) + 1,
            "cell_spacing_m": round(model.spacing, 4),
            "beam_variance_m2": round(model.variance, 6),
            "path_m": round(float(np.hypot(*np.diff(poses[:, :2], axis=0).T).sum()), 2),
            "symmetry": point_symmetry(model)}
    if info["symmetry"]["ratio"] < SYMMETRY_RATIO:
        labels, m = _view_clusters(learner, data, settings, info)
    else:
        m = _places_map(learner, data, labels)
        learner.robot_map_ = model
    return bind_places(learner, m, labels, info, settings, start)


def predict_robot(model, observations, lengths, odometry) -> np.ndarray:
    """(T,) the place of every step of a new walk, each episode placed on ``model`` with its own
    ``odometry`` (T, 3) (:func:`~topomap.core.motion.robot.place_walk`); a one-line
    :class:`ParameterError` naming ``odometry`` or ``observations`` when they do not fit."""
    if odometry is None:
        raise ParameterError("odometry", "is required to place a walk on a map of motion mode "
                                         "'robot': the walk's (T, 3) wheel odometry")
    X = np.asarray(observations, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != model.scans.shape[1] or not np.all(np.isfinite(X)):
        raise ParameterError("observations", f"must be finite (T, {model.scans.shape[1]}) scans "
                                             f"as the map was learned from, got shape {X.shape}")
    lengths = np.array([len(X)] if lengths is None else lengths, dtype=np.int64)
    O = check_odometry(odometry, len(X), lengths)
    ends = np.cumsum(lengths)
    return np.concatenate([place_walk(model, X[a:b], O[a:b])[0]
                           for a, b in zip(ends - lengths, ends)]).astype(np.int64)
