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

The default, ``mode="auto"``, takes this route on a log given odometry whose commands turn the
robot (:func:`is_robot_log`: the given odometry's turns explained by the commands,
:mod:`topomap.core.motion.commands`; or a continuous log whose actions gave no odometry of their
own), behind one more guard, the held-out check (:mod:`topomap.core.motion.robot_check`), the
judge of which map places the log's own last part nearer its dead reckoning (floor the scans
saw but the walk never entered, :mod:`topomap.core.motion.unwalked`, is measured and recorded;
it sends a log back only where its odometry was read from the scans); where one fails, the map
is the view clusters -- the
same map as without odometry where the continuous path finds no odometry in the commands --
with the reason.  ``MotionSettings(scan_odometry=True)``, the default, gives a log without
odometry the same route on odometry read from its scans (:mod:`topomap.core.motion.robot_scans`).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

import numpy as np
from sklearn.cluster import KMeans

from ..checks import ParameterError
from ..map.model import TopologicalMap
from ..split.threads import beside
from .beams import beam_order, described, in_route_frame
from .bind import bind_places
from .commands import MIN_TURN_SHARE, turn_share
from .unwalked import FAR, MAX_UNWALKED_DEPTH, unwalked_floor
from .inputs import check_odometry
from .robot import learn_robot, place_walk
from .scans import scan_headings
from .robot_check import check_reason, check_views, held_out_span, robot_check, robot_wins
from .symmetry import SCAN_REACH, SYMMETRY_RATIO, point_symmetry

__all__ = ["fit_robot", "predict_robot", "is_robot_log", "early_headings", "MIN_BEAMS"]

#: beams a row must hold to be read as a ring of range beams (a beam and its two neighbours)
MIN_BEAMS = 3
#: the most a map's cell spacing may be, as a share of the scans' median range (share): a
#: robot's odometry that agrees with its scans puts neighbouring cells well within what its
#: beams see -- 0.2-0.3 on the benchmark's robots (spacing 0.065-0.09 m, median range 0.31-0.48
#: m) -- where odometry read from 12 beams that register nothing put them 8.85 m apart in a
#: 2 x 1 m arena (18 times the median range) and its check, measured in that frame, passed it
MAX_SPACING_RANGE = 1.0


def _route_log(data) -> bool:
    """A log the route learns from: one episode, no GDS, a ring of :data:`MIN_BEAMS` beams or
    more a row."""
    return len(data.lengths) == 1 and not np.any(data.gds >= 0) and data.X.shape[1] >= MIN_BEAMS


def is_robot_log(data, odometry, info: dict | None = None) -> bool:
    """Whether ``mode="auto"`` tries the robot route on a continuous log: odometry given, a log
    the route learns from (one episode, no GDS, a ring of :data:`MIN_BEAMS` beams or more a
    row), and turn commands -- read off the given odometry (its turns explained by the commands,
    :func:`~.commands.turn_share` at least :data:`~.commands.MIN_TURN_SHARE`) or, with ``info``
    of the continuous path, no odometry learned from the actions (``info["odometry"]`` False:
    commands that move a robot differently with its heading)."""
    if odometry is None or not _route_log(data):
        return False
    if info is not None:
        return info.get("odometry") is False
    return turn_share(odometry, data.u) >= MIN_TURN_SHARE


class _OnItsWay:
    """A result a thread is computing (called: waits for it); a pickled or copied learner that
    holds one gets None instead (a thread's lock cannot be pickled)."""

    def __init__(self, result):
        self.result = result

    def __call__(self):
        return self.result()

    def __reduce__(self):
        return type(None), ()


def _ordered_headings(X, odometry):
    """``(order, headings)``: the beams' order the route reads ``X`` in
    (:func:`~.beams.beam_order`) and the steps' headings solved on the scans so ordered."""
    order = beam_order(X, odometry)
    return order, scan_headings(in_route_frame(X, order), odometry[:, 2])


def early_headings(settings, data, odometry):
    """Where the robot route may learn from the log (``settings.mode`` ``"robot"``, or
    ``"auto"`` and :func:`is_robot_log`), start solving its headings from the odometry
    (:func:`~.scans.scan_headings`: the heading graph's sparse solves, which release the GIL) on
    another thread, so that they run beside phase 1 and the split; a function without arguments
    gives ``(order, headings)``: the beams' order the route reads the scans in
    (:func:`~.beams.beam_order`) and the headings (the same numbers as solved in turn).  None
    where the route cannot follow (``settings`` None: no continuous path)."""
    if settings is None or odometry is None or settings.mode not in ("auto", "robot"):
        return None
    if not (is_robot_log(data, odometry) if settings.mode == "auto" else _route_log(data)):
        return None
    return _OnItsWay(beside(_ordered_headings, data.X, np.asarray(odometry, dtype=np.float64),
                            steps=len(data.X)))


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


def _scale_reason(info: dict, reach: float) -> str:
    """Why a map whose cells lie farther apart than its scans reach gives way (one line)."""
    return (f"the robot route's cells lie {info['cell_spacing_m']:.3g} m apart, more than the "
            f"scans' median range ({reach:.3g} m) times {MAX_SPACING_RANGE:g}: its odometry does "
            f"not agree with its scans")


def _symmetry_reason(info: dict) -> str:
    """Why a map that is its own point reflection gives way to the view clusters (one line)."""
    return (f"the robot route's map looks the same turned by 180 degrees about "
            f"{tuple(info['symmetry']['centre'])} (mirror mismatch "
            f"{info['symmetry']['ratio']:.2f} times a neighbour's, below {SYMMETRY_RATIO}): its "
            f"odometry cannot tell a walk from its point reflection")


def _coverage_reason(info: dict) -> str:
    """Why a map whose scans saw floor its walk never entered gives way (one line)."""
    return (f"the robot's scans saw floor its walk never entered ({info['unwalked']:.1%} of the "
            f"points along the cells' beams lie over {FAR:g} cell spacings from every cell, on "
            f"average {info['unwalked_depth']:.3f} spacings beyond, above "
            f"{MAX_UNWALKED_DEPTH:g}): the robot route cannot place a new walk there")


def _view_clusters(learner, data, settings, info: dict):
    """``(labels, map)`` of K-means on the views, as many clusters as the split map has states,
    where the robot route's map is its own point reflection; a warning says so."""
    from .learn import ContinuousFallbackWarning

    info.update(chosen="views", reason=_symmetry_reason(info))
    warnings.warn(f"robot log: the map's states are the view clusters (K-means on the views), "
                  f"not places: {info['reason']}", ContinuousFallbackWarning, stacklevel=5)
    labels = KMeans(learner.map_split_.n_states, n_init=settings.places.n_init,
                    random_state=learner.random_state).fit(data.X).labels_
    return labels, _places_map(learner, data, labels, settings.places.fallback_variance)


def fit_robot(learner, data, settings, odometry, fallback=None,
              start: float | None = None, place_odometry=None, headings=None,
              solving=None) -> bool:
    """Replace ``learner``'s map and labels by the robot route's places and keep its metric map as
    ``robot_map_`` -- or, where that map is its own point reflection
    (:func:`~.symmetry.point_symmetry`), by the view clusters, with a
    :class:`~.learn.ContinuousFallbackWarning`; record ``motion_info_`` and the seconds in
    ``timings_["places"]``; True.  ``fallback``: ``(views, info, build)`` where ``mode="auto"``
    chose the route -- ``views()`` gives ``(labels, map, info)`` of the view clusters of the log
    (made only where a guard fails: the map the log gets without odometry; ``info`` what their
    making measured), ``info`` what was measured before, ``build`` the map builder
    (:func:`~.learn.fit_places`; the held-out check builds its view clusters by it): the route
    must then also pass the guards of :func:`_failed_guard`, else the view clusters' map stays,
    with the warning; ``info`` is kept in ``motion_info_``.  ``start``: when the seconds began
    (``time.perf_counter``; None: now).  ``place_odometry``: the odometry the held-out check
    places its held-out steps by (None: ``odometry``; :mod:`~.robot_scans`).  ``headings`` (T,)
    [rad]: the steps' headings closed by loops already (odometry read from the scans,
    :func:`~.registration.scan_poses`, whose map's point symmetry is then measured with
    :data:`~.symmetry.SCAN_REACH`; None: solved from ``odometry``, by ``solving`` where given:
    :func:`early_headings`).  The route reads the scans with their beams in the order
    :func:`~.beams.beam_order` finds (beam 0 ahead, anticlockwise; kept in ``robot_map_``), but
    for odometry read from the scans, whose frame is the scans' own."""
    _check_log(data, odometry)
    start = time.perf_counter() if start is None else start
    # the check's view clusters need no headings: made on another thread while the route runs
    views = None if fallback is None else beside(
        check_views, data.X, learner.map_split_.n_states, settings.check.holdout,
        learner.random_state, steps=len(data.X))
    if headings is not None:  # odometry read from the scans: the scans' own frame
        order, solved = None, headings
    else:
        order, solved = (beam_order(data.X, odometry), None) if solving is None else solving()
    X = in_route_frame(data.X, order)
    model, labels, poses = learn_robot(X, odometry, learner.map_split_.n_states,
                                       learner.random_state, headings=solved)
    model = model if order is None else replace(model, beam_order=order)
    info = {**({} if fallback is None else fallback[1]), "chosen": "robot",
            "cells": model.n_cells, "places": int(labels.max()) + 1,
            "cell_spacing_m": round(model.spacing, 4),
            "beam_variance_m2": round(model.variance, 6),
            "path_m": round(float(np.hypot(*np.diff(poses[:, :2], axis=0).T).sum()), 2),
            "symmetry": point_symmetry(model, None if headings is None else SCAN_REACH),
            **({} if order is None else {"beams": described(order)})}
    if fallback is not None:
        reason = _failed_guard(learner, data, settings, (X, model, labels, poses, info),
                               (fallback, views, odometry, place_odometry, headings is not None))
        if reason is not None:
            return _fall_back(learner, settings, fallback, info, reason, start)
    if info["symmetry"]["ratio"] < SYMMETRY_RATIO:
        labels, m = _view_clusters(learner, data, settings, info)
    else:
        m = _places_map(learner, data, labels)
        learner.robot_map_ = model
    return bind_places(learner, m, labels, info, settings, start)


def _failed_guard(learner, data, settings, route, given) -> str | None:
    """Why the route's map gives way to the view clusters (one line), None where every guard
    passes, in turn: its cells within the scans' reach (:data:`MAX_SPACING_RANGE`), not its
    own point reflection, the floor its scans saw walked (:func:`~.unwalked.unwalked_floor`,
    recorded; a guard on odometry read from the scans and where the check holds out the first
    part, which cannot show unwalked floor) and the held-out check
    (:func:`~.robot_check.robot_check`).  ``route``: ``(X, model, places, poses, info)`` of
    :func:`fit_robot`, ``info`` taking the guards' figures; ``given``: ``(fallback, views,
    odometry, place_odometry, from_scans)``."""
    X, model, labels, poses, info = route
    fallback, views, odometry, place_odometry, from_scans = given
    reach = float(np.median(X))
    if model.spacing > MAX_SPACING_RANGE * reach:
        return _scale_reason(info, reach)
    if info["symmetry"]["ratio"] < SYMMETRY_RATIO:
        return _symmetry_reason(info)
    share, depth = unwalked_floor(model)
    info["unwalked"], info["unwalked_depth"] = round(share, 4), round(depth, 4)
    first = held_out_span(len(X), settings.check.holdout, labels)[0] == 0
    if (from_scans or first) and depth > MAX_UNWALKED_DEPTH:
        return _coverage_reason(info)
    info["check"] = robot_check(X, data.u, odometry, learner.map_split_.n_states,
                                lambda X, u, views: fallback[2](X, u, views, [len(X)],
                                                                pooled=True),
                                settings.check.holdout, learner.random_state,
                                symbols=learner.labels_phase1_, headings=poses[:, 2],
                                place_odometry=place_odometry, views=views, places=labels)
    return None if robot_wins(info["check"]) else check_reason(info["check"])


def _fall_back(learner, settings, fallback, info: dict, reason: str, start: float) -> bool:
    """Bind ``fallback``'s view clusters (``views()``: labels, map) with ``info`` and
    ``reason``, warning."""
    from .learn import ContinuousFallbackWarning

    labels, m, measured = fallback[0]()
    info.update(measured, chosen="views", reason=reason)
    warnings.warn(f"robot log: the map's states are the view clusters (K-means on the views), "
                  f"not places: {reason}", ContinuousFallbackWarning, stacklevel=5)
    return bind_places(learner, m, labels, info, settings, start)


def predict_robot(model, observations, lengths, odometry,
                  from_scans: bool = False) -> np.ndarray:
    """(T,) the place of every step of a new walk, each episode placed on ``model`` with its own
    ``odometry`` (T, 3) (:func:`~topomap.core.motion.robot.place_walk`); a one-line
    :class:`ParameterError` naming ``odometry`` or ``observations`` when they do not fit.
    ``from_scans``: a map learned on odometry read from the scans, where ``odometry`` None is
    read from the walk's own scans and closed by its own loops
    (:func:`~.robot_scans.walk_odometry`)."""
    if odometry is None and not from_scans:
        raise ParameterError("odometry", "is required to place a walk on a map of motion mode "
                                         "'robot': the walk's (T, 3) wheel odometry")
    X = np.asarray(observations, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != model.scans.shape[1] or not np.all(np.isfinite(X)):
        raise ParameterError("observations", f"must be finite (T, {model.scans.shape[1]}) scans "
                                             f"as the map was learned from, got shape {X.shape}")
    X = in_route_frame(X, model.beam_order)
    lengths = np.array([len(X)] if lengths is None else lengths, dtype=np.int64)
    if odometry is None:  # read from the scans: the walk's own, not a user's input to check
        from .robot_scans import walk_odometry

        O = walk_odometry(X, lengths)
    else:
        O = check_odometry(odometry, len(X), lengths)
    ends = np.cumsum(lengths)
    return np.concatenate([place_walk(model, X[a:b], O[a:b])[0]
                           for a, b in zip(ends - lengths, ends)]).astype(np.int64)
