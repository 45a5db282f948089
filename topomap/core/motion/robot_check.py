"""The held-out check of the robot route: its places against the view clusters, on the log alone.

The robot route (:mod:`topomap.core.motion.robot`) beats K-means on the views by 5-10x on small
furnished plans but places walks farther off than the views where a 30-minute walk covers a
plan thinly (``benchmarks/notes/robots.md``).  No positions are known, so the check asks the
log's own dead reckoning, on a part neither map was learned from:

1. both maps are learned on the steps before the last ``holdout`` share (or after the first,
   where the last lies on ground the rest of the log never visits and the first less so,
   :func:`held_out_span`: a map learned without that ground places it blind, whichever map it
   is, and the check measures nothing): the robot route's
   cells and places (:func:`~.robot.learn_robot`; its reckoned poses are the map's frame) and
   K-means on the views (a map with one pooled variance, as the fallback's);
2. each places the held-out steps as it would a new walk -- the robot route by the held-out
   steps' own odometry (:func:`~.robot.place_walk`), the view clusters by their views and actions
   (:meth:`~topomap.core.map.model.TopologicalMap.predict`) -- and each held-out step stands at
   its state's mean reckoned position (:func:`~.crossfit.state_positions`);
3. the held-out steps' own positions: their odometry's travel along the headings of the whole
   log (:func:`~.scans.scan_headings`: headings say nothing of which room a step is in; those of
   the held-out part solved alone lost 2.6 rad on a 2,000-step part), started from the learned
   part's last pose -- the walk goes on from there (a held-out first part: ended at the learned
   part's first pose), so a map that puts the held-out walk in the
   other alike room is that room's distance off (a frame aligned by offsets, as the continuous
   path's check has it, would absorb such a shift; on ``robot_alike`` seed 0 this frame lies
   0.26 m from the truth, where the learned part's poses lie 0.11 m);
4. the error of a map is the median distance of the held-out steps from their placed
   positions [m], and the robot route is kept only where the views' median distance exceeds
   its own by more than :data:`ROBOT_MARGIN_SE` bootstrap standard errors
   (:func:`~.crossfit.median_gap`, stretches of :data:`~.crossfit.STRETCH_RUNS` mean runs).
"""

from __future__ import annotations

import numpy as np
from sklearn.cluster import KMeans

from ..size import split_holdout
from .coverage import NOVEL_SHARE, novelty
from .crossfit import STRETCH_RUNS, median_gap, state_positions
from .reckoning import forward_moves, reckon
from .robot import learn_robot, place_walk
from .scans import scan_headings
from .settings import mean_run

__all__ = ["robot_check", "check_views", "robot_wins", "check_reason", "continued_poses",
           "preceding_poses", "held_out_span", "ROBOT_MARGIN_SE"]

#: standard errors: the robot route is kept only where the views' held-out median distance
#: exceeds its own by more than this many bootstrap standard errors of the difference (the
#: continuous path's ``MARGIN_SE``, the other way round: the route must win; measured gaps
#: 6.4-22.4 standard errors on eight furnished 1 m walks and two of ``robot_office`` (7.4, 7.7)
#: where the route wins on a new walk, 0.8 on the office walk where it loses, -13.9 on a
#: point-symmetric plan; benchmarks/notes/robots.md, 2026-12-03)
ROBOT_MARGIN_SE = 2.0


def continued_poses(odometry, headings, start) -> np.ndarray:
    """(T - 1, 3) poses of the steps after the first of a walk with wheel ``odometry`` (T, 3)
    and ``headings`` (T,) [rad] in a frame of their own, whose first step stands at the pose
    ``start`` (x [m], y [m], heading [rad]): the odometry's travel along the headings, turned
    and moved so that the first step is ``start``."""
    O = np.asarray(odometry, dtype=np.float64)
    h = np.asarray(headings, dtype=np.float64)
    P = reckon(forward_moves(O), h - h[0] + float(start[2]))
    P[:, :2] += np.asarray(start[:2], dtype=np.float64)
    return P[1:]


def preceding_poses(odometry, headings, end) -> np.ndarray:
    """(T - 1, 3) poses of the steps before the last of a walk with wheel ``odometry`` (T, 3)
    and ``headings`` (T,) [rad] in a frame of their own, whose last step stands at the pose
    ``end`` (x [m], y [m], heading [rad]): the odometry's travel along the headings, turned and
    moved so that the last step is ``end``."""
    O = np.asarray(odometry, dtype=np.float64)
    h = np.asarray(headings, dtype=np.float64)
    P = reckon(forward_moves(O), h - h[-1] + float(end[2]))
    P[:, :2] += np.asarray(end[:2], dtype=np.float64) - P[-1, :2]
    return P[:-1]


def held_out_span(T: int, holdout: float, places=None) -> tuple[int, int]:
    """``(a, b)``: the steps the check holds out of a log of ``T`` steps -- the last ``holdout``
    share, or as many first steps where the last part's :func:`~.coverage.novelty` under the
    whole log's ``places`` ((T,) labels; None: the last part) reaches
    :data:`~.coverage.NOVEL_SHARE` and the first part's is lower (a walk at 20 Hz whose last
    quarter went where its first three never did: novelty 0.73, the first quarter's 0; the
    last quarters of the 15 walks of the benchmark's five plans at 10 Hz: 0-0.42)."""
    _, _, cut = split_holdout(T, [T], holdout)
    if places is not None:
        last, first = novelty(places, cut, T), novelty(places, 0, T - cut)
        if last >= NOVEL_SHARE and first < last:
            return 0, T - cut
    return cut, T


def check_views(X, n_states: int, holdout: float, random_state=0) -> np.ndarray:
    """The check's view clusters: K-means on the views of the steps before the cut (labels of
    those steps); made apart from :func:`robot_check` so that it can run beside the route."""
    _, _, cut = split_holdout(len(X), [len(X)], holdout)
    return KMeans(n_states, n_init=1, random_state=random_state).fit(X[:cut]).labels_


def robot_check(X, u, odometry, n_states: int, views_map, holdout: float, random_state=0, *,
                symbols=None, headings=None, place_odometry=None, views=None,
                places=None) -> dict:
    """The check's figures (module docstring): ``{"learned", "held_out", "robot", "views",
    "gap", "se"}`` -- steps learned and held out, each map's median distance [m] of the
    held-out steps from their placed positions, the views' less the robot route's and its
    bootstrap standard error; ``"held_out_first": True`` where the first steps were held out
    (:func:`held_out_span`).  ``views_map(X, u, labels)``: the view clusters' map of labelled
    steps; ``symbols`` (T,): phase 1's symbols, whose mean run sets the bootstrap's stretch
    (None: one stretch per :data:`~.crossfit.STRETCH_RUNS` steps); ``headings`` (T,): the whole
    log's headings (:func:`~.scans.scan_headings`; None: solved here), which the learned part
    takes too (its own headings solved again cost as much as the whole log's and differ only
    in the closures into the held-out part, which say nothing of which room a step is in);
    ``place_odometry`` (T, 3): the odometry the held-out steps are placed by, as a new walk's
    would be (None: ``odometry``; odometry read from the scans places a new walk by its
    unclosed registration, :mod:`~.robot_scans`); ``views``: a function returning
    :func:`check_views` of the log (None: made here; used only where the last steps are held
    out); ``places`` (T,): the whole log's places, which choose the held-out part
    (:func:`held_out_span`; None: the last)."""
    X, u = np.asarray(X, dtype=np.float64), np.asarray(u)
    O = np.asarray(odometry, dtype=np.float64)
    a, b = held_out_span(len(X), holdout, places)
    first = a == 0
    learn = slice(b, len(X)) if first else slice(0, a)
    if headings is None:
        headings = scan_headings(X, O[:, 2])
    model, learned, P = learn_robot(X[learn], O[learn], n_states, random_state,
                                    headings=headings[learn])
    frame = (preceding_poses(O[a:b + 1], headings[a:b + 1], P[0]) if first
             else continued_poses(O[a - 1:b], headings[a - 1:b], P[-1]))[:, :2]
    O_place = O if place_odometry is None else np.asarray(place_odometry, dtype=np.float64)
    robot_placed = state_positions(learned, P)[model.place[place_walk(model, X[a:b],
                                                                      O_place[a:b])[1]]]
    if first:
        views = KMeans(n_states, n_init=1, random_state=random_state).fit(X[learn]).labels_
    else:
        views = check_views(X, n_states, holdout, random_state) if views is None else views()
    decoded = views_map(X[learn], u[learn], views).predict(X[a:b], u[a:b])
    views_placed = state_positions(views, P)[decoded]
    dist = {name: np.linalg.norm(placed - frame, axis=1)
            for name, placed in (("robot", robot_placed), ("views", views_placed))}
    run = 1.0 if symbols is None else mean_run(np.asarray(symbols), [len(X)])
    gap, se = median_gap(dist["robot"], dist["views"], int(round(STRETCH_RUNS * run)),
                         seed=random_state if isinstance(random_state, int) else 0)
    return {"learned": len(X) - (b - a), "held_out": b - a,
            **({"held_out_first": True} if first else {}),
            "robot": round(float(np.median(dist["robot"])), 4),
            "views": round(float(np.median(dist["views"])), 4),
            "gap": round(gap, 4), "se": round(se, 4)}


def robot_wins(check: dict) -> bool:
    """Whether :func:`robot_check`'s figures keep the robot route: the views' median distance
    above its own by more than :data:`ROBOT_MARGIN_SE` standard errors."""
    return check["gap"] > ROBOT_MARGIN_SE * check["se"]


def check_reason(check: dict) -> str:
    """Why the robot route gave way to the view clusters (one line), from the check's figures."""
    part = "first" if check.get("held_out_first") else "last"
    return (f"the held-out check placed the log's {part} {check['held_out']} steps "
            f"{check['robot']:.3f} m from their own dead reckoning with the robot route and "
            f"{check['views']:.3f} m with the view clusters: the robot route must be nearer by "
            f"more than {ROBOT_MARGIN_SE:g} standard errors ({check['se']:.3f} m)")
