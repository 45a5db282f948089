"""The CPU seconds of the continuous fit with each check against the places alone, in one
process, the routes in turn (pairs under the same load).

    python benchmarks/bench_continuous_check_cost.py two_rooms:0 corridor:1 --repeats 3
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

ROUTES = {"places": {"check": {"holdout": 0}}, "bootstrap": {"check": {"rule": "bootstrap"}},
          "coverage": {"check": {"rule": "coverage"}}}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("walks", nargs="+", help="case:seed")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    a = p.parse_args()
    warnings.simplefilter("ignore")
    for w in a.walks:
        case, seed = w.split(":")
        _, train, _, ns, S = bc.walks(case, int(seed), bc.BASE, Path(a.cache))
        cpu = {r: [] for r in ROUTES}
        for _ in range(a.repeats):
            for r, motion in ROUTES.items():
                t = time.process_time()
                MapLearner(n_clusters=ns, n_states=S, refine="em", random_state=0,
                           motion=motion).fit(train.observations, train.actions,
                                              n_actions=train.n_actions)
                cpu[r].append(time.process_time() - t)
        base = np.array(cpu["places"])
        print(f"{w}: " + ", ".join(
            f"{r} {np.median(v):.2f} s ({np.median(np.array(v) / base):.2f}x; pairs "
            f"{', '.join(f'{x:.2f}' for x in np.array(v) / base)})" for r, v in cpu.items()),
            flush=True)


if __name__ == "__main__":
    main()
