"""The CPU seconds of the continuous fit with each check against the places alone, in one
process, the routes in turn (pairs under the same load).

    python benchmarks/bench_continuous_check_cost.py two_rooms:0 corridor:1 --repeats 3

``--fold-starts 3 2 1`` times instead the default check's own call (``cross_fitted``, captured
from one default fit and called again) with the k-means++ starts of its learned part's places
(the whole log's take the learner's ``n_init``, 3) at each count, in turn with the places alone,
and prints the cost as 1 + check / places per round and the verdict each count gives (the
default rule on its ``gap`` and ``se``).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

import bench_continuous as bc
from topomap import MapLearner
from topomap.core.motion import check as check_mod, crossfit
from topomap.core.motion.check import gives_way

ROUTES = {"places": {"check": {"holdout": 0}}, "bootstrap": {"check": {"rule": "bootstrap"}},
          "coverage": {"check": {"rule": "coverage"}}}


def _fit(train, ns, S, motion):
    return MapLearner(n_clusters=ns, n_states=S, refine="em", random_state=0,
                      motion=motion).fit(train.observations, train.actions,
                                         n_actions=train.n_actions)


def routes(w, train, ns, S, repeats):
    cpu = {r: [] for r in ROUTES}
    for _ in range(repeats):
        for r, motion in ROUTES.items():
            t = time.process_time()
            _fit(train, ns, S, motion)
            cpu[r].append(time.process_time() - t)
    base = np.array(cpu["places"])
    print(f"{w}: " + ", ".join(
        f"{r} {np.median(v):.2f} s ({np.median(np.array(v) / base):.2f}x; pairs "
        f"{', '.join(f'{x:.2f}' for x in np.array(v) / base)})" for r, v in cpu.items()),
        flush=True)


def fold_starts(w, train, ns, S, repeats, counts):
    got, call, cut = {}, check_mod.cross_fitted, crossfit.cut_places
    starts = {"n": None}

    def capture(*a, **k):
        got["args"], got["kw"] = a, k
        return call(*a, **k)

    def fold_cut(*a, **k):
        return cut(*a, **(k if starts["n"] is None else dict(k, n_init=starts["n"])))

    check_mod.cross_fitted, crossfit.cut_places = capture, fold_cut
    try:
        _fit(train, ns, S, {})  # the default fit: its check's arguments
        places, cpu, seen = [], {n: [] for n in counts}, {}
        for _ in range(repeats):
            t = time.process_time()
            _fit(train, ns, S, ROUTES["places"])
            places.append(time.process_time() - t)
            for n in counts:
                starts["n"] = n
                t = time.process_time()
                out = call(*got["args"], **got["kw"])
                cpu[n].append(time.process_time() - t)
                seen[n] = out
            starts["n"] = None
    finally:
        check_mod.cross_fitted, crossfit.cut_places = call, cut
    p, span = np.array(places), got["kw"].get("span") is not None
    print(f"{w}: places alone {np.median(p):.2f} s", flush=True)
    for n in counts:
        c, s = seen[n], 1 + np.array(cpu[n]) / p
        chosen = "views" if gives_way(c, "coverage", span) else "places"
        print(f"  {n} starts: check {np.median(cpu[n]):.2f} s, {np.median(s):.2f}x (rounds "
              f"{', '.join(f'{x:.2f}' for x in s)}); places {c['places']}, views "
              f"{c['views']}, z {c['gap'] / c['se']:+.2f} -> {chosen}", flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("walks", nargs="+", help="case:seed")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--fold-starts", type=int, nargs="+", metavar="N",
                   help="time the default check's call with its places at N starts instead")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    warnings.simplefilter("ignore")
    for w in a.walks:
        case, seed = w.split(":")
        _, train, _, ns, S = bc.walks(case, int(seed), bc.BASE, Path(a.cache))
        if a.fold_starts:
            fold_starts(w, train, ns, S, a.repeats, a.fold_starts)
        else:
            routes(w, train, ns, S, a.repeats)


if __name__ == "__main__":
    main()
