"""The continuous branch of :meth:`topomap.MapLearner.fit`: places instead of a refinement.

After phases 1 and 2 (the paper's split, kept as ``map_split_``), a log that
:func:`~topomap.core.motion.settings.is_continuous` judges continuous gets as many places as the
split map has states (:func:`~topomap.core.motion.places.cut_places`); every place is a state
with its own Gaussian observation model (its ``state_symbol`` is its own id: the places are the
map's symbols), transitions and actions are counted on the raw rows, so ``labels_`` has a state
per row and :meth:`~topomap.core.map.model.TopologicalMap.predict`, ``filter`` and ``score`` take
the same stream as before.  Nothing here runs on a log that is not continuous.
"""

from __future__ import annotations

import time
import warnings
from contextlib import nullcontext
from dataclasses import replace

import numpy as np

from ..map.model import TopologicalMap
from ..phase1.clustering import one_blas_thread, one_thread
from .check import choose_places
from .bind import bind_places
from .crossfit import MARGIN_SE
from .commands import turn_share
from .places import log_view_clusters
from .robot_fit import early_headings, fit_robot, is_robot_log
from .robot_scans import early_scan_reading, fit_scan_robot, is_scan_log
from .settings import MotionSettings, is_continuous, mean_run

__all__ = ["fit_places", "pooled_variances", "fallback_reason", "ContinuousFallbackWarning"]


class ContinuousFallbackWarning(UserWarning):
    """A continuous log whose places gave way to the view clusters: the map is K-means on the
    views (the yardstick), and the warning says why (``motion_info_["reason"]``)."""


def fallback_reason(info: dict) -> str | None:
    """Why the places of a continuous log gave way to the view clusters (None where they did
    not), in one line, from what :func:`~topomap.core.motion.check.choose_places` recorded."""
    if info.get("chosen") != "views":
        return None
    check = info.get("check")
    if isinstance(check, str):
        return check
    if not info.get("odometry", True):
        return ("no odometry could be learned from the actions: walks that return to a view do "
                f"not cancel their commands' moves (return ratios {info['return_ratios']}, at "
                "most places.max_return kept); turn / forward commands move a robot differently "
                "with its heading")
    if "span" in check:  # the part of the log the rest seldom visits, held out
        return (f"the held-out check placed steps {check['span'][0]}-{check['span'][1]} of the "
                f"log, in places its other steps seldom visit, nearer their own pose graph with "
                f"the view clusters ({check['views']:.3f} cell extents) than with the places "
                f"({check['places']:.3f})")
    if "second" in check:  # the last part undecided, the one before it held out
        second = check["second"]
        return (f"the held-out check placed the log's last {check['held_out']} steps no nearer "
                f"their own pose graph by more than {MARGIN_SE:g} standard errors either way, "
                f"and steps {second['span'][0]}-{second['span'][1]} nearer with the view "
                f"clusters ({second['views']:.3f} cell extents) than with the places "
                f"({second['places']:.3f}), by more than {MARGIN_SE:g} standard errors "
                f"({second['se']:.3f})")
    if check.get("rule") in ("bootstrap", "coverage"):  # the views' gain beyond its noise
        return (f"the held-out check placed the log's last {check['held_out']} steps nearer "
                f"their own pose graph with the view clusters ({check['views']:.3f} cell "
                f"extents) than with the places ({check['places']:.3f}), by more than "
                f"{MARGIN_SE:g} standard errors ({check['se']:.3f})")
    if "mean_misplaced" not in check:  # the cross-fitted check: one error per map
        return (f"the held-out check placed the log's last {check['held_out']} steps no nearer "
                f"their own pose graph with the places ({check['places']:.3f} cell extents) than "
                f"with the view clusters ({check['views']:.3f})")
    shares = check["mean_misplaced"]
    return (f"the held-out check placed the log's held-out parts no better with the places "
            f"(misplaced {shares['places']:.3f}) than with the view clusters "
            f"({shares['views']:.3f})")


def pooled_variances(tmap: TopologicalMap, X, labels, reg_covar: float,
                     scale: float = 1.0) -> TopologicalMap:
    """``tmap`` with one variance for every state and feature: ``scale`` times the mean squared
    distance of the rows of ``X`` to their state's mean (``labels``) plus ``reg_covar`` --
    diagonal or full as ``tmap``'s covariances.  Every state's Gaussian then ranks a view by its
    distance to the state's mean alone, as the nearest centre does; a ``scale`` below 1 makes
    that ranking outweigh the transitions in a decoding, which then moves a step off its nearest
    centre only where two centres are all but equally near."""
    X = np.asarray(X, dtype=np.float64)
    var = float(scale) * (float(np.mean((X - tmap.means[labels]) ** 2)) + float(reg_covar))
    S, D = tmap.means.shape
    cov = np.full((S, D), var) if tmap.covariance_type == "diag" else \
        np.broadcast_to(var * np.eye(D), (S, D, D)).copy()
    return replace(tmap, covariances=cov)


def fit_places(learner, data, settings: MotionSettings, metric, odometry=None) -> bool:
    """When ``data`` are continuous, replace ``learner``'s map and labels by places (as many
    states as its split map, observations in ``metric``'s space), record what was measured in
    ``motion_info_`` and the seconds in ``timings_["places"]``, and return True; else False.
    ``settings.mode == "robot"``: the robot route instead (:func:`.robot_fit.fit_robot`).

    Every BLAS call of the branch runs on one thread
    (:func:`~topomap.core.phase1.clustering.one_blas_thread`): its products are too small to
    gain from a second, whose OpenBLAS thread then spins for its next call -- CPU the check
    paid for (on ``two_rooms`` seed 0 the learned odometry's 0.10 s against 0.02 s and the
    held-out decoding's 0.06 s against 0.01 s, under load) -- and each entry of a product is
    computed the same way whatever the threads (the same maps)."""
    with one_blas_thread():
        return _fit_places(learner, data, settings, metric, odometry)


def _fit_places(learner, data, settings: MotionSettings, metric, odometry=None) -> bool:
    """:func:`fit_places` with BLAS as it is set."""
    solving, learner._solving = getattr(learner, "_solving", None), None  # early_headings'
    if settings.mode == "robot":  # the robot route (:mod:`topomap.core.motion.robot_fit`)
        return fit_robot(learner, data, settings, odometry, solving=solving)
    if not is_continuous(settings, learner.labels_phase1_, data.lengths, data.gds,
                         odometry is not None):
        return False
    if np.any(data.gds >= 0):
        raise ValueError("motion mode 'continuous' cuts places of plain steps: gds must be all -1")
    start = time.perf_counter()
    with early_scan_reading(settings, data, odometry) as reading:  # beside the view clusters
        return _continuous(learner, data, settings, metric, odometry, start, solving, reading)


def _continuous(learner, data, settings, metric, odometry, start: float, solving,
                reading) -> bool:
    """:func:`fit_places` on a continuous log, from ``start`` (``time.perf_counter``);
    ``solving``: its headings on their way (:func:`~.robot_fit.early_headings`), ``reading``:
    its scans' odometry on its way (:func:`~.robot_scans.early_scan_reading`)."""
    Z = np.ascontiguousarray(metric.fit_transform(data.X), dtype=np.float64)

    def build(X, u, labels, lengths, pooled=False, **fields):
        S = int(labels.max()) + 1
        m = TopologicalMap.from_labels(
            X, u, labels, lengths=lengths, state_symbol=np.arange(S), state_gds=np.full(S, -1),
            state_parent=np.full(S, -1), n_actions=data.n_actions,
            covariance_type=learner.covariance_type, reg_covar=learner.reg_covar, **fields)
        return pooled_variances(m, X, labels, learner.reg_covar,
                                settings.places.fallback_variance) if pooled else m

    names = dict(action_names=data.action_names, gds_names=data.gds_names,
                 split_history=learner.split_history_)
    if is_robot_log(data, odometry):  # the odometry shows turn commands: the robot route
        def views():  # the view clusters, as the log gets them without odometry
            labels, k = log_view_clusters(settings, Z, learner.map_split_.n_states,
                                          learner.random_state)
            return labels, build(data.X, data.u, labels, data.lengths, pooled=True, **names), {
                "view_clusters": k, "mean_run": round(mean_run(labels, data.lengths), 3)}

        info = {"turn_share": round(turn_share(odometry, data.u), 4)}
        return fit_robot(learner, data, settings, odometry, fallback=(views, info, build),
                         start=start, solving=solving)
    # while the scans are read on a thread of their own, one OpenMP thread here: the second
    # core is the reading's (scikit-learn's Lloyd iterations on two threads wait on it)
    with nullcontext() if reading is None else one_thread():
        labels, info = choose_places(settings, data.X, Z, data.u, data.lengths,
                                     learner.map_split_.n_states, data.n_actions, build,
                                     n_init=learner.n_init, random_state=learner.random_state,
                                     method=learner.phase1)
    m = build(data.X, data.u, labels, data.lengths, pooled=info["chosen"] == "views", **names)
    if is_robot_log(data, odometry, info):  # no odometry learned from the actions: the route
        return fit_robot(learner, data, settings, odometry,
                         fallback=(lambda: (labels, m, {}), info, build), start=start)
    if settings.scan_odometry and is_scan_log(data, odometry, info):  # odometry from the scans
        return fit_scan_robot(learner, data, settings, (lambda: (labels, m, {}), info, build),
                              start=start, reading=reading)
    reason = fallback_reason(info)
    if reason is not None:
        info["reason"] = reason
        warnings.warn(f"continuous log: the map's states are the view clusters (K-means on the "
                      f"views), not places: {reason}", ContinuousFallbackWarning, stacklevel=5)
    return bind_places(learner, m, labels, info, settings, start)
