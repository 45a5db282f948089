"""Robots as they log, every route side by side: errors in metres of a held-out walk.

    python benchmarks/bench_robots.py                                   # develop plans, seeds 0-2
    python benchmarks/bench_robots.py --plans robot_three robot_office alcoves --seeds 0 1 2
    python benchmarks/bench_robots.py --routes ideal views shipped --robot gyro_bias=0.02
    python benchmarks/bench_robots.py --table                           # the log's medians only

A robot (``robot_harness.py``: 60-beam LiDAR in its own frame, turn / forward / stop commands,
wheel odometry with 2 % speed and 5 % turn-rate noise, a gyro bias of 0.005-0.01 rad/s and
slips) walks 18,000 steps (30 minutes at 10 Hz) in a floor plan; a held-out walk of 6,000 steps
of another seed is placed by each route, each step at its state's mean training position
(:mod:`topomap.core.position_scores`).  Routes:

``ideal``      K-means on the TRUE positions, 64 cells (each held-out step at its nearest cell)
``ceiling``    the true places in topomap's model class (:func:`ceiling_scores`, on the split map)
``views``      K-means on the views, 64 clusters (:func:`kmeans_view_scores`)
``shipped``    ``MapLearner(n_clusters=32, n_states=64, random_state=0).fit(X, u, odometry=...)``
``no_odometry`` the same without the odometry (``predict`` without it too): the default reads
               it from the scans (``scan_odometry`` below)
``scan_odometry`` the same with ``motion={"scan_odometry": True}`` (the default): the robot route
               on odometry read from the scans, behind the guards
               (:mod:`topomap.core.motion.robot_scans`)
``robot_mode`` the same with ``motion="robot"``, the held-out walk placed by
               ``predict(X, u, odometry=...)`` with its own odometry

and the research routes of ``robot_routes.py`` and ``robot_slam.py``.  Every row goes to
``--log`` (JSON lines; a run skips rows already there); the table printed is the median over the seeds of every (plan, robot,
route), with the median error as a multiple of ``ideal``'s.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import robot_harness as H  # noqa: E402
import robot_routes as RR  # noqa: E402
import robot_slam as RS  # noqa: E402
from walk_stamp import of_these_walks, walk_stamp, warn_mixed_walks  # noqa: E402

from topomap import MapLearner  # noqa: E402
from topomap.evaluation.metres import (ceiling_scores, kmeans_view_scores,  # noqa: E402
                                          map_scores, score_units)

N_CLUSTERS, N_STATES = 32, 64


def _pair(train, held, regions):
    return (regions(train.positions), regions(held.positions))


def base_route(name, tw, hw, regions, seed):
    """The yardsticks and the learner as shipped."""
    train, held = tw.traj, hw.traj
    if name == "ideal":
        from sklearn.cluster import KMeans

        km = KMeans(N_STATES, n_init=4, random_state=seed).fit(train.positions)
        return score_units(km.labels_, train.positions, km.predict(held.positions),
                           held.positions, N_STATES, _pair(train, held, regions))
    if name == "views":
        return kmeans_view_scores(N_STATES, train, held, regions, random_state=0)
    if name == "ceiling":
        split = MapLearner(N_CLUSTERS, N_STATES, motion="discrete", random_state=0).fit(
            train.observations, train.actions, n_actions=train.n_actions)
        return ceiling_scores(split.map_, split.labels_, train, held, regions, random_state=seed)
    if name in ("shipped", "no_odometry", "scan_odometry"):
        kw = {"odometry": tw.odometry} if name == "shipped" else {}
        held_kw = {"odometry": hw.odometry} if name == "shipped" else {}
        motion = {"scan_odometry": True} if name == "scan_odometry" else "auto"
        try:
            learner = MapLearner(N_CLUSTERS, N_STATES, motion=motion, random_state=0).fit(
                train.observations, train.actions, n_actions=train.n_actions, **kw)
        except TypeError:  # a learner that takes no odometry
            learner = MapLearner(N_CLUSTERS, N_STATES, random_state=0).fit(
                train.observations, train.actions, n_actions=train.n_actions)
        info = getattr(learner, "motion_info_", None) or {}
        row = {"states": learner.map_.n_states, "chosen": info.get("chosen"),
               "reason": info.get("reason"), "check": info.get("check"),
               "unwalked": info.get("unwalked"), "unwalked_depth": info.get("unwalked_depth"),
               "symmetry": (info.get("symmetry") or {}).get("ratio"),
               "fit_only_s": round(sum(learner.timings_.values()), 2)}
        if getattr(learner, "robot_map_", None) is None:
            return {**row, **map_scores(learner.map_, learner.labels_, train, held, regions)}
        placed = learner.predict(held.observations, held.actions, **held_kw)
        return {**row, **score_units(learner.labels_, train.positions, placed, held.positions,
                                     learner.map_.n_states, _pair(train, held, regions))}
    if name == "robot_mode":
        learner = MapLearner(N_CLUSTERS, N_STATES, motion="robot", random_state=0).fit(
            train.observations, train.actions, n_actions=train.n_actions, odometry=tw.odometry)
        placed = learner.predict(held.observations, held.actions, odometry=hw.odometry)
        return {"states": learner.map_.n_states, "chosen": learner.motion_info_["chosen"],
                "fit_only_s": round(sum(learner.timings_.values()), 2),
                "symmetry": learner.motion_info_["symmetry"]["ratio"],
                **score_units(learner.labels_, train.positions, placed, held.positions,
                              learner.map_.n_states, _pair(train, held, regions))}
    return None


ROUTES = ("ideal", "ceiling", "views", "shipped", "no_odometry", "scan_odometry", "robot_mode",
          *RR.ROUTES,
          *RS.ROUTES)


def route(name, tw, hw, regions, seed):
    start, cpu = time.perf_counter(), time.process_time()
    row = base_route(name, tw, hw, regions, seed)
    if row is None and name in RS.ROUTES:
        row = RS.route(name, tw, hw, regions, seed, N_CLUSTERS, N_STATES)
    if row is None:
        row = RR.route(name, tw, hw, regions, seed, N_CLUSTERS, N_STATES)
    return {"fit_s": round(time.perf_counter() - start, 2),
            "cpu_s": round(time.process_time() - cpu, 2), **row}


def _done(log: Path) -> set:
    if not log.exists():
        return set()
    return {(r["plan"], r["robot"], r["seed"], r["route"])
            for r in map(json.loads, log.read_text().splitlines())
            if r and of_these_walks(r)}


def run(plans, seeds, routes, robot, log: Path, cache: Path) -> None:
    done = _done(log)
    for plan in plans:
        for seed in seeds:
            todo = [r for r in routes if (plan, robot.name(), seed, r) not in done]
            if not todo:
                continue
            tw, hw = H.pair(plan, seed, robot, cache)
            regions = H.region_of(plan)
            for r in todo:
                row = {"plan": plan, "robot": robot.name(), "seed": seed, "route": r,
                       "walks": walk_stamp(), **route(r, tw, hw, regions, seed)}
                with open(log, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
                print(f"{plan:13s} {robot.name():12s} seed {seed} {r:16s} median "
                      f"{row['median_error']:.3f} p90 {row['p90_error']:.3f} wrong "
                      f"{row['wrong_region']:.3f} {row['fit_s']:6.1f} s", flush=True)


def table(log: Path, plans=None, routes=None) -> list[dict]:
    rows = [json.loads(x) for x in log.read_text().splitlines() if x.strip()]
    warn_mixed_walks(rows)
    groups: dict = {}
    for r in rows:
        if (plans is None or r["plan"] in plans) and (routes is None or r["route"] in routes):
            groups.setdefault((r["plan"], r["robot"], r["route"]), []).append(r)
    ideal = {(p, rb): float(np.median([r["median_error"] for r in rs]))
             for (p, rb, rn), rs in groups.items() if rn == "ideal"}
    out = []
    for (plan, rb, rn), rs in sorted(groups.items()):
        med = {k: float(np.median([r.get(k) if r.get(k) is not None else np.nan for r in rs]))
               for k in ("median_error", "p90_error", "wrong_region", "fit_s")}
        x = med["median_error"] / ideal[(plan, rb)] if (plan, rb) in ideal else np.nan
        out.append({"plan": plan, "robot": rb, "route": rn, "seeds": len(rs), "x_ideal": x,
                    "chosen": ",".join(str(r.get("chosen")) for r in rs), **med})
    return out


def print_table(rows) -> None:
    print("| plan | robot | route | seeds | median m | x ideal | p90 m | wrong room | fit s | "
          "chosen |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['plan']} | {r['robot']} | {r['route']} | {r['seeds']} | "
              f"{r['median_error']:.3f} | {r['x_ideal']:.2f} | {r['p90_error']:.2f} | "
              f"{r['wrong_region']:.3f} | {r['fit_s']:.1f} | {r['chosen']} |")


def _robot(changes) -> H.Robot:
    kinds = {f.name: f.type for f in fields(H.Robot)}
    kw = {}
    for c in changes:
        k, _, v = c.partition("=")
        if k not in kinds:
            raise SystemExit(f"--robot {c}: not a robot field ({', '.join(kinds)})")
        kw[k] = int(v) if kinds[k] in (int, "int") else float(v)
    return H.Robot(**kw)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--plans", nargs="+", default=list(H.DEVELOP))
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--routes", nargs="+", default=["ideal", "ceiling", "views", "shipped"],
                   choices=ROUTES)
    p.add_argument("--robot", nargs="*", default=[], metavar="FIELD=VALUE")
    p.add_argument("--log", default="bench_robots.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench/robots"))
    p.add_argument("--table", action="store_true", help="print the log's table and stop")
    a = p.parse_args()
    log = Path(a.log)
    if not a.table:
        run(a.plans, a.seeds, a.routes, _robot(a.robot), log, Path(a.cache))
    print_table(table(log, a.plans, a.routes))


if __name__ == "__main__":
    main()
