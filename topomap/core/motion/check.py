"""The held-out check that decides between places and view clusters, on the log alone.

Places cut from views and odometry (:func:`~topomap.core.motion.places.cut_places`) beat the view
clusters where alike rooms are told apart by the way in, but can lose to them where alike views
carry no history worth the cost: in an open room, where the view alone places a step as well, a
place that straddles the noise of the odometry only adds it.  The default rule
(``check.rule="coverage"``, and ``"bootstrap"`` and ``"crossfit"``) is
:mod:`topomap.core.motion.crossfit`'s (:mod:`topomap.core.motion.coverage`); what
follows is the ``"folds"`` rule.  No positions are known, so the check asks the geometry the log has: both maps are learned on the first part of the log and
decode the rest (:meth:`~topomap.core.map.model.TopologicalMap.predict`, as any new walk); each
decoded state stands at the mean odometric position of its training steps; the odometric
positions of the held-out steps are the same filter run on
(:func:`~topomap.core.motion.odometry.odometric_positions`, its copies learned on the first part
and carried on).  What alike rooms cost the view clusters is a held-out step placed in the other
room: far off, not a little off.  So the check counts the held-out steps each map places more
than ``check.far`` cell extents from their odometric position (:func:`misplaced_share`),
among the held-out steps that joined a copy made before the held-out part: where the log's end
goes where its start had not been, the filter makes new copies there, whose positions neither
map was learned on (a fold where no step joined one gives no reference).
One held-out part is one draw of where the log happens to end; ``check.folds`` parts are held
out one after another from the end (each learned from the steps before it), and the places are
kept only when their share over the folds' held-out steps with a reference (:func:`pooled_shares`:
each such step counted once) is below the view clusters', at most
``check.margin`` times it and at least ``check.min_gain`` below it, or when most of the
last ``check.votes`` parts, each on its own, find the places' share ``check.min_gain``
below the view clusters' (:func:`outvoted`; a third part, learned from the first quarter
alone, is too weak to average in -- on Tanni's rat path its mean kept places that placed the
new walk 35 % farther off than the view clusters -- but not to vote); in doubt -- the two
alike, neither misplacing more than a few steps, or the carried-on filter lost and no
reference for either -- the view clusters stay.  The
median distance of each (:func:`frame_error`) is recorded beside: it weighs the many steps both
maps place within a cell, and fell back on every alcove layout where the places were better.
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import pairwise_distances_argmin

from ..size import split_holdout
from ..stats import majority_share
from .coverage import novel_span
from .crossfit import FOLD_STARTS, MARGIN_SE, cross_fitted
from .odometry import odometric_positions, reckoned_steps
from .places import Places, cut_places, graph_places
from .settings import MotionSettings

#: steps: the least a held-out part holds (a shorter log, or a fold that would leave fewer
#: before it, is not checked); a few dozen runs of one view at 10-50 Hz, not varied
MIN_PART = 100

__all__ = ["held_out_frame", "frame_error", "misplaced_rows", "misplaced_steps", "misplaced_share",
           "keeps_places", "outvoted", "pooled_shares", "gain_blocks", "gain_noise", "clears_noise",
           "tells_apart", "view_purity", "gives_way", "undecided", "part_before_last",
           "choose_places"]


def held_out_frame(settings: MotionSettings, part: Places, Z, u, lengths, cut: int):
    """``(P, joined)``: (T - cut, 2) odometric positions (cell extents) of the steps from
    ``cut`` on -- the filter of ``part`` (learned on the steps before ``cut``) carried on, each
    later step taking the view cluster of the nearest centre -- and (T - cut,) whether each of
    those steps joined a copy made before ``cut`` (a step that did not has no position the
    maps learned on the steps before ``cut`` could be measured against)."""
    k = int(part.views.max()) + 1
    centres = np.zeros((k, Z.shape[1]))
    np.add.at(centres, part.views, Z[:cut])
    centres /= np.maximum(np.bincount(part.views, minlength=k), 1)[:, None]
    later = pairwise_distances_argmin(Z[cut:], centres)
    fsym = np.concatenate([part.views, later])
    gate = settings.places.gates[len(settings.places.gates) // 2] * part.extent
    P, copy, _ = odometric_positions(fsym, reckoned_steps(u, lengths, part.V), lengths, gate,
                                     pull=settings.places.pull)
    return P[cut:] / part.extent, copy[cut:] <= copy[:cut].max()


def frame_error(placed, frame) -> float:
    """The median distance between ``placed`` and ``frame`` ((T, 2) arrays)."""
    return float(np.median(np.linalg.norm(placed - frame, axis=1)))


def misplaced_rows(placed, frame, far: float) -> np.ndarray:
    """Whether each row of ``placed`` stands more than ``far`` from that of ``frame``."""
    return np.linalg.norm(placed - frame, axis=1) > far


def misplaced_steps(placed, frame, far: float) -> int:
    """How many rows of ``placed`` stand more than ``far`` from those of ``frame``."""
    return int(np.count_nonzero(misplaced_rows(placed, frame, far)))


def misplaced_share(placed, frame, far: float) -> float:
    """The share of the rows of ``placed`` more than ``far`` from those of ``frame``."""
    return misplaced_steps(placed, frame, far) / len(placed)


def keeps_places(misplaced: dict, margin: float, min_gain: float = 0.0) -> bool:
    """Whether the places' misplaced share is below the view clusters', at most ``margin``
    times it, and at least ``min_gain`` below it (both none misplaced: in doubt, no; a few
    held-out steps either way, too: the held-out steps come in runs of one view, and a share
    of a hundredth is a handful of runs)."""
    return misplaced["places"] < misplaced["views"] and (
        misplaced["places"] <= margin * misplaced["views"]) and (
        misplaced["views"] - misplaced["places"] >= min_gain)


def outvoted(folds: list, votes: int, min_gain: float) -> bool:
    """Whether most of the first ``votes`` of ``folds`` (each a dict with ``misplaced`` shares),
    each on its own, find the places' share at least ``min_gain`` below the view clusters'
    (``votes`` 0, or fewer folds than ``votes``: no vote)."""
    if votes == 0 or len(folds) < votes:
        return False
    wins = sum(keeps_places(f["misplaced"], 1.0, min_gain) for f in folds[:votes])
    return 2 * wins > votes


def tells_apart(settings: MotionSettings, info: dict) -> bool:
    """Whether the odometry of a log told sightings of one view apart: its middle gate's
    filter (the check's frame) kept more than ``check.min_copies`` times as many copies as
    there are view clusters (``info`` of :func:`cut_places`).  Where it kept one copy per view
    cluster, no view was seen in two places at that gate, and the places can beat the view
    clusters in the check only by following the frame's own drift (poor odometry: six beams
    between pillars)."""
    copies = info["copies"][len(settings.places.gates) // 2]
    return copies > settings.check.min_copies * info["view_clusters"]


def view_purity(places, views) -> float:
    """The share of steps whose place's view cluster -- the one most of the place's steps have
    -- is their own (``places``, ``views``: (T,) labels): 1 where every
    place lies within one view cluster, low where the places cut across the views, the odometry
    and not the view deciding where a step belongs: the purity of the places with the view
    clusters as the truth (:func:`~topomap.core.stats.majority_share`)."""
    return majority_share(views, places)


def pooled_shares(folds: list) -> dict:
    """The misplaced shares of places and view clusters over all the held-out steps with a
    reference of ``folds`` (each a dict with ``misplaced_steps`` and ``referenced``): every such
    step counts once, so a fold where few held-out steps joined an earlier copy -- the log's
    end going where its start had not been -- weighs as little as the steps it could score."""
    referenced = sum(f["referenced"] for f in folds)
    return {name: round(sum(f["misplaced_steps"][name] for f in folds) / referenced, 4)
            for name in ("places", "views")}


def gain_blocks(places_far, views_far, block: int) -> list:
    """``[[steps, gain], ...]``: the held-out steps (boolean rows, each misplaced by the places
    and by the view clusters or not, in walking order) cut into stretches of ``block``
    consecutive steps (the last one shorter), each with how many more of its steps the view
    clusters misplace than the places."""
    gain = np.asarray(views_far, dtype=int) - np.asarray(places_far, dtype=int)
    return [[int(min(block, gain.size - s)), int(gain[s:s + block].sum())]
            for s in range(0, gain.size, block)]


def gain_noise(folds: list) -> tuple[float, float]:
    """``(gain, noise)`` over the stretches of all ``folds`` (each a dict with ``blocks``, of
    :func:`gain_blocks`): the views' misplaced share less the places' over all their steps, and
    its standard error from the spread of the stretches' gains about it (batch means: the
    stretches, not the steps, are the independent draws, since a step misplaced in the other
    room is followed by more); one stretch alone gives no spread (noise infinite)."""
    b = np.array([x for f in folds for x in f["blocks"]], dtype=float).reshape(-1, 2)
    n = b[:, 0].sum()
    if n == 0:
        return 0.0, float("inf")
    gain = b[:, 1].sum() / n
    if len(b) < 2:
        return float(gain), float("inf")
    spread = np.sum((b[:, 1] - b[:, 0] * gain) ** 2) * len(b) / (len(b) - 1)
    return float(gain), float(np.sqrt(spread) / n)


def clears_noise(gain: float, noise: float, confidence: float) -> bool:
    """Whether ``gain`` is more than ``confidence`` times ``noise`` (``confidence`` 0: no bar,
    even where one stretch left the noise unknown)."""
    return confidence == 0 or gain > confidence * noise


def _state_means(labels, frame) -> np.ndarray:
    counts = np.maximum(np.bincount(labels), 1)[:, None]
    return np.column_stack([np.bincount(labels, weights=frame[:, j]) for j in range(2)]) / counts


def _fold(settings: MotionSettings, X, Z, u, lengths, end: int, held: int, build,
          n_states: int, n_actions: int, *, block: int, **kmeans) -> dict | None:
    """The check on the steps before ``end``: places and view clusters learned on the steps
    before ``end - held``, decoding the ``held`` steps after them; None when the first part
    gives no odometry."""
    if end < len(u):
        lengths = split_holdout(len(u), lengths, 1 - end / len(u))[0]
        X, Z, u = X[:end], Z[:end], u[:end]
    head, tail, cut = split_holdout(end, lengths, held / end)
    part: Places = cut_places(settings, Z[:cut], u[:cut], head, n_states, n_actions, **kmeans)
    if part.places is None:
        return None
    frame, joined = held_out_frame(settings, part, Z, u, lengths, cut)
    if not joined.any():
        return None
    errors, misplaced, steps, far, referenced = {}, {}, {}, {}, int(joined.sum())
    for name, labels in (("places", part.places), ("views", part.views)):
        decoded = build(X[:cut], u[:cut], labels, head, pooled=name == "views").predict(
            X[cut:], u[cut:], lengths=tail)
        placed = _state_means(labels, part.frame)[decoded]
        errors[name] = round(frame_error(placed, frame), 4)
        far[name] = misplaced_rows(placed[joined], frame[joined], settings.check.far)
        steps[name] = int(np.count_nonzero(far[name]))
        misplaced[name] = round(steps[name] / referenced, 4)
    return {"learned": cut, "held_out": end - cut, "weight": part.info["weight"],
            "anchored": round(float(joined.mean()), 4),
            "referenced": referenced, **errors, "misplaced": misplaced,
            "misplaced_steps": steps, "blocks": gain_blocks(far["places"], far["views"], block)}


def choose_places(settings: MotionSettings, X, Z, u, lengths, n_states: int, n_actions: int,
                  build, **kmeans) -> tuple[np.ndarray, dict]:
    """``(labels, info)``: the places of the whole log (:func:`cut_places`), or its view clusters
    when the held-out check prefers them or finds no odometry.  ``build(X, u, labels, lengths)``
    makes a map of labelled steps (``pooled=True``: one variance shared by its states, the view
    clusters' map); ``kmeans``: ``n_init``, ``random_state``, ``method``.  Where the odometry is
    loose (:func:`~topomap.core.motion.places.position_weight`) and the places cut with the
    loose weight give way to the view clusters, the places cut with ``places.weight`` are
    checked in turn (on ``ring`` at 50 Hz, seed 0, those kept alike rooms apart where the loosely
    weighted ones did not); ``info["loose"]`` then says what the first try chose and why."""
    if settings.check.rule in ("crossfit", "bootstrap", "coverage"):
        return _crossfit(settings, X, Z, u, lengths, n_states, n_actions, build, **kmeans)
    labels, info = _choose(settings, X, Z, u, lengths, n_states, n_actions, build, **kmeans)
    weight = settings.places.weight
    if info["chosen"] == "places" or info.get("weight", weight) == weight:
        return labels, info
    labels2, info2 = _choose(settings, X, Z, u, lengths, n_states, n_actions, build,
                             weight=settings.places.weight, **kmeans)
    if info2["chosen"] != "places":
        return labels, info
    first = {k: info[k] for k in ("weight", "chosen", "check", "purity") if k in info}
    if isinstance(first.get("check"), dict):  # the first try's shares, not its folds
        first["check"] = {k: first["check"][k] for k in ("mean_misplaced", "outvoted")}
    return labels2, dict(info2, loose=first)


def _cut(settings: MotionSettings, Z, u, lengths, n_states: int, n_actions: int,
         **kmeans) -> tuple:
    """The places cut from the whole log, their info, and the choice already made (None: a
    check decides): the view clusters where no places were cut, the places where the log is too
    short to hold a part out (or ``holdout`` is 0), the view clusters where the odometry told no
    sighting of a view apart (:func:`tells_apart`: such places beat the view clusters in a check
    only by following the frame's drift; every rule)."""
    whole = cut_places(settings, Z, u, lengths, n_states, n_actions, **kmeans)
    info = dict(whole.info)
    if whole.places is None:
        return whole, info, (whole.views, dict(info, chosen="views"))
    T = len(u)
    holdout = settings.check.holdout
    if holdout == 0 or T * min(holdout, 1 - holdout) < MIN_PART:
        return whole, info, (whole.places, dict(info, chosen="places"))
    if not tells_apart(settings, info):
        return whole, info, (whole.views, dict(info, chosen="views",
                                               check="the middle gate kept one copy per view "
                                                     "cluster"))
    return whole, info, None


def gives_way(check: dict, rule: str, span: bool) -> bool:
    """Whether :func:`~topomap.core.motion.crossfit.cross_fitted`'s figures (``check``) give
    the places up for the view clusters under ``rule``: ``span`` (an earlier part held out in
    place of the last, ``"coverage"``), where the view clusters are nearer at all (``gap``
    below 0); ``"bootstrap"`` and ``"coverage"``, where ``gap`` is below
    -:data:`~topomap.core.motion.crossfit.MARGIN_SE` standard errors (``se``); ``"crossfit"``,
    where the places' error is not below the view clusters'."""
    if span:
        return check["gap"] < 0
    if rule in ("bootstrap", "coverage"):
        return check["gap"] < -MARGIN_SE * check["se"]
    return not check["places"] < check["views"]


def undecided(check: dict) -> bool:
    """Whether :func:`~topomap.core.motion.crossfit.cross_fitted`'s figures (``check``) leave
    the choice to a second held-out part under ``"coverage"``: the places kept, but the gap
    within :data:`~topomap.core.motion.crossfit.MARGIN_SE` standard errors either way (the
    last quarter tells the maps apart no better than its noise)."""
    return -MARGIN_SE * check["se"] <= check["gap"] < MARGIN_SE * check["se"]


def part_before_last(T: int, holdout: float) -> tuple[int, int]:
    """``(a, b)``: the steps of a log of ``T`` steps held out second under ``"coverage"`` --
    the ``holdout`` share just before the last (held out first)."""
    cut = split_holdout(T, [T], holdout)[2]  # where the last part starts
    return max(cut - (T - cut), 0), cut


def _crossfit(settings: MotionSettings, X, Z, u, lengths, n_states: int, n_actions: int,
              build, **kmeans) -> tuple[np.ndarray, dict]:
    """:func:`choose_places` by one rule: ``check.rule="bootstrap"``, the places unless the
    view clusters' held-out error is below theirs by more than
    :data:`~topomap.core.motion.crossfit.MARGIN_SE` standard errors (its ``gap`` and ``se``);
    ``"crossfit"``, the places where their error is below the view clusters'
    (:func:`~topomap.core.motion.crossfit.cross_fitted`'s figures); ``"coverage"``, as
    ``"bootstrap"`` but where a part of the log lies in places the rest of it seldom visits
    (:func:`~topomap.core.motion.coverage.novel_span`), that part held out instead of the last,
    the places kept only where the view clusters are no nearer there; elsewhere, where the last
    part keeps the places within the bar (:func:`undecided`), the part before it
    (:func:`part_before_last`, learned on the rest) held out too and deciding by the same bar
    (benchmarks/notes/continuous.md, "why `robot_three@0.3333` loses").  Every rule gives the
    view clusters unchecked where the odometry told no sighting of a view apart
    (:func:`tells_apart`): places cut from such odometry beat the view clusters in the check
    only by following the frame's drift (benchmarks/notes/continuous.md, "50 Hz").  Where the
    first part held out finds the pose graph's places standing in for the filter's
    (:func:`~topomap.core.motion.crossfit.stands_in`), they are weighed on the second part
    too, and kept, they are the whole log's (:func:`~topomap.core.motion.places.graph_places`;
    ``info["positions"]`` ``"graph"``)."""
    whole, info, done = _cut(settings, Z, u, lengths, n_states, n_actions, **kmeans)
    if done is not None:
        return done
    rule = settings.check.rule
    bootstrap = rule in ("bootstrap", "coverage")
    # under "coverage", the part of the log the rest seldom visits where there is one
    span = novel_span(whole.places, settings.check.holdout) if rule == "coverage" else None
    check = cross_fitted(settings, X, Z, u, lengths, n_states, n_actions, build,
                         starts=FOLD_STARTS if bootstrap else None, span=span,
                         new_ground=span is not None, weight=info["weight"], **kmeans)
    if check is None:
        return whole.views, dict(info, chosen="views",
                                  check="the held-out check's first part gave no odometry")
    lose = gives_way(check, rule, span is not None)
    if span is not None:  # on ground new to the rest: the places only where no farther off
        check = dict(check, rule=rule, span=list(span))
    elif bootstrap:
        check = dict(check, rule=rule)
    if rule == "coverage" and span is None and undecided(check):  # a second part asked
        before = part_before_last(len(u), settings.check.holdout)
        second = cross_fitted(settings, X, Z, u, lengths, n_states, n_actions, build,
                              starts=FOLD_STARTS, span=before, candidate=check.get("candidate"),
                              weight=info["weight"], **kmeans)
        if second is not None:
            lose = gives_way(second, rule, False)
            check = dict(check, second=dict(second, span=list(before)))
    chosen = "views" if lose else "places"
    if chosen == "views":
        return whole.views, dict(info, chosen=chosen, check=check)
    if check.get("candidate") == "graph":  # the pose graph's places stand in for the filter's
        return graph_places(settings, Z, whole, u, lengths, n_states,
                            **{k: kmeans[k] for k in ("n_init", "random_state", "method")
                               if k in kmeans}), dict(info, chosen=chosen, positions="graph",
                                                      check=check)
    return whole.places, dict(info, chosen=chosen, check=check)


def _choose(settings: MotionSettings, X, Z, u, lengths, n_states: int, n_actions: int,
            build, weight=None, **kmeans) -> tuple[np.ndarray, dict]:
    """:func:`choose_places` for one weight of the positions (None: the log's own)."""
    whole, info, done = _cut(settings, Z, u, lengths, n_states, n_actions, weight=weight,
                             **kmeans)
    if done is not None:
        return done
    purity = view_purity(whole.places, whole.views)
    if purity < settings.check.min_purity:
        return whole.views, dict(info, chosen="views", purity=round(purity, 4),
                                  check="the places cut across the view clusters")
    kmeans = dict(kmeans, weight=info["weight"])  # the held-out parts weigh as the whole log
    T = len(u)
    step = int(round(T * settings.check.holdout))
    block = max(1, int(round(settings.check.block_runs * info["mean_run"])))
    folds = []
    for i in range(max(settings.check.folds, settings.check.votes)):
        if T - (i + 1) * step < MIN_PART:
            break
        fold = _fold(settings, X, Z, u, lengths, T - i * step, step, build, n_states,
                     n_actions, block=block, **kmeans)
        if fold is None:
            break
        folds.append(fold)
    if not folds:
        return whole.views, dict(info, chosen="views",
                                  check="no held-out part with odometry and a reference")
    misplaced = pooled_shares(folds[:settings.check.folds])
    gain, noise = gain_noise(folds[:settings.check.folds])
    by_mean = keeps_places(misplaced, settings.check.margin, settings.check.min_gain) and (
        clears_noise(gain, noise, settings.check.confidence))
    by_vote = outvoted(folds, settings.check.votes, settings.check.min_gain)
    chosen = "places" if by_mean or by_vote else "views"
    info.update(chosen=chosen, check=dict(folds[0], folds=folds, mean_misplaced=misplaced,
                                          gain_noise=[round(gain, 4), round(noise, 4)],
                                          outvoted=by_vote))
    return (whole.places if chosen == "places" else whole.views), info
