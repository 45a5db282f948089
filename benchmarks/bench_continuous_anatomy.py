"""Where the places lose to the view clusters on a new walk, and what a prediction that hedges
could win back.

    python benchmarks/bench_continuous_anatomy.py --log anatomy.jsonl three_rooms:8:3 corridor:base:1

Each argument is ``case:setting:seed`` (``setting`` an index of ``bench_continuous.SETTINGS`` or
``base``). The default learner (``MapLearner(n_clusters, n_states, refine="em",
random_state=0)``) and K-means on the views (as many clusters, ``n_init=4``,
``random_state=0``: the yardstick) are learned on the triple's cached training walk, as
``bench_continuous.py`` does; each held-out step is placed at its state's (cluster's) mean
training position, and a state's region is the region most of its training steps lie in.

Anatomy (every triple): the median error of both; the share of held-out steps each places in
the wrong region; the medians over the steps both place in the right region (the smear inside
a region); and per region its share of the training and of the held-out steps, with both
medians and wrong-region shares there.

``--weights W ...``: the unchecked places of the whole log cut with each positions' weight
``W`` (``motion.places.weight``), their purity, and their map decoded with one pooled variance
(scale 1 and 0.1), beside K-means on the views.

Probes (where the check kept the places; ``purity`` -- the share of training steps whose place's
view cluster is their own; ``view clusters`` are the fallback's own,
:func:`~topomap.core.motion.places.view_clusters` on the training views, each place taken as the
view cluster most of its training steps have):

* ``unsure``: the share of held-out steps whose posterior (forward-backward on the places) puts
  less than 0.99 on any one view cluster, and the median error if those steps took the view
  clusters' placement instead (a bound: the rule would have to answer with a place);
* ``differs``: the same bound where the decoded place's view cluster is not the step's nearest;
* ``windows``: the correlation over 60-second stretches of the held-out walk between the
  places' log-likelihood per step less the view clusters' (each its own Gaussian) and the
  places' median error less the views';
* ``pooled_small``: places with fewer training steps than 0.75 times the mean handed back to the
  view clusters (their steps labelled with their view cluster, the map counted again): the
  median error and the number of states.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
from sklearn.cluster import KMeans
from sklearn.metrics import pairwise_distances_argmin

import bench_continuous as bc
from topomap.core.motion import MotionSettings
from topomap.core.motion.check import view_purity
from topomap.core.motion.places import view_clusters
from topomap.core.stats import label_means
from topomap.evaluation.metres import _majority

WINDOW_S = 60.0


def _median(placed, truth) -> float:
    return round(float(np.median(np.linalg.norm(placed - truth, axis=1))), 4)


def _regions(rt, rh, truth, train_units, held_units, placed, n):
    """Per region: training and held-out shares, both maps' medians and wrong shares."""
    rows = []
    for g in range(int(max(rt.max(), rh.max())) + 1):
        here = rh == g
        if not here.any():
            continue
        row = {"region": g, "train": round(float(np.mean(rt == g)), 3),
               "held": round(float(here.mean()), 3)}
        for name, units, hu in (("places", train_units[0], held_units[0]),
                                ("views", train_units[1], held_units[1])):
            wrong = _majority(units, rt, n)[hu] != rh
            row[name] = _median(placed[name][here], truth[here])
            row[f"wrong_{name}"] = round(float(wrong[here].mean()), 3)
        rows.append(row)
    return rows


def anatomy(case: str, setting: str, seed: int, cache: Path) -> dict:
    s = dict(bc.BASE, **({} if setting == "base" else bc.SETTINGS[int(setting)]))
    world, train, held, ns, S = bc.walks(case, seed, s, cache)
    rt, rh = world.region_of(train.positions), world.region_of(held.positions)
    learner, _ = bc._fit(train, n_clusters=ns, n_states=S, random_state=0, refine="em")
    states = learner.map_.predict(held.observations, held.actions)
    km = KMeans(S, n_init=4, random_state=0).fit(train.observations)
    kh = km.predict(held.observations)
    placed = {"places": label_means(learner.labels_, train.positions, learner.map_.n_states)[states],
              "views": label_means(km.labels_, train.positions, S)[kh]}
    n = max(learner.map_.n_states, S)
    regions = _regions(rt, rh, held.positions, (learner.labels_, km.labels_), (states, kh),
                       placed, n)
    wp = _majority(learner.labels_, rt, n)[states] != rh
    wv = _majority(km.labels_, rt, n)[kh] != rh
    both = ~wp & ~wv
    row = {"case": case, "setting": bc.setting_name(s), "seed": seed,
           "chosen": learner.motion_info_["chosen"], "copies": learner.motion_info_.get("copies"),
           "places": _median(placed["places"], held.positions),
           "views": _median(placed["views"], held.positions),
           "wrong_places": round(float(wp.mean()), 3), "wrong_views": round(float(wv.mean()), 3),
           "both_right": round(float(both.mean()), 3),
           "both_right_places": _median(placed["places"][both], held.positions[both]),
           "both_right_views": _median(placed["views"][both], held.positions[both]),
           "regions": regions}
    if row["chosen"] == "places":
        row["probes"] = probes(learner, train, held, S, states, placed, s["dt"])
    return row


def probes(learner, train, held, S, states, placed, dt) -> dict:
    """The four probes of the module docstring on one fit that kept its places."""
    m, X, Xh, uh = learner.map_, train.observations, held.observations, held.actions
    vl = view_clusters(X, S, MotionSettings().places.n_init, 0)
    centres = label_means(vl, X, S)
    vh = pairwise_distances_argmin(Xh, centres)
    cluster_of = _majority(learner.labels_, vl, m.n_states)
    G = m.predict_proba(Xh, uh)
    mass = np.zeros((Xh.shape[0], S))
    np.add.at(mass.T, cluster_of, G.T)
    viewed = label_means(vl, train.positions, S)[vh]
    out = {"purity": round(view_purity(learner.labels_, vl), 3)}
    for name, hedge in (("unsure", mass.max(axis=1) < 0.99), ("differs", cluster_of[states] != vh)):
        mixed = np.where(hedge[:, None], viewed, placed["places"])
        out[name] = {"share": round(float(hedge.mean()), 3),
                     "bound": _median(mixed, held.positions)}
    out["windows"] = _windows(m, vl, train, held, placed, dt)
    n = np.bincount(learner.labels_, minlength=m.n_states)
    small = n < 0.75 * n.mean()
    labels = np.where(small[learner.labels_], m.n_states + vl, learner.labels_)
    labels = np.unique(labels, return_inverse=True)[1]
    pooled = bc._own_gaussians(X, train.actions, labels, m.n_actions)
    spots = label_means(labels, train.positions, pooled.n_states)
    out["pooled_small"] = {"handed_back": int(small.sum()), "states": pooled.n_states,
                           "median": _median(spots[pooled.predict(Xh, uh)], held.positions)}
    return out


def _windows(m, vl, train, held, placed, dt) -> float:
    """Correlation over the held-out walk's stretches: likelihood gain against error gain."""
    own = bc._own_gaussians(train.observations, train.actions, vl, m.n_actions)
    w = int(round(WINDOW_S / dt))
    gains, losses = [], []
    for a in range(0, len(held) - w + 1, w):
        sl = slice(a, a + w)
        Xw, uw = held.observations[sl], held.actions[sl]
        gains.append(m.score(Xw, uw) - own.score(Xw, uw))
        losses.append(_median(placed["places"][sl], held.positions[sl])
                      - _median(placed["views"][sl], held.positions[sl]))
    return round(float(np.corrcoef(gains, losses)[0, 1]), 3)


def purity(case: str, setting: str, seed: int, cache: Path) -> dict:
    """The places' ``purity`` alone: the places of the whole log, unchecked
    (``MotionSettings(check={"holdout": 0})``: the places the check decides on), against the view
    clusters."""

    s = dict(bc.BASE, **({} if setting == "base" else bc.SETTINGS[int(setting)]))
    _, train, _, ns, S = bc.walks(case, seed, s, cache)
    learner, _ = bc._fit(train, n_clusters=ns, n_states=S, random_state=0, refine="em",
                         motion=MotionSettings(check={"holdout": 0}))
    vl = view_clusters(train.observations, S, MotionSettings().places.n_init, 0)
    return {"case": case, "setting": bc.setting_name(s), "seed": seed,
            "chosen": learner.motion_info_["chosen"],
            "purity": round(view_purity(learner.labels_, vl), 3)}


def weights(case: str, setting: str, seed: int, cache: Path, ws) -> dict:
    """The places of the whole log, unchecked (``MotionSettings(check={"holdout": 0})``), cut
    with each positions' weight of ``ws`` (the loose weight too): each weight's median error,
    the places' ``purity``, and the median error when the places' map decodes with one variance
    shared by its states (:func:`~topomap.core.motion.learn.pooled_variances`, scale 1 and 0.1:
    the view likelihood weighed more against the transitions)."""
    from topomap.core.motion.learn import pooled_variances

    s = dict(bc.BASE, **({} if setting == "base" else bc.SETTINGS[int(setting)]))
    _, train, held, ns, S = bc.walks(case, seed, s, cache)
    km = KMeans(S, n_init=4, random_state=0).fit(train.observations)
    row = {"case": case, "setting": bc.setting_name(s), "seed": seed,
           "views": _median(label_means(km.labels_, train.positions, S)[
               km.predict(held.observations)], held.positions)}
    vl = view_clusters(train.observations, S, MotionSettings().places.n_init, 0)
    for w in ws:
        learner, _ = bc._fit(train, n_clusters=ns, n_states=S, random_state=0, refine="em",
                             motion=MotionSettings(check={"holdout": 0},
                                                   places={"weight": w, "loose_weight": w}))
        m, labels = learner.map_, learner.labels_
        spots = label_means(labels, train.positions, m.n_states)
        r = {"places": _median(spots[m.predict(held.observations, held.actions)],
                               held.positions),
             "purity": round(view_purity(labels, vl), 3)}
        for scale in (1.0, 0.1):
            pm = pooled_variances(m, train.observations, labels, learner.reg_covar, scale)
            r[f"pooled{scale:g}"] = _median(spots[pm.predict(held.observations, held.actions)],
                                            held.positions)
        row[f"weight{w:g}"] = r
    return row


def _seldom(row) -> str:
    """Held-out share in regions trained on less than half their held-out share, and both
    maps' medians there (weighted by the held-out steps)."""
    rows = [g for g in row["regions"] if g["train"] < 0.5 * g["held"]]
    if not rows:
        return "0 | | "
    w = np.array([g["held"] for g in rows])
    p = np.array([g["places"] for g in rows])
    v = np.array([g["views"] for g in rows])
    return f"{w.sum():.2f} | {np.average(p, weights=w):.3f} | {np.average(v, weights=w):.3f}"


def print_table(log: Path) -> None:
    """One Markdown row per triple of ``log``."""
    print("| triple | chosen | places / views, m | wrong region, places / views | both right: "
          "places / views, m | seldom-trained share | there: places | there: views | "
          "unsure (bound) | differs (bound) | windows | pooled_small (states) |")
    print("|" + "---|" * 12)
    for line in log.read_text().splitlines():
        r = json.loads(line)
        head = (f"| `{r['case']}` {r['setting']} s{r['seed']} | {r['chosen']} | "
                f"{r['places']:.3f} / {r['views']:.3f} | {r['wrong_places']:.2f} / "
                f"{r['wrong_views']:.2f} | {r['both_right_places']:.3f} / "
                f"{r['both_right_views']:.3f} | {_seldom(r)} | ")
        q = r.get("probes")
        tail = " | | | |" if q is None else (
            f"{q['unsure']['share']:.2f} ({q['unsure']['bound']:.3f}) | "
            f"{q['differs']['share']:.2f} ({q['differs']['bound']:.3f}) | {q['windows']:.2f} | "
            f"{q['pooled_small']['median']:.3f} ({q['pooled_small']['states']}) |")
        print(head + tail)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("triples", nargs="*", help="case:setting:seed")
    p.add_argument("--table", action="store_true", help="print the log's rows as a table")
    p.add_argument("--purity", action="store_true",
                   help="the places' purity alone (a fit without the check), no anatomy")
    p.add_argument("--weights", nargs="+", type=float, default=None, metavar="W",
                   help="the unchecked places cut with each of these positions' weights")
    p.add_argument("--log", default="anatomy.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    if a.table:
        print_table(Path(a.log))
        return
    done = bc.logged_triples(Path(a.log))
    for t in a.triples:
        case, setting, seed = t.split(":")
        if (case, setting, int(seed)) in done:
            continue
        if a.weights:
            body = weights(case, setting, int(seed), Path(a.cache), a.weights)
        else:
            body = (purity if a.purity else anatomy)(case, setting, int(seed), Path(a.cache))
        row = {"triple": [case, setting, int(seed)], **body}
        with open(a.log, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(json.dumps({k: v for k, v in row.items() if k != "regions"}), flush=True)


if __name__ == "__main__":
    main()
