"""Speed of the arena world: simulating and sensing against ratinabox's own motion loop.

    python benchmarks/bench_arena.py                 # every case, 3 repeats each
    python benchmarks/bench_arena.py --repeats 5 --cases agent arena

Cases (each repeat runs in a fresh process, so its peak RSS is its own):

* ``agent`` -- ratinabox alone: an ``Agent`` (dt 0.1 s) in the ``two_rooms`` layout's
  ``Environment`` takes 18,000 ``update()`` calls (30 minutes at 10 Hz); the loop is timed.
* ``arena`` -- ``ArenaWorld(layout="two_rooms", sensor=RangeFinder(12, 3.0)).simulate(18000)``:
  the same motion, plus the 12-beam range finder over all positions, the compass actions and the
  trajectory.  Target: at most 1.2 x ``agent``.
* ``tanni`` -- Tanni et al.'s 2-hour rat path read, resampled at 10 Hz (73,000 steps) and sensed
  by the range finder: ``ArenaWorld(path="tanni")`` built, then ``walk_from(0, 73000)``.  Target:
  at most 5 s.

Printed: per case the median seconds and peak RSS (MiB) over the repeats, and the ratio
arena / agent.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time

import numpy as np

N_STEPS = 18_000
TANNI_STEPS = 73_000


def run_case(case: str) -> dict:
    """Run one case in this process; returns seconds and peak RSS (MiB)."""
    from topomap.worlds.arena import ArenaWorld, RangeFinder, builtin_layout
    from topomap.worlds.arena.kinematics import isolated_global_rng

    if case == "agent":
        from ratinabox.Agent import Agent
        from ratinabox.Environment import Environment

        env = Environment(params=builtin_layout("two_rooms").environment_params())
        with isolated_global_rng(0):
            agent = Agent(env, params={"dt": 0.1})
            start = time.perf_counter()
            for _ in range(N_STEPS):
                agent.update()
            seconds = time.perf_counter() - start
    elif case == "arena":
        world = ArenaWorld(layout="two_rooms", sensor=RangeFinder(n_beams=12, max_range=3.0))
        start = time.perf_counter()
        world.simulate(N_STEPS, None, np.random.default_rng(0))
        seconds = time.perf_counter() - start
    elif case == "tanni":
        start = time.perf_counter()
        world = ArenaWorld(path="tanni", sensor=RangeFinder(n_beams=12, max_range=3.0))
        world.walk_from(0, TANNI_STEPS)
        seconds = time.perf_counter() - start
    else:
        raise ValueError(f"unknown case {case!r}")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return {"seconds": seconds, "peak_mib": peak}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=["agent", "arena", "tanni"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--case", help=argparse.SUPPRESS)  # one run, in a child process
    args = parser.parse_args()
    if args.case:
        print(json.dumps(run_case(args.case)))
        return
    medians = {}
    for case in args.cases:
        runs = [json.loads(subprocess.run([sys.executable, __file__, "--case", case],
                                          check=True, capture_output=True, text=True)
                           .stdout.strip().splitlines()[-1]) for _ in range(args.repeats)]
        medians[case] = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        print(f"{case:6s} {medians[case]['seconds']:7.2f} s  peak RSS "
              f"{medians[case]['peak_mib']:6.0f} MiB  (median of {args.repeats})", flush=True)
    if "agent" in medians and "arena" in medians:
        ratio = medians["arena"]["seconds"] / medians["agent"]["seconds"]
        print(f"arena / agent: {ratio:.2f} (target <= 1.2)")


if __name__ == "__main__":
    main()
