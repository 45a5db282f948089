"""Map quality and fit time of MapLearner on every world with ground truth.

    python benchmarks/bench_worlds.py                       # every world, T = 10,000 and 50,000
    python benchmarks/bench_worlds.py --worlds gridroom random_graph --sizes 10000 --repeats 1

For each world and walk length T: a random walk (seed 0) is simulated, Gaussian sensor noise
(``--sigma``, the app's default 0.01, seed 1) is added, and ``MapLearner`` is fitted with
``ns`` = the number of distinct noise-free observations of the world (its symbols) and the
stopping rule ``TargetStates`` set to the true number of places.  The table reports, against the
ground-truth places, ARI and NMI after phase 1 and after splitting, three diagnostics, and the fit
time (median of ``--repeats`` fits; phase 1 + phase 2, simulation excluded):

* ``ideal p1`` -- ARI of the labelling "state = true symbol": what a perfect phase 1 gives;
* ``sym ARI`` -- ARI of the phase-1 states against the true symbols (did K-means find them?);
* ``compound`` -- states holding steps of more than one place after splitting (of all states);
* ``spread`` -- places whose steps fall in more than one state after splitting (of all places).

Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from topomap import MapLearner
from topomap.worlds import GridRoom, MiniGridWorld, RandomGraphWorld
from topomap.worlds.explorers import RandomExplorer
from topomap.core.metrics import adjusted_rand, compound_states, nmi
from topomap.worlds.noise import GaussianNoise


def _symbolic(world):
    """True places, symbol of each place id (a dict) and ns, for gridroom / random_graph."""
    return world.n_places, dict(enumerate(world.place_symbols.tolist())), world.n_symbols


def _minigrid(world):
    places = world.reachable_places()
    views = np.array([world.observe(p) for p in places])
    _, sym = np.unique(views, axis=0, return_inverse=True)
    return places.size, dict(zip(places.tolist(), sym.ravel().tolist())), int(sym.max()) + 1


WORLDS = {
    "gridroom": ("gridroom 8x6, 4 symbols", lambda: GridRoom(8, 6, 4, seed=0), _symbolic),
    "gridroom_12x12": ("gridroom 12x12, 8 symbols", lambda: GridRoom(12, 12, 8, seed=0), _symbolic),
    "random_graph": ("random_graph 30 places, 20 symbols, 4 edges",
                     lambda: RandomGraphWorld(30, 4, 20, seed=0), _symbolic),
    "random_graph_60": ("random_graph 60 places, 15 symbols, 3 edges",
                        lambda: RandomGraphWorld(60, 3, 15, seed=0), _symbolic),
    "minigrid_empty": ("MiniGrid-Empty-8x8-v0", lambda: MiniGridWorld("MiniGrid-Empty-8x8-v0"),
                       _minigrid),
    "minigrid_fourrooms": ("MiniGrid-FourRooms-v0 (seed 0)",
                           lambda: MiniGridWorld("MiniGrid-FourRooms-v0"), _minigrid),
}


def bench(name, T, repeats, sigma):
    label, make, truth = WORLDS[name]
    world = make()
    n_places, symbol_of, ns = truth(world)
    traj = world.simulate(T, RandomExplorer(), np.random.default_rng(0))
    X = GaussianNoise(sigma).apply(traj.observations, np.random.default_rng(1))
    places = traj.places
    symbols = np.array([symbol_of[p] for p in places.tolist()])
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        learner = MapLearner(n_clusters=ns, n_states=n_places, random_state=0).fit(
            X, traj.actions, lengths=traj.lengths, n_actions=traj.n_actions)
        times.append(time.perf_counter() - t0)
    p1, p2 = learner.labels_phase1_, learner.labels_
    return {
        "world": label, "places": n_places, "ns": ns, "T": T,
        "visited": int(np.unique(places).size),
        "ari1": adjusted_rand(p1, places), "ari2": adjusted_rand(p2, places),
        "nmi1": nmi(p1, places), "nmi2": nmi(p2, places),
        "ideal": adjusted_rand(symbols, places), "sym": adjusted_rand(p1, symbols),
        "compound": compound_states(p2, places), "states": learner.map_.n_states,
        "spread": compound_states(places, p2),
        "fit": statistics.median(times),
    }


HEADER = ("| world | places | ns | T | visited | ARI p1 | ARI split | NMI p1 | NMI split | ideal p1 "
          "| sym ARI | compound | spread | fit s |")


def row(r):
    return (f"| {r['world']} | {r['places']} | {r['ns']} | {r['T']:,} | {r['visited']} | "
            f"{r['ari1']:.3f} | {r['ari2']:.3f} | {r['nmi1']:.3f} | {r['nmi2']:.3f} | "
            f"{r['ideal']:.3f} | {r['sym']:.3f} | {r['compound']}/{r['states']} | {r['spread']}/{r['places']} | {r['fit']:.2f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    ap.add_argument("--sizes", nargs="+", type=int, default=[10_000, 50_000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sigma", type=float, default=0.01)
    args = ap.parse_args()
    print(f"noise sigma {args.sigma}; fit time: median of {args.repeats}")
    print(HEADER)
    print("|" + "---|" * (HEADER.count("|") - 1))
    for name in args.worlds:
        for T in args.sizes:
            print(row(bench(name, T, args.repeats, args.sigma)), flush=True)


if __name__ == "__main__":
    main()
