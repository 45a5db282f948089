"""Choosing the number of states: the size ``stop=auto`` picks, by criterion, in every world.

    python benchmarks/bench_auto.py                          # every world, 3 seeds, T = 10,000
    python benchmarks/bench_auto.py --worlds office gridroom --seeds 0 --steps 2000

For each world and seed: a random walk is simulated (that seed), Gaussian sensor noise (sigma
0.01, seed + 100) is added, and ``MapLearner`` is fitted with ``ns`` = the world's number of
symbols (20 in the office, as in the paper) and

* ``told`` -- the true number of places as the target (``TargetStates``), the reference;
* ``heldout`` / ``bic`` -- ``AutoStates(criterion)``: the size chosen from the split sizes,

each without and with the refinement (``refine="em"``).  The table gives the medians over the
seeds of the number of states after the split (the chosen size) and at the end, the ARI against
the true places, and the fit time (phase 1 + the size choice + the split + the refinement).
Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from bench_worlds import WORLDS as GROUND_TRUTH_WORLDS

from topomap import MapLearner
from topomap.core.auto import AutoStates
from topomap.core.metrics import adjusted_rand
from topomap.worlds import OfficeWorld
from topomap.worlds.explorers import RandomExplorer
from topomap.worlds.noise import GaussianNoise

WORLDS = {"office": ("office (the paper's layout)", OfficeWorld, lambda w: (w.n_places, 20))}
for _name, (_label, _make, _truth) in GROUND_TRUTH_WORLDS.items():
    WORLDS[_name] = (_label, _make, lambda w, truth=_truth: truth(w)[::2])
RULES = ("told", "heldout", "bic")


def fit(world, n_places, ns, seed, T, rule, refine):
    traj = world.simulate(T, RandomExplorer(), np.random.default_rng(seed))
    X = GaussianNoise(0.01).apply(traj.observations, np.random.default_rng(seed + 100))
    stopping = None if rule == "told" else AutoStates(rule)
    t0 = time.perf_counter()
    learner = MapLearner(n_clusters=ns, n_states=n_places, stopping=stopping, refine=refine,
                         random_state=seed).fit(X, traj.actions, gds=traj.gds,
                                                lengths=traj.lengths, n_actions=traj.n_actions)
    seconds = time.perf_counter() - t0
    split = learner.map_split_ if refine else learner.map_
    return {"split": split.n_states, "final": learner.map_.n_states, "seconds": seconds,
            "ari": adjusted_rand(learner.labels_, traj.places)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--steps", type=int, default=10_000)
    args = ap.parse_args()
    fit(WORLDS["office"][1](), 29, 20, 0, 500, "heldout", "em")  # compile the kernels first
    print(f"T = {args.steps:,}, medians over seeds {args.seeds}")
    print("| world | places | refine | rule | states after split (each seed) | final states | ARI | fit s |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.worlds:
        label, make, truth = WORLDS[name]
        world = make()
        n_places, ns = truth(world)
        for refine in (None, "em"):
            for rule in RULES:
                runs = [fit(world, n_places, ns, s, args.steps, rule, refine) for s in args.seeds]
                med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
                every = "/".join(str(r["split"]) for r in runs)
                print(f"| {label} | {n_places} | {refine or 'none'} | {rule} | {every} | "
                      f"{med['final']:g} | {med['ari']:.3f} | {med['seconds']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
