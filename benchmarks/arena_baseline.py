"""Where maps learned from continuous streams stand today: errors in metres in the arena.

    python benchmarks/arena_baseline.py                      # all three cases, one seed
    python benchmarks/arena_baseline.py --cases two_rooms --no-em

Cases (12 compass-aligned range beams, max range 3 m, plus N(0, 0.02^2) noise; 10 Hz):

* ``two_rooms``, ``four_rooms`` -- 18,000 steps (30 minutes) of ratinabox's random motion
  (its defaults) to learn from, and a held-out walk of 6,000 steps from another seed;
  ``MapLearner(n_clusters=32, n_states=64)``;
* ``tanni`` -- Tanni et al.'s rat path (3.5 x 2.5 m): its first 75 % to learn, the rest held
  out; ``MapLearner(n_clusters=50, n_states=100)``.

Rows: the map after the split, the map refined with ``refine="em"``, the ceiling (the true places
in topomap's model class) and K-means on the views (as many clusters as the map has states), each
scored by :mod:`topomap.evaluation.metres`: median and 90th-percentile error (metres) and the
share of held-out steps placed in the wrong region; fit times in seconds.  Results are appended as
JSON lines to ``--log``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from topomap import MapLearner
from topomap.evaluation.metres import ceiling_scores, kmeans_view_scores, map_scores
from topomap.worlds.arena import ArenaWorld, RangeFinder
from topomap.worlds.noise import GaussianNoise

SIGMA = 0.02


def _noisy(traj, seed: int):
    traj.observations = GaussianNoise(SIGMA).apply(traj.observations, np.random.default_rng(seed))
    return traj


def data(case: str, seed: int):
    """``(world, train, heldout, ns, n_states)`` of a case."""
    sensor = RangeFinder(n_beams=12, max_range=3.0)
    if case == "tanni":
        world = ArenaWorld(path="tanni", sensor=sensor)
        n = world.path_steps
        cut = int(0.75 * n)
        return (world, _noisy(world.walk_from(0, cut), seed + 100),
                _noisy(world.walk_from(cut, n - cut), seed + 101), 50, 100)
    world = ArenaWorld(layout=case, sensor=sensor)
    train = world.simulate(18_000, None, np.random.default_rng(seed))
    held = world.simulate(6_000, None, np.random.default_rng(seed + 1000))
    return world, _noisy(train, seed + 100), _noisy(held, seed + 101), 32, 64


def run(case: str, seed: int, em: bool) -> list[dict]:
    world, train, held, ns, S = data(case, seed)
    rows = []
    for refine in ([None, "em"] if em else [None]):
        start = time.perf_counter()
        learner = MapLearner(n_clusters=ns, n_states=S, refine=refine, random_state=seed)
        learner.fit_trajectory(train)
        seconds = time.perf_counter() - start
        scores = map_scores(learner.map_, learner.labels_, train, held, world.region_of)
        rows.append({"model": f"map, {'split + em' if refine else 'split'}",
                     "states": learner.map_.n_states, "fit_s": round(seconds, 1), **scores})
        if refine is None:
            split = learner
    rows.append({"model": "ceiling", "states": S, **ceiling_scores(
        split.map_, split.labels_, train, held, world.region_of, random_state=seed)})
    rows.append({"model": "K-means on views", "states": S, **kmeans_view_scores(
        S, train, held, world.region_of, random_state=seed)})
    return [{"case": case, "seed": seed, "train": len(train), "heldout": len(held), **r}
            for r in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["two_rooms", "four_rooms", "tanni"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-em", action="store_true")
    parser.add_argument("--log", default="arena_baseline.jsonl")
    args = parser.parse_args()
    for case in args.cases:
        for row in run(case, args.seed, not args.no_em):
            print(f"{row['case']:10s} {row['model']:18s} {row['states']:4d} states  median "
                  f"{row['median_error']:.3f} m  p90 {row['p90_error']:.3f} m  wrong region "
                  f"{row['wrong_region']:.3f}  {row.get('fit_s', '')}", flush=True)
            with open(args.log, "a") as fh:
                fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
