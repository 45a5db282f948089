"""A robot's fit with its wheel odometry beside the same fit without it: wall and CPU seconds,
peak RSS.

    python benchmarks/bench_robot_cost.py                        # robot_alike@0.3333 seed 0, 5 rounds
    python benchmarks/bench_robot_cost.py --plan robot_twin@0.3333 --seed 1 --rounds 7
    python benchmarks/bench_robot_cost.py --scans --rounds 3 \
        --robot speed_mean=0.1 wall_repel_distance=0.1 slip_size=0.03

Each round fits ``MapLearner(n_clusters=32, n_states=64, random_state=0)`` on the 18,000-step
walk of :mod:`robot_harness` without odometry (``motion={"scan_odometry": False}``: the view
clusters) and with ``odometry=`` (the order alternating between rounds, both in this process,
after one fit of each that compiles and warms the caches) and prints the medians and the ratio
with / without; the map each fit chose is printed first.  ``--scans``: the second fit is the
default without odometry instead, its odometry read from the scans.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import warnings
from pathlib import Path

import numpy as np

import robot_harness as H
from topomap import MapLearner


def _robot(changes) -> H.Robot:
    """The harness's robot with ``FIELD=VALUE`` changes (as ``bench_robots.py --robot``)."""
    from bench_robots import _robot as robot

    return robot(changes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", default="robot_alike@0.3333")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench/robots"))
    ap.add_argument("--scans", action="store_true",
                    help="time the default without odometry (odometry read from the scans)")
    ap.add_argument("--robot", nargs="*", default=[], metavar="FIELD=VALUE")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    walk, _ = H.pair(args.plan, args.seed, _robot(args.robot), Path(args.cache))
    t = walk.traj

    def fit(odometry: bool):
        """Without odometry and the scans' odometry off (the view clusters), or the second
        fit: with the wheel odometry, or (``--scans``) the default without it."""
        if not odometry:
            kw, motion = {}, {"scan_odometry": False}
        else:
            kw, motion = ({} if args.scans else {"odometry": walk.odometry}), "auto"
        return MapLearner(n_clusters=32, n_states=64, motion=motion, random_state=0).fit(
            t.observations, t.actions, n_actions=t.n_actions, **kw)

    for odometry in (False, True):
        print(f"odometry={odometry}: chosen {fit(odometry).motion_info_.get('chosen')}")
    times, loads = {False: [], True: []}, []
    for r in range(args.rounds):
        for odometry in ((False, True) if r % 2 == 0 else (True, False)):
            w, c = time.perf_counter(), time.process_time()
            fit(odometry)
            times[odometry].append((time.perf_counter() - w, time.process_time() - c))
        loads.append(os.getloadavg()[0])
    a, b = np.array(times[False]), np.array(times[True])
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    second = "with scans:" if args.scans else "with odometry:"
    for label, x in (("without odometry:", a), (second, b)):
        print(f"{label:17s} wall {np.median(x[:, 0]):.2f} s, CPU {np.median(x[:, 1]):.2f} s")
    print(f"with / without: wall {np.median(b[:, 0] / a[:, 0]):.2f}x, CPU "
          f"{np.median(b[:, 1] / a[:, 1]):.2f}x; peak RSS {rss:.0f} MiB; load "
          f"{min(loads):.2f}-{max(loads):.2f}")


if __name__ == "__main__":
    main()
