"""Each quarter of a continuous log held out in turn, and how new its ground is to the rest.

    python benchmarks/bench_continuous_quarters.py --log quarters.jsonl corridor:1 l_rooms:1

Each argument is ``case:seed`` (the base setting, cached walks of ``bench_continuous``).  The
default learner is fitted (its ``choose_places`` arguments and the whole log's places captured);
then each quarter ``q`` of the training log is held out, places and view clusters learned again
on the other three (as :func:`topomap.core.motion.crossfit.cross_fitted` does on the first three,
the learned part two episodes where ``q`` is inside), both decoding ``q``; recorded per quarter:
the bootstrap gap and its standard error, both maps' median errors against the truth, and its
*novelty* -- the share of its steps in places of the whole log that hold at most ``RARE`` of
their steps outside it (ground the rest of the log barely visits).  Beside them: the new walk's
errors with the whole log's places and view clusters.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import bench_continuous as bc
from topomap import MapLearner
from topomap.core.motion import check as check_mod, learn as learn_mod
from topomap.core.motion.crossfit import (BLOCKS, FOLD_STARTS, STRETCH_RUNS, aligned_distances,
                                          median_gap, state_positions, translated_error)
from topomap.core.motion.places import cut_places
from topomap.core.motion.posegraph import graph_positions
from topomap.evaluation.metres import kmeans_view_scores, map_scores

#: share of a place's steps outside a quarter at most which the place counts as new to the rest
RARE = 0.1


def novelty(places, a, b, rare=RARE):
    """The share of the steps ``a:b`` in places holding at most ``rare`` of their steps
    elsewhere."""
    k = int(places.max()) + 1
    inside = np.bincount(places[a:b], minlength=k)
    total = np.bincount(places, minlength=k)
    new = (total - inside) <= rare * total
    return float(np.mean(new[places[a:b]]))


def capture_fit(train, ns, S):
    """The default fit, with the arguments of its ``choose_places`` and the whole log's places."""
    got = {}
    orig_choose, orig_cut = learn_mod.choose_places, check_mod._cut

    def choose(*a, **k):
        got["args"], got["kw"] = a, k
        return orig_choose(*a, **k)

    def cut(*a, **k):
        out = orig_cut(*a, **k)
        got["whole"] = out[0]
        return out

    learn_mod.choose_places, check_mod._cut = choose, cut
    try:
        t = time.process_time()
        learner = MapLearner(n_clusters=ns, n_states=S, refine="em", random_state=0).fit(
            train.observations, train.actions, n_actions=train.n_actions)
        cpu = time.process_time() - t
    finally:
        learn_mod.choose_places, check_mod._cut = orig_choose, orig_cut
    return learner, got, cpu


def quarter_fold(settings, X, Z, u, a, b, build, n_states, n_actions, P_true, **kmeans):
    T = len(u)
    keep = np.r_[0:a, b:T]
    head = np.array([n for n in (a, T - b) if n > 0])
    tail = np.array([b - a])
    fs = replace(settings, places=replace(settings.places, n_init=FOLD_STARTS))
    Zl, ul, Xl = Z[keep], u[keep], X[keep]
    part = cut_places(fs, Zl, ul, head, n_states, n_actions, **kmeans)
    if part.places is None:
        return None
    gate = settings.places.gates[len(settings.places.gates) // 2]
    learned = graph_positions(part.views, ul, head, part.V, part.extent, gate,
                              settings.places.pull)
    k = int(part.views.max()) + 1
    centres = np.zeros((k, Z.shape[1]))
    np.add.at(centres, part.views, Zl)
    centres /= np.maximum(np.bincount(part.views, minlength=k), 1)[:, None]
    from sklearn.metrics import pairwise_distances_argmin
    hv = pairwise_distances_argmin(Z[a:b], centres)
    heldP = graph_positions(hv, u[a:b], tail, part.V, part.extent, gate, settings.places.pull)
    block = (np.arange(a, b) * BLOCKS) // T
    out, dist = {"a": int(a), "b": int(b)}, {}
    for name, labels in (("places", part.places), ("views", part.views)):
        m = build(Xl, ul, labels, head, pooled=name == "views")
        decoded = m.predict(X[a:b], u[a:b], lengths=tail)
        placed = state_positions(labels, learned)[decoded]
        out[name] = round(translated_error(placed, heldP), 4)
        dist[name] = aligned_distances(placed, heldP, block)
        truth = state_positions(labels, P_true[keep])[decoded]
        out[f"{name}_truth"] = round(float(np.median(np.linalg.norm(truth - P_true[a:b],
                                                                     axis=1))), 4)
    gap, se = median_gap(dist["places"], dist["views"],
                         int(round(STRETCH_RUNS * part.info["mean_run"])),
                         seed=kmeans.get("random_state", 0))
    out.update(gap=round(gap, 4), se=round(se, 4), z=round(gap / se, 3) if se > 0 else None)
    return out


def probe(case, seed, cache, log):
    world, train, held, ns, S = bc.walks(case, seed, bc.BASE, cache)
    learner, got, cpu = capture_fit(train, ns, S)
    settings, X, Z, u, lengths, n_states, n_actions, build = got["args"]
    whole = got["whole"]
    regions = world.region_of
    row = {"case": case, "seed": seed, "cpu_default": round(cpu, 2),
           "chosen": learner.motion_info_["chosen"],
           "views_yardstick": kmeans_view_scores(S, train, held, regions,
                                                 random_state=0)["median_error"],
           "shipped": map_scores(learner.map_, learner.labels_, train, held,
                                 regions)["median_error"]}
    for name, labels in (("places", whole.places), ("views", whole.views)):
        if labels is not None:
            m = build(X, u, labels, lengths, pooled=name == "views")
            row[f"whole_{name}"] = map_scores(m, labels, train, held, regions)["median_error"]
    T = len(u)
    kw = dict(got["kw"], weight=whole.info.get("weight"))
    quarters = []
    for q in range(4):
        a, b = q * T // 4, (q + 1) * T // 4
        t = time.process_time()
        f = quarter_fold(settings, X, Z, u, a, b, build, n_states, n_actions, train.positions,
                         **kw)
        if f is not None:
            f["cpu"] = round(time.process_time() - t, 2)
            for r in (0.05, 0.1, 0.2):
                f[f"novelty_{r}"] = round(novelty(whole.places, a, b, r), 4)
        quarters.append(f)
    row["quarters"] = quarters
    with open(log, "a") as fh:
        fh.write(json.dumps(row) + "\n")
    print(f"{case:12s} s{seed} {row['chosen']:6s} shipped {row['shipped']:.3f} places "
          f"{row.get('whole_places', float('nan')):.3f} views {row['views_yardstick']:.3f} | "
          + " | ".join(f"q{i} z {f['z']:+.2f} nov {f['novelty_0.1']:.3f} truth "
                       f"{f['places_truth']:.3f}/{f['views_truth']:.3f}"
                       for i, f in enumerate(quarters) if f is not None), flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("walks", nargs="+", help="case:seed")
    p.add_argument("--log", default="quarters.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    claims = Path(a.log).with_suffix(".claims")
    claims.mkdir(exist_ok=True)
    for w in a.walks:
        case, seed = w.split(":")
        try:
            (claims / w.replace(":", "-")).touch(exist_ok=False)
        except FileExistsError:
            continue
        probe(case, int(seed), Path(a.cache), a.log)


if __name__ == "__main__":
    main()
