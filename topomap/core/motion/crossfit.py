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
where their error is below the view clusters' (``check.rule="crossfit"``), or --
``check.rule="bootstrap"`` -- unless the view clusters' median distance is below theirs by more
than :data:`MARGIN_SE` bootstrap standard errors (:func:`median_gap`).  The default,
``check.rule="coverage"``, holds out an earlier part instead where the rest of the log seldom
visits its places (:mod:`topomap.core.motion.coverage`), and the part before the last beside it
where the last keeps the places within the bar (:func:`topomap.core.motion.check.undecided`).
With ``places.graph_gate`` the held-out part also weighs places cut from a pose graph of the
learned part (:func:`~topomap.core.motion.places.graph_places`) against the filter's
(:func:`stands_in`): where the moves are noisy against a cell, as a rat's, the filter's tight
gates close few loops and its places straddle the room.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from sklearn.metrics import pairwise_distances_argmin

from ..size import split_holdout
from .places import cut_places, graph_places
from .posegraph import graph_positions
from .settings import MotionSettings

__all__ = ["translated_error", "state_positions", "cross_fitted", "BLOCKS", "MARGIN_SE",
           "STRETCH_RUNS", "DRAWS", "FOLD_STARTS", "aligned_distances", "median_gap",
           "split_span", "stands_in"]


#: the held-out part's own pose graph drifts away from the learned part's: its steps are moved
#: by their median offset in blocks of one ``BLOCKS``-th of the log (two in the last quarter).
BLOCKS = 8
#: standard errors: the view clusters replace the places only where the places' median distance
#: exceeds theirs by more than this many bootstrap standard errors of the difference (places
#: cut from three quarters of a large layout lose to the view clusters on its last quarter by
#: 1.3-1.6 standard errors where those cut from the whole log win; the rat's paths lose by 4-6,
#: benchmarks/notes/continuous.md, "A margin from the fold's own noise").
MARGIN_SE = 2.0
#: mean runs of one view cluster (steps) in a stretch, the bootstrap's unit: a step placed in
#: the other room is followed by more, so stretches, not steps, are drawn (as ``block_runs``).
STRETCH_RUNS = 50.0
#: bootstrap draws of the stretches
DRAWS = 200
#: k-means++ starts of the learned part's view clusters under the bootstrap check (the whole
#: log's take ``n_init``): one start made the same choice as four on 19 of the 20 walks of
#: benchmarks/notes/continuous.md (``open``, a tie, the other way) at a quarter of their cost,
#: the check's largest part.
FOLD_STARTS = 1


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


def _nearest_views(views, Z_learned, Z_held) -> np.ndarray:
    """The view cluster of every held-out step (rows of ``Z_held``): the nearest centre of
    ``views`` (the clusters of the learned steps, rows of ``Z_learned``)."""
    k = int(views.max()) + 1
    centres = np.zeros((k, Z_learned.shape[1]))
    np.add.at(centres, views, Z_learned)
    centres /= np.maximum(np.bincount(views, minlength=k), 1)[:, None]
    return pairwise_distances_argmin(Z_held, centres)


def split_span(lengths, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
    """``(learned, held)``: the episode lengths of the steps outside ``a:b`` and of those inside
    it (an episode the span cuts through leaves a piece before it and one after it)."""
    ends = np.cumsum(lengths)
    starts = ends - np.asarray(lengths)
    before = [min(e, a) - s for s, e in zip(starts, ends) if s < a]
    inside = [min(e, b) - max(s, a) for s, e in zip(starts, ends) if s < b and e > a]
    after = [e - max(s, b) for s, e in zip(starts, ends) if e > b]
    return np.array(before + after, dtype=np.int64), np.array(inside, dtype=np.int64)


def _weigh_graph(out: dict, dist: dict, candidate, new_ground: bool, bootstrap) -> None:
    """Where the pose graph's places were decoded (``dist["graph"]``), record their gain over
    the filter's in ``out`` and, where they stand in (:func:`stands_in`) or ``candidate`` says
    so, make their figures the places' (``out`` and ``dist``); else record a given
    ``candidate``.  ``bootstrap``: ``(stretch, seed)`` of :func:`median_gap`."""
    if "graph" in dist:
        gain, gain_se = median_gap(dist["graph"], dist["places"], bootstrap[0], seed=bootstrap[1])
        if candidate is None:
            candidate = "graph" if stands_in(gain, gain_se, new_ground) else "filter"
        out.update(filter=out["places"], graph_gain=round(gain, 4), graph_se=round(gain_se, 4),
                   candidate=candidate)
        if candidate == "graph":
            out["places"], dist["places"] = out["graph"], dist["graph"]
    elif candidate is not None:
        out["candidate"] = candidate


def cross_fitted(settings: MotionSettings, X, Z, u, lengths, n_states: int, n_actions: int,
                 build, starts: int | None = None, span: tuple[int, int] | None = None, *,
                 candidate: str | None = None, new_ground: bool = False,
                 **kmeans) -> dict | None:
    """The check's figures: ``{"learned", "held_out", "places", "views", "gap", "se"}`` -- the
    steps learned from, those held out, each map's error (:func:`translated_error`, cell
    extents), and the views' median distance less the places' with its bootstrap standard error
    (the held-out steps moved by their median offset in blocks of one :data:`BLOCKS`-th of the
    log, :func:`aligned_distances`, :func:`median_gap`); None where the learned part gives no
    odometry.  ``span``: the steps ``a:b`` held out, the rest learned from (None: the last
    ``check.holdout`` share).  ``starts``: the k-means++ starts of the learned part's view
    clusters (None: ``places.n_init``).  ``build`` and ``kmeans`` (``n_init``,
    ``random_state``, ``method``, ``weight``) as
    :func:`~topomap.core.motion.check.choose_places`'s.

    With ``places.graph_gate`` above 0 the places of the pose graph
    (:func:`~topomap.core.motion.places.graph_places`) decode the held-out part too: where they
    stand in for the filter's places (:func:`stands_in` of ``graph_gain``, ``graph_se`` and
    ``new_ground``: the span held out is ground the rest of the log seldom visits), they are
    the ``candidate`` (``"graph"``, else ``"filter"``) whose figures ``places``, ``gap`` and
    ``se`` are; ``candidate`` given (``"graph"`` or ``"filter"``), that one is, and the other
    is not cut."""
    T = len(u)
    if span is None:
        head, tail, cut = split_holdout(T, lengths, settings.check.holdout)
        span = (cut, T)
    else:
        head, tail = split_span(lengths, *span)
    a, b = span
    keep = np.r_[0:a, b:T]
    Xl, Zl, ul = X[keep], Z[keep], u[keep]
    fold = settings if starts is None else replace(
        settings, places=replace(settings.places, n_init=int(starts)))
    part = cut_places(fold, Zl, ul, head, n_states, n_actions, **kmeans)
    if part.places is None:
        return None
    gate = settings.places.gates[len(settings.places.gates) // 2]
    learned = graph_positions(part.views, ul, head, part.V, part.extent, gate,
                              settings.places.pull)
    held = graph_positions(_nearest_views(part.views, Zl, Z[a:b]), u[a:b], tail, part.V,
                           part.extent, gate, settings.places.pull)
    out, dist = {"learned": int(keep.size), "held_out": b - a}, {}
    block = (np.arange(a, b) * BLOCKS) // T
    maps = {"places": part.places, "views": part.views}
    if settings.places.graph_gate > 0 and candidate != "filter":
        maps["graph"] = graph_places(settings, Zl, part, ul, head, n_states,
                                     **{k: kmeans[k] for k in ("n_init", "random_state", "method")
                                        if k in kmeans})
    for name, labels in maps.items():
        decoded = build(Xl, ul, labels, head, pooled=name == "views").predict(
            X[a:b], u[a:b], lengths=tail)
        placed = state_positions(labels, learned)[decoded]
        out[name] = round(translated_error(placed, held), 4)
        dist[name] = aligned_distances(placed, held, block)
    seed = kmeans.get("random_state", 0)
    seed = seed if isinstance(seed, int) else 0
    stretch = int(round(STRETCH_RUNS * part.info["mean_run"]))
    _weigh_graph(out, dist, candidate, new_ground, (stretch, seed))
    gap, se = median_gap(dist["places"], dist["views"], stretch, seed=seed)
    return dict(out, gap=round(gap, 4), se=round(se, 4))


def stands_in(gain: float, se: float, new_ground: bool) -> bool:
    """Whether the pose graph's places stand in for the filter's, their median distance
    ``gain`` below it (``se``: its bootstrap standard error): by more than :data:`MARGIN_SE`
    standard errors, or at all on ``new_ground`` -- as the places against the view clusters
    there (:func:`~topomap.core.motion.check.gives_way`): on ground one stay covered, a held-out
    part says which map is nearer, not by how much (on Tanni's rat path with two pillars,
    seed 1, the pose graph's places 0.044 cell extents nearer with a standard error of 0.049;
    on a new walk 0.094 m off, the filter's 0.126 m)."""
    return gain > 0 if new_ground else gain > MARGIN_SE * se


def aligned_distances(placed, frame, groups) -> np.ndarray:
    """(T,) the distance of every row of ``placed`` from that of ``frame`` ((T, 2) each) after
    the rows of each group (``groups``, (T,) labels) of ``frame`` are moved by their median
    offset."""
    d = np.asarray(placed, dtype=np.float64) - np.asarray(frame, dtype=np.float64)
    for g in np.unique(groups):
        rows = groups == g
        d[rows] -= np.median(d[rows], axis=0)
    return np.linalg.norm(d, axis=1)


def median_gap(places, views, stretch: int, draws: int = DRAWS,
               seed: int = 0) -> tuple[float, float]:
    """``(gap, se)``: the views' median distance less the places' (``views``, ``places``:
    (T,) distances in walking order) and its bootstrap standard error, stretches of ``stretch``
    consecutive steps drawn with replacement (one stretch: se infinite)."""
    places, views = np.asarray(places), np.asarray(views)
    gap = float(np.median(views) - np.median(places))
    starts = np.arange(0, places.size, max(int(stretch), 1))
    if starts.size < 2:
        return gap, float("inf")
    rng = np.random.default_rng(seed)
    stretches = np.split(np.arange(places.size), starts[1:])
    gaps = np.empty(draws)
    for i in range(draws):
        rows = np.concatenate([stretches[j] for j in rng.integers(0, starts.size, starts.size)])
        gaps[i] = np.median(views[rows]) - np.median(places[rows])
    return gap, float(np.std(gaps))
