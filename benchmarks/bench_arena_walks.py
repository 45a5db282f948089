"""How ratinabox's random motion (the arena's defaults, 10 Hz) covers floor plans.

Two measurements behind two of the arena's constants:

``coverage``
    for each built-in layout and seed, the step by which the walk has entered every region and
    the smallest region's share of the steps after 2,000 ... 24,000 steps: the arena's default
    walk (``ArenaWorld.default_steps``).
``doors``
    a 2 x 1 m box cut by a wall with one door in its middle: how often a 30-minute walk crosses
    doors 0.01 ... 0.3 m wide: the narrowest passage a floor plan may have
    (``topomap.worlds.arena.walkable.MIN_PASSAGE``).

    python benchmarks/bench_arena_walks.py coverage --seeds 3
    python benchmarks/bench_arena_walks.py doors --seeds 2
"""

from __future__ import annotations

import argparse

import numpy as np

from topomap.worlds.arena import LAYOUTS, ArenaWorld, Layout
from topomap.worlds.arena.layouts import _box, _wall

LENGTHS = (2000, 6000, 12000, 18000, 24000)
DOORS = (0.01, 0.03, 0.05, 0.1, 0.3)


def coverage(seeds: int) -> None:
    for name in LAYOUTS:
        world = ArenaWorld(layout=name)
        for seed in range(seeds):
            traj = world.simulate(max(LENGTHS), None, np.random.default_rng(seed))
            regions = world.region_of(traj.positions)
            firsts = [np.flatnonzero(regions == r) for r in range(len(world.region_names))]
            every = None if any(f.size == 0 for f in firsts) else max(int(f[0]) for f in firsts)
            least = {n: float(np.bincount(regions[:n], minlength=len(firsts)).min() / n)
                     for n in LENGTHS}
            print(f"{name:11s} seed {seed}: every region entered by step {every}; smallest "
                  "region's share " + ", ".join(f"{n}: {v:.3f}" for n, v in least.items()),
                  flush=True)


def doors(seeds: int) -> None:
    for width in DOORS:
        plan = Layout(f"door{width}", _box(0, 0, 2, 1), walls=_wall([1, 0], [1, 1],
                                                                     [(0.5, width)]))
        world = ArenaWorld(layout=plan)
        crossings = []
        for seed in range(seeds):
            side = world.simulate(18000, None, np.random.default_rng(seed)).positions[:, 0] > 1
            crossings.append(int(np.abs(np.diff(side.astype(int))).sum()))
        print(f"door {width:.2f} m: crossings in 30 min {crossings}", flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=["coverage", "doors"])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    coverage(args.seeds) if args.what == "coverage" else doors(args.seeds)
