"""Time and peak memory of MapLearner.fit on synthetic aliased worlds.

    python benchmarks/bench_fit.py            # both sizes, 5 repeats, medians
    python benchmarks/bench_fit.py --repeats 3 --sizes small

The world: ``n_places`` places on a random directed graph (every place has ``n_actions`` labelled
out-edges, one per action, so moves are deterministic), each place emitting one of ``ns`` symbols
(perceptual aliasing: ``n_places > ns``), each symbol a random point in 15-D plus Gaussian noise.
A random walk of ``T`` steps picks actions uniformly.  Peak memory is the tracemalloc peak of the
fit (numpy allocations included), measured in an extra untimed run.
"""

from __future__ import annotations

import argparse
import statistics
import time
import tracemalloc

import numpy as np

from topomap import MapLearner
from topomap.metrics import adjusted_rand

SIZES = {
    "small": dict(T=2_000, D=15, ns=20, n_places=30, n_actions=17),
    "large": dict(T=100_000, D=15, ns=50, n_places=100, n_actions=17),
}


def aliased_walk(T, D, ns, n_places, n_actions, seed=0):
    rng = np.random.default_rng(seed)
    succ = rng.integers(0, n_places, size=(n_places, n_actions))
    symbol = np.concatenate([np.arange(ns), rng.integers(0, ns, n_places - ns)])
    centres = rng.uniform(0, 1, size=(ns, D))
    actions = rng.integers(0, n_actions, size=T)
    places = np.empty(T, dtype=np.int64)
    p = 0
    for t in range(T):
        places[t] = p
        p = succ[p, actions[t]]
    X = centres[symbol[places]] + rng.normal(0, 0.02, size=(T, D))
    return X, actions, places


def run(name, repeats):
    cfg = SIZES[name]
    X, u, places = aliased_walk(cfg["T"], cfg["D"], cfg["ns"], cfg["n_places"], cfg["n_actions"])
    def fit():
        return MapLearner(n_clusters=cfg["ns"], n_states=cfg["n_places"], random_state=0).fit(X, u)

    rows = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        learner = fit()
        total = time.perf_counter() - t0
        rows.append((learner.timings_["phase1"], learner.timings_["phase2"], total))
    p1, p2, tot = (statistics.median(c) for c in zip(*rows))
    # memory in a run of its own: tracing every allocation slows the code it watches
    tracemalloc.start()
    fit()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    ari0 = adjusted_rand(places, learner.labels_phase1_)
    ari1 = adjusted_rand(places, learner.labels_)
    print(f"{name:6s} T={cfg['T']:>7,} D={cfg['D']} ns={cfg['ns']} -> {cfg['n_places']} states | "
          f"phase1 {p1:7.3f} s  phase2 {p2:7.3f} s  total {tot:7.3f} s  "
          f"peak {peak / 2**20:7.1f} MiB | ARI {ari0:.3f} -> {ari1:.3f}  (median of {repeats})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--sizes", nargs="+", default=list(SIZES), choices=list(SIZES))
    args = ap.parse_args()
    for name in args.sizes:
        run(name, args.repeats)


if __name__ == "__main__":
    main()
