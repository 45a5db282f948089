"""A mixed map: the places where the held-out check finds them better, the view clusters where
it does not -- judged per view cluster, not for the whole map.

    python benchmarks/bench_continuous_mixed.py --log mixed.jsonl pillars:8:3 two_rooms:8:3

Each argument is ``case:setting:seed`` (``setting`` an index of ``bench_continuous.SETTINGS`` or
``base``). The default learner (``MapLearner(n_clusters, n_states, refine="em",
random_state=0)``) is fitted on the triple's cached training walk; where it kept its places,
the check's last ``motion.check.folds`` held-out parts are run again as
:mod:`topomap.core.motion.check` runs them (places and view clusters cut on the steps before
the part, at the positions' weight the whole log used, both decoding the part), and every
held-out step with a reference is counted against the view cluster the whole log gives it
(:func:`~topomap.core.motion.places.view_clusters`): how many more of its steps the view
clusters misplace than the places (``gain``). The mixed map labels every training step of a
view cluster whose gain is below zero (``neg``) -- or at most zero (``nonpos``) -- with that
view cluster, every other step with its place; each state its own Gaussian, counted on the raw
rows. ``neg_n`` keeps the state count: the places are cut again on the whole log, as many as
the view clusters ``neg`` hands back fewer, and the steps of those view clusters labelled with
them. Printed: the median error on the held-out walk of the default, of K-means on the views
(nearest centre) and of each mixed map, the view clusters each hands back, their training share
and the states.

Beside them, two measures of why the check kept the places:

* ``check_truth`` -- the check's held-out parts scored against the training walk's true
  positions (each state at the mean true position of its training steps in the part learned
  on): the median error of places and view clusters over those parts, and the pooled misplaced
  shares against the odometric frame at ``far`` 2 (the check's), 3, 4 and 6 cell extents. Where
  the truth and the frame disagree, the check's ruler -- the odometry the places were cut from
  -- misjudged; where both favour the places and the new walk does not, the training log's
  held-out parts and the new walk disagree;
* ``new_walk`` -- where on the new walk the places lose (:func:`new_walk_clusters`): per view
  cluster, a few or a smear.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
from sklearn.metrics import pairwise_distances_argmin

import bench_continuous as bc
from topomap.core.motion import MotionSettings
from topomap.core.motion.check import (_state_means, held_out_frame, misplaced_rows,
                                       misplaced_steps)
from topomap.core.motion.learn import pooled_variances
from topomap.core.motion.places import cut_places, view_clusters
from topomap.core.stats import label_means
from topomap.core.size import split_holdout

#: the check's ``far`` (cell extents) and wider ones: the pooled misplaced shares at each
FARS = (2.0, 3.0, 4.0, 6.0)


def _median(placed, truth) -> float:
    return round(float(np.median(np.linalg.norm(placed - truth, axis=1))), 4)


def cluster_gains(learner, X, u, P, n: int, vl) -> tuple[np.ndarray, np.ndarray, dict]:
    """``(gain, steps, truth)``: the gain and the held-out steps with a reference per view
    cluster of ``vl`` over the check's held-out parts, and the median true error (metres, ``P``
    the training walk's true positions) of places and view clusters over those parts' steps --
    the check's held-out parts scored against the truth instead of the odometric frame."""
    truth = {"places": [], "views": []}
    shares = {f: {"places": 0, "views": 0, "referenced": 0} for f in FARS}
    st, T = MotionSettings(), len(u)
    step = int(round(T * st.check.holdout))
    k = int(vl.max()) + 1
    gain, steps = np.zeros(k, dtype=int), np.zeros(k, dtype=int)
    kw = dict(n_init=learner.n_init, random_state=0, method=learner.phase1,
              weight=learner.motion_info_["weight"])
    for i in range(st.check.folds):
        end = T - i * step
        lengths = np.array([end])
        head, tail, cut = split_holdout(end, lengths, step / end)
        part = cut_places(st, X[:cut], u[:cut], head, n, learner.map_.n_actions, **kw)
        if part.places is None:  # as the check: a part without odometry ends the folds
            break
        frame, joined = held_out_frame(st, part, X[:end], u[:end], lengths, cut)
        far = {}
        for name, labels in (("places", part.places), ("views", part.views)):
            m = bc._own_gaussians(X[:cut], u[:cut], labels, learner.map_.n_actions)
            if name == "views":
                m = pooled_variances(m, X[:cut], labels, learner.reg_covar,
                                     st.places.fallback_variance)
            decoded = m.predict(X[cut:end], u[cut:end])
            placed = _state_means(labels, part.frame)[decoded]
            far[name] = misplaced_rows(placed[joined], frame[joined], st.check.far)
            for f in FARS:
                shares[f][name] += misplaced_steps(placed[joined], frame[joined], f)
            truth[name].append(np.linalg.norm(label_means(labels, P[:cut], int(labels.max()) + 1)
                                              [decoded] - P[cut:end], axis=1))
        c = vl[cut:end][joined]
        np.add.at(gain, c, far["views"].astype(int) - far["places"].astype(int))
        np.add.at(steps, c, 1)
        for f in FARS:
            shares[f]["referenced"] += int(joined.sum())
    truth = {k: round(float(np.median(np.concatenate(v))), 4) if v else None
             for k, v in truth.items()}
    truth["far"] = {str(f): {k: round(c[k] / max(c["referenced"], 1), 4)
                             for k in ("places", "views")} for f, c in shares.items()}
    return gain, steps, truth


def new_walk_clusters(placed, viewed, truth, nearest) -> dict:
    """Where on the new walk the places lose: per view cluster of the held-out steps (their
    nearest), the places' summed error less the views'; the share of steps in view clusters
    where the places lose, the share of the places' excess error they carry, and the median if
    the views placed those steps (a bound: it reads the truth)."""
    ep = np.linalg.norm(placed - truth, axis=1)
    ev = np.linalg.norm(viewed - truth, axis=1)
    k = int(nearest.max()) + 1
    excess = np.bincount(nearest, weights=ep - ev, minlength=k)
    lose = excess > 0
    worst = np.sort(excess[lose])[::-1]
    return {"lose_share": round(float(lose[nearest].mean()), 3),
            "clusters_lose": int(lose.sum()), "clusters": int(np.unique(nearest).size),
            "top3_of_excess": round(float(worst[:3].sum() / max(worst.sum(), 1e-12)), 3),
            "net_excess_m_per_step": round(float((ep - ev).mean()), 4),
            "bound": round(float(np.median(np.where(lose[nearest], ev, ep))), 4)}


def mixed(case: str, setting: str, seed: int, cache: Path) -> dict:
    s = dict(bc.BASE, **({} if setting == "base" else bc.SETTINGS[int(setting)]))
    world, train, held, ns, S = bc.walks(case, seed, s, cache)
    learner, _ = bc._fit(train, n_clusters=ns, n_states=S, random_state=0, refine="em")
    X, u, m = train.observations, train.actions, learner.map_
    spots = label_means(learner.labels_, train.positions, m.n_states)
    vl = view_clusters(X, m.n_states, MotionSettings().places.n_init, 0)
    vspots = label_means(vl, train.positions, m.n_states)
    nearest = pairwise_distances_argmin(held.observations, label_means(vl, X, m.n_states))
    row = {"case": case, "setting": bc.setting_name(s), "seed": seed,
           "chosen": learner.motion_info_["chosen"],
           "default": _median(spots[m.predict(held.observations, held.actions)], held.positions),
           "views": _median(vspots[nearest], held.positions)}
    if row["chosen"] != "places":
        return row
    row["new_walk"] = new_walk_clusters(spots[m.predict(held.observations, held.actions)],
                                        vspots[nearest], held.positions, nearest)
    gain, steps, row["check_truth"] = cluster_gains(learner, X, u, train.positions, m.n_states,
                                                     vl)
    row["gains"] = [[int(g), int(n)] for g, n in zip(gain, steps)]
    for name, bad in (("neg", gain < 0), ("nonpos", (gain <= 0) & (steps > 0)),
                      ("neg_n", gain < 0)):
        places = learner.labels_
        if name == "neg_n" and bad.any():  # as many states: fewer places cut beside them
            places = cut_places(MotionSettings(), X, u, [len(u)], m.n_states - int(bad.sum()),
                                m.n_actions, n_init=learner.n_init, random_state=0,
                                method=learner.phase1,
                                weight=learner.motion_info_["weight"]).places
        labels = np.where(bad[vl], m.n_states + vl, places)
        labels = np.unique(labels, return_inverse=True)[1]
        mm = bc._own_gaussians(X, u, labels, m.n_actions)
        ms = label_means(labels, train.positions, mm.n_states)
        row[name] = {"median": _median(ms[mm.predict(held.observations, held.actions)],
                                       held.positions),
                     "handed_back": int(bad.sum()), "share": round(float(bad[vl].mean()), 3),
                     "states": mm.n_states}
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("triples", nargs="+", help="case:setting:seed")
    p.add_argument("--log", default="mixed.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    done = bc.logged_triples(Path(a.log))
    for t in a.triples:
        case, setting, seed = t.split(":")
        if (case, setting, int(seed)) in done:
            continue
        row = {"triple": [case, setting, int(seed)], **mixed(case, setting, int(seed),
                                                              Path(a.cache))}
        with open(a.log, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(json.dumps({k: v for k, v in row.items() if k != "gains"}), flush=True)


if __name__ == "__main__":
    main()
