"""The robot route with the beams numbered as a robot's driver may number them: the error of
the default fit with wheel odometry (the harness's robot at a rat's scale, ``Robot.small()``,
the walks of ``bench_robots.py --robot speed_mean=0.1 wall_repel_distance=0.1
slip_size=0.03``) on scans in the route's order (beam 0 ahead, anticlockwise), reversed
(clockwise), and starting behind the robot (``angle_min = -pi``).

    python benchmarks/bench_robot_beams.py                            # robot_alike@0.3333 seed 0
    python benchmarks/bench_robot_beams.py --plans robot_alike@0.3333 robot_office@0.3333 --seeds 0 1

Each case fits ``MapLearner(n_clusters=32, n_states=64, random_state=0).fit(X, u,
odometry=...)`` on the 18,000-step walk of :mod:`robot_harness` with the columns of its scans
(and its held-out walk's) reordered, places the held-out walk with ``predict``
(``--no-odometry``: neither the fit nor ``predict`` is given the odometry) and prints the map
chosen, the order :mod:`topomap.core.motion.beams` found, the median distance of the held-out
steps from the truth [m] and the share in the wrong room.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

import numpy as np

import robot_harness as H
from topomap import MapLearner
from topomap.evaluation.metres import score_units

ORDERS = {
    "in order": lambda B: np.arange(B),
    "clockwise": lambda B: np.arange(B)[::-1],
    "from -pi": lambda B: np.roll(np.arange(B), B // 2),
    "clockwise from -pi": lambda B: np.roll(np.arange(B)[::-1], B // 2),
}


def run(plan: str, seed: int, orders, cache: Path, odometry: bool = True) -> None:
    walk, held = H.pair(plan, seed, H.Robot.small(), cache)
    t, h = walk.traj, held.traj
    regions = H.region_of(plan)
    for name in orders:
        cols = ORDERS[name](t.observations.shape[1])
        given = {"odometry": walk.odometry} if odometry else {}
        learner = MapLearner(n_clusters=32, n_states=64, random_state=0).fit(
            t.observations[:, cols], t.actions, n_actions=t.n_actions, **given)
        info = learner.motion_info_
        placed_on_cells = getattr(learner, "robot_map_", None) is not None
        extra = {"odometry": held.odometry} if placed_on_cells and odometry else {}
        placed = learner.predict(h.observations[:, cols], h.actions, **extra)
        s = score_units(learner.labels_, t.positions, placed, h.positions,
                        learner.map_.n_states, (regions(t.positions), regions(h.positions)))
        print(f"| {plan} | {seed} | {name} | {info.get('chosen')} | {info.get('beams', '-')} | "
              f"{s['median_error']:.3f} | {s['wrong_region']:.1%} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plans", nargs="+", default=["robot_alike@0.3333"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--orders", nargs="+", default=list(ORDERS), choices=list(ORDERS))
    ap.add_argument("--no-odometry", action="store_true",
                    help="fit and place without the wheel odometry (odometry read from the scans)")
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench/robots"))
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    print("| plan | seed | beams | chosen | order found | error m | wrong room |")
    print("|---|---|---|---|---|---|---|")
    for plan in args.plans:
        for seed in args.seeds:
            run(plan, seed, args.orders, Path(args.cache), not args.no_odometry)


if __name__ == "__main__":
    main()
