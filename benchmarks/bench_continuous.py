"""Maps from continuous motion, every route side by side: errors in metres in the arena.

    python benchmarks/bench_continuous.py                               # the main table
    python benchmarks/bench_continuous.py --cases two_rooms --routes shipped views --seeds 0
    python benchmarks/bench_continuous.py --settings                    # unseen sensor settings
    python benchmarks/bench_continuous.py --settings 10 --steps 72000   # 40 Hz for 30 minutes
    python benchmarks/bench_continuous.py --curve --cases two_rooms alcoves   # error vs steps
    python benchmarks/bench_continuous.py --timing                      # the whole rat path

Robots (a LiDAR in the robot's frame, turn / forward / stop commands, drifting wheel odometry)
have their section in ``benchmarks/bench_robots.py`` (``benchmarks/notes/robots.md``).

Cases (compass-aligned range beams plus Gaussian noise, compass actions; 10 Hz unless said):

* ``two_rooms``, ``four_rooms``, ``corridor``, ``open`` (the arena's layouts) and ``alcoves``
  (``benchmarks/floorplans/alcoves.yaml``: three identical alcoves off a corridor) -- 18,000
  training steps of ratinabox's random motion, a held-out walk of 6,000 steps of another seed,
  ``n_clusters=32, n_states=64``; ``l_rooms``, ``pillars``, ``three_rooms``, ``grid6``,
  ``ring`` and ``sizes`` (``benchmarks/floorplans/``) likewise, kept out of the default cases:
  floor plans no setting was chosen on;
* ``tanni`` -- Tanni et al.'s rat path: its first 75 % to learn, the rest held out,
  ``n_clusters=50, n_states=100``.

Routes: ``split`` (the paper's map, ``motion="discrete"``), ``em`` (``refine="em"``,
``motion="discrete"``), ``views`` (K-means on the views, :func:`kmeans_view_scores`), ``ceiling``
(the true places in topomap's model class, :func:`ceiling_scores`), ``positions`` (K-means on the
true positions: the held-out steps placed by their true position), ``shipped`` (the default
call: ``MapLearner(n_clusters, n_states, refine="em", random_state=0)``, motion="auto"),
``unchecked`` (the shipped route without its held-out check: the places always,
``MotionSettings(check={"holdout": 0})``), ``crossfit`` (the shipped route with the one
cross-fitted rule, ``MotionSettings(check={"rule": "crossfit"})``; ``crossfit10`` and
``crossfit15`` hold out 10 and 15 %), ``bootstrap`` (``check.rule="bootstrap"``, the
default's rule, named: the crossfit's figures, the places kept unless the view clusters beat them
by two bootstrap standard errors), ``coverage`` (``check.rule="coverage"``: ``bootstrap``,
but where a quarter lies mostly in places the rest of the log seldom visits, that quarter held
out instead of the last and the places kept only where no farther off,
:mod:`topomap.core.motion.coverage`), ``folds``
(``check.rule="folds"``, the rule before),
``one_gate`` (the shipped route with one gate of 3 cell extents),
``no_odometry`` (places are the view clusters: K-means with as many clusters as states, each its
own Gaussian, decoded by the map), ``merged_runs`` (runs of one symbol merged into one step, split
+ EM on the runs, each row labelled with its run's state), ``fallback`` (the map the default
falls back to: the view clusters, every state one pooled variance), ``folds3`` (the default
with the mean over three held-out quarters, not two, each recorded in its row's ``motion``), ``unscaled`` (the default
with the fallback's pooled variance not scaled down and no least gain of the check,
``fallback_variance=1, min_gain=0``: the version before both), ``no_vote`` (the default
without the vote of three held-out quarters, ``votes=0``: the version before it),
``confidence2`` (the default with the pooled share's gain asked to beat twice its own noise,
``confidence=2``), ``no_graph`` (the default without the pose graph's places the check weighs
beside the filter's, ``places.graph_gate=0``: the version before them),
``self_decoded`` (the places unchecked, each training row then labelled with the state the map
itself decodes it into, so that a state stands where the map puts its steps, not where they were
cut; a state the decoding never takes keeps the rows it was cut from). ``views`` is seeded
with ``random_state=0``. Scores
(:mod:`topomap.evaluation.metres`): median and 90th-percentile error, wrong-region share;
states; fit seconds; the peak RSS of the benchmark process so far (``rss_mib``: a bound on the
route's own, see ``--timing`` for a fresh process). Every row is appended to ``--log`` (JSON lines)
and a run skips the rows already there; the table printed is the median over the seeds of each case
and route. Simulated walks are cached in ``--cache``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from topomap import MapLearner, Trajectory
from walk_stamp import of_these_walks, walk_stamp, warn_mixed_walks
from topomap.core.map.model import TopologicalMap
from topomap.evaluation.metres import (ceiling_scores, kmeans_view_scores, map_scores,
                                          score_units)

HERE = Path(__file__).resolve().parent
LAYOUTS = {name: str(HERE / "floorplans" / f"{name}.yaml")
           for name in ("alcoves", "l_rooms", "pillars", "three_rooms", "grid6", "ring",
                        "sizes", "tanni_pillars")}
ROOMS = ("two_rooms", "four_rooms", "corridor", "open", "alcoves")
#: floor plans kept out of the main table: layouts the default was not developed on
UNSEEN = ("l_rooms", "pillars", "three_rooms", "grid6", "ring", "sizes")
ROUTES = ("split", "em", "views", "ceiling", "positions", "shipped", "unchecked", "crossfit",
          "folds", "crossfit10", "crossfit15", "bootstrap", "coverage", "one_gate",
          "no_odometry", "merged_runs", "fallback", "folds3", "unscaled", "no_vote",
          "confidence2", "self_decoded", "weight1", "weight05", "no_graph")
#: the main sensor: 12 compass beams, max range 3 m, noise 0.02; random motion 0.16 m/s, 10 Hz
BASE = {"beams": 12, "max_range": 3.0, "sigma": 0.02, "speed": 0.16, "dt": 0.1,
        "actions": "compass", "frame": "compass", "sensor": "range", "wrong": 0.0}
#: the settings beside it (one thing changed at a time, or two)
SETTINGS = [{"beams": 8, "max_range": 2.0}, {"beams": 16, "sigma": 0.03}, {"sigma": 0.01},
            {"speed": 0.08}, {"speed": 0.12, "max_range": 2.0}, {"dt": 0.05, "beams": 8},
            {"actions": "turns"}, {"frame": "egocentric"}, {"sensor": "bvc"}, {"sigma": 0.05},
            {"dt": 0.025}, {"dt": 0.05}, {"dt": 0.02}, {"beams": 6},
            {"speed": 0.3, "dt": 0.05}, {"wrong": 0.15}, {"max_range": 2.0}]


def setting_name(s: dict) -> str:
    return ",".join(f"{k}={v}" for k, v in sorted(s.items()) if BASE.get(k) != v) or "base"


def _world(case: str, s: dict):
    from topomap.worlds.arena import ArenaWorld, BoundaryVectorCells, RangeFinder

    sensor = (BoundaryVectorCells(n=32) if s["sensor"] == "bvc" else
              RangeFinder(n_beams=s["beams"], max_range=s["max_range"], frame=s["frame"]))
    if case in ("tanni", "tanni_pillars"):
        return ArenaWorld(layout=LAYOUTS.get(case, "auto"), path="tanni", sensor=sensor,
                          dt=s["dt"], actions=s["actions"], path_tolerance=0.1)
    if "@" in case:  # a robot floor plan at a rat's scale, e.g. robot_twin@0.3333
        from robot_harness import layout

        return ArenaWorld(layout=layout(case), sensor=sensor, dt=s["dt"], actions=s["actions"],
                          speed_mean=s["speed"])
    return ArenaWorld(layout=LAYOUTS.get(case, case), sensor=sensor, dt=s["dt"],
                      actions=s["actions"], speed_mean=s["speed"])


def _noisy(traj, sigma: float, seed: int, wrong: float = 0.0):
    """``traj`` with N(0, sigma^2) added to its views and a share ``wrong`` of its actions
    replaced by another action drawn at random (a compass misread)."""
    rng = np.random.default_rng(seed)
    traj.observations = traj.observations + rng.normal(0.0, sigma, traj.observations.shape)
    if wrong > 0:
        flip = rng.random(traj.actions.size) < wrong
        other = rng.integers(1, traj.n_actions, traj.actions.size)
        traj.actions = np.where(flip, (traj.actions + other) % traj.n_actions, traj.actions)
    return traj


def walks(case: str, seed: int, s: dict, cache: Path, n_train: int = 18_000):
    """``(world, train, heldout, ns, n_states)``; the walks are cached as npz files."""
    world = _world(case, s)
    name = cache / f"{case}-{setting_name(s)}-{seed}-{n_train}-{walk_stamp()}.npz"
    if name.exists():
        with np.load(name, allow_pickle=False) as f:
            parts = [Trajectory(f[f"{p}X"], f[f"{p}u"], positions=f[f"{p}P"],
                                action_names=world.action_names)
                     for p in ("train", "held")]
    else:
        if case in ("tanni", "tanni_pillars"):
            n = world.path_steps
            cut = int(0.75 * n)
            parts = [world.walk_from(0, cut), world.walk_from(cut, n - cut)]
        else:
            held_steps = int(round(6_000 * 0.1 / s["dt"]))
            parts = [world.simulate(n_train, None, np.random.default_rng(seed)),
                     world.simulate(held_steps, None, np.random.default_rng(seed + 1000))]
        parts = [_noisy(t, s["sigma"], seed + 100 + i, s["wrong"]) for i, t in enumerate(parts)]
        cache.mkdir(parents=True, exist_ok=True)
        np.savez(name, **{f"{p}{k}": v for p, t in zip(("train", "held"), parts)
                          for k, v in (("X", t.observations), ("u", t.actions),
                                       ("P", t.positions))})
    ns, S = (50, 100) if case.startswith("tanni") else (32, 64)
    return world, parts[0], parts[1], ns, S


def _learner_row(learner, seconds, train, held, regions):
    return {"states": learner.map_.n_states, "fit_s": round(seconds, 2),
            "motion": getattr(learner, "motion_info_", None),
            "ambiguity": getattr(learner, "symbol_ambiguity_", None),  # where the refinement ran
            **map_scores(learner.map_, learner.labels_, train, held, regions)}


def _fit(train, **kw):
    start = time.perf_counter()
    learner = MapLearner(**kw).fit(train.observations, train.actions, n_actions=train.n_actions)
    return learner, time.perf_counter() - start


def _own_gaussians(X, u, labels, n_actions):
    S = int(labels.max()) + 1
    return TopologicalMap.from_labels(X, u, labels, state_symbol=np.arange(S),
                                      state_gds=np.full(S, -1), state_parent=np.full(S, -1),
                                      n_actions=n_actions)


def merged_runs(train, ns, S):
    """Split + EM on the sequence of runs (one step per run of one symbol), every row labelled
    with its run's state; the map counted on the rows."""
    first = MapLearner(n_clusters=ns, n_states=ns, motion="discrete", random_state=0)
    sym = first.fit(train.observations, train.actions, n_actions=train.n_actions).labels_phase1_
    start = np.flatnonzero(np.r_[True, sym[1:] != sym[:-1]])
    run_of = np.cumsum(np.r_[True, sym[1:] != sym[:-1]]) - 1
    last = np.r_[start[1:] - 1, sym.size - 1]  # the action that leaves the run
    Xr = np.stack([train.observations[run_of == r].mean(axis=0) for r in range(start.size)])
    runs = MapLearner(n_clusters=ns, n_states=S, refine="em", motion="discrete",
                      random_state=0).fit(Xr, train.actions[last], n_actions=train.n_actions)
    labels = runs.labels_[run_of]
    m = TopologicalMap.from_labels(train.observations, train.actions, labels,
                                   state_symbol=runs.map_.state_symbol,
                                   state_gds=np.full(runs.map_.n_states, -1),
                                   state_parent=np.full(runs.map_.n_states, -1),
                                   n_actions=train.n_actions)
    return m, labels


def route(name, train, held, ns, S, regions, seed):
    """The scores of one route on one case."""
    from topomap.core.motion import MotionSettings

    kw = dict(n_clusters=ns, n_states=S, random_state=0)
    if name in ("split", "em"):
        return _learner_row(*_fit(train, motion="discrete", refine="em" if name == "em" else None,
                                  **kw), train, held, regions)
    if name in ("shipped", "unchecked", "one_gate", "folds3", "unscaled", "no_vote",
                "confidence2", "weight1", "weight05", "crossfit", "folds", "crossfit10",
                "crossfit15", "bootstrap", "coverage", "no_graph"):
        motion = {"shipped": MotionSettings(),
                  "bootstrap": MotionSettings(check={"rule": "bootstrap"}),
                  "coverage": MotionSettings(check={"rule": "coverage"}),
                  "crossfit": MotionSettings(check={"rule": "crossfit"}),
                  "crossfit10": MotionSettings(check={"rule": "crossfit", "holdout": 0.1}),
                  "crossfit15": MotionSettings(check={"rule": "crossfit", "holdout": 0.15}),
                  "folds": MotionSettings(check={"rule": "folds"}),
                  "unchecked": MotionSettings(check={"holdout": 0}),
                  "one_gate": MotionSettings(places={"gates": (3.0,)}),
                  "folds3": MotionSettings(check={"folds": 3}),
                  "unscaled": MotionSettings(places={"fallback_variance": 1.0},
                                             check={"min_gain": 0.0}),
                  "no_vote": MotionSettings(check={"votes": 0}),
                  "confidence2": MotionSettings(check={"confidence": 2.0}),
                  "weight1": MotionSettings(places={"weight": 1.0, "loose_weight": 1.0}),
                  "weight05": MotionSettings(places={"weight": 0.5, "loose_weight": 0.5}),
                  "no_graph": MotionSettings(places={"graph_gate": 0.0})}[name]
        return _learner_row(*_fit(train, refine="em", motion=motion, **kw), train, held, regions)
    if name == "self_decoded":
        learner, seconds = _fit(train, refine="em", motion=MotionSettings(check={"holdout": 0}),
                                **kw)
        labels = learner.map_.predict(train.observations, train.actions)
        unused = np.bincount(labels, minlength=learner.map_.n_states) == 0
        keep = unused[learner.labels_]  # a state the decoding never takes keeps its own rows
        labels[keep] = learner.labels_[keep]
        return {"states": learner.map_.n_states, "fit_s": round(seconds, 2),
                **map_scores(learner.map_, labels, train, held, regions)}
    start = time.perf_counter()
    if name == "views":
        scores = kmeans_view_scores(S, train, held, regions, random_state=0)
    elif name == "ceiling":
        split, _ = _fit(train, motion="discrete", **kw)
        scores = ceiling_scores(split.map_, split.labels_, train, held, regions,
                                random_state=seed)
    elif name == "positions":
        from sklearn.cluster import KMeans

        km = KMeans(S, n_init=4, random_state=seed).fit(train.positions)
        pair = (None, None) if regions is None else (regions(train.positions),
                                                     regions(held.positions))
        scores = score_units(km.labels_, train.positions, km.predict(held.positions),
                             held.positions, S, pair)
    elif name == "no_odometry":
        from sklearn.cluster import KMeans

        labels = KMeans(S, n_init=3, random_state=0).fit(train.observations).labels_
        m = _own_gaussians(train.observations, train.actions, labels, train.n_actions)
        scores = map_scores(m, labels, train, held, regions)
    elif name == "fallback":
        from topomap.core.motion.learn import pooled_variances
        from topomap.core.motion.places import view_clusters

        labels = view_clusters(train.observations, S, MotionSettings().places.n_init, 0)
        m = pooled_variances(_own_gaussians(train.observations, train.actions, labels,
                                            train.n_actions), train.observations, labels, 1e-3,
                             MotionSettings().places.fallback_variance)
        scores = map_scores(m, labels, train, held, regions)
    elif name == "merged_runs":
        m, labels = merged_runs(train, ns, S)
        scores = map_scores(m, labels, train, held, regions)
    else:
        raise ValueError(f"unknown route {name!r}")
    return {"states": S, "fit_s": round(time.perf_counter() - start, 2), **scores}


def _peak_rss_mib() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024


def _done(log: Path) -> set:
    if not log.exists():
        return set()
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    return {(r["case"], r["setting"], r["seed"], r["train"], r["route"]) for r in rows
            if of_these_walks(r)}


def logged_triples(log: Path) -> set:
    """The ``(case, setting, seed)`` of every walk a per-walk log (``"triple"`` rows) holds."""
    if not log.exists():
        return set()
    return {tuple(json.loads(line)["triple"]) for line in log.read_text().splitlines()
            if line.strip()}


def run(cases, routes, seeds, settings, steps, log: Path, cache: Path) -> None:
    done = _done(log)
    for s in settings:
        for case in cases:
            for seed in seeds:
                for n in steps:
                    todo = [r for r in routes
                            if (case, setting_name(s), seed, n, r) not in done]
                    if not todo:
                        continue
                    world, train, held, ns, S = walks(case, seed, s, cache, n)
                    for r in todo:
                        row = {"case": case, "setting": setting_name(s), "seed": seed,
                               "train": len(train) if case.startswith("tanni") else n,
                               "route": r, "walks": walk_stamp(),
                               **route(r, train, held, ns, S, world.region_of, seed),
                               "rss_mib": _peak_rss_mib()}
                        with open(log, "a") as fh:
                            fh.write(json.dumps(row) + "\n")
                        print(f"{case:10s} {row['setting']:24s} seed {seed} {row['train']:6d} "
                              f"{r:12s} median {row['median_error']:.3f} p90 "
                              f"{row['p90_error']:.3f} wrong {row['wrong_region']:.3f} "
                              f"{row['states']:4d} states {row['fit_s']:7.1f} s", flush=True)


def table(log: Path, train: int | None = None) -> list[dict]:
    """Medians over seeds of every (case, setting, training steps, route) in ``log``."""
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    warn_mixed_walks(rows)
    groups: dict = {}
    for r in rows:
        if train is None or r["train"] == train or r["case"].startswith("tanni"):
            groups.setdefault((r["case"], r["setting"], r["train"], r["route"]), []).append(r)
    out = []
    for (case, setting, n, rname), rs in sorted(groups.items()):
        med = {k: float(np.median([r.get(k, np.nan) for r in rs]))
               for k in ("median_error", "p90_error", "wrong_region", "states", "fit_s",
                         "rss_mib")}
        out.append({"case": case, "setting": setting, "train": n, "route": rname,
                    "seeds": len(rs), **med})
    return out


def print_table(rows) -> None:
    print("| case | setting | train | route | seeds | median m | p90 m | wrong | states | fit s "
          "| peak RSS MiB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['setting']} | {r['train']} | {r['route']} | {r['seeds']} | "
              f"{r['median_error']:.3f} | {r['p90_error']:.2f} | {r['wrong_region']:.3f} | "
              f"{r['states']:.0f} | {r['fit_s']:.1f} | {r['rss_mib']:.0f} |")


def plot_curve(log: Path, png: Path) -> None:
    """Median error against training steps, one panel per case, one line per route."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in table(log) if r["setting"] == "base" and r["case"] != "tanni"]
    cases = sorted({r["case"] for r in rows})
    fig, axes = plt.subplots(1, len(cases), figsize=(4 * len(cases), 3.4), squeeze=False)
    for ax, case in zip(axes[0], cases):
        for rname in ROUTES:
            pts = sorted((r["train"], r["median_error"]) for r in rows
                         if r["case"] == case and r["route"] == rname)
            if len(pts) > 1:
                ax.plot(*zip(*pts), marker="o", label=rname)
        ax.set_xscale("log")
        ax.set_title(case)
        ax.set_xlabel("training steps (10 Hz)")
        ax.set_ylabel("median error of a held-out walk (m)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=120)


def timing(cache: Path) -> None:
    """The shipped fit on the whole rat path at 10 Hz in a fresh process: seconds, peak RSS."""
    world = _world("tanni", BASE)
    name = cache / "tanni-whole.npz"
    if not name.exists():
        t = _noisy(world.walk_from(0, world.path_steps), BASE["sigma"], 100)
        cache.mkdir(parents=True, exist_ok=True)
        np.savez(name, X=t.observations, u=t.actions)
    code = ("import sys, time, resource, numpy as np; from topomap import MapLearner; "
            f"f = np.load({str(name)!r}); X, u = f['X'], f['u']; t = time.perf_counter(); "
            "m = MapLearner(n_clusters=50, n_states=100, refine='em', random_state=0)"
            ".fit(X, u, n_actions=9); s = time.perf_counter() - t; "
            "print(len(u), round(s, 2), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss "
            "// 1024, sorted(m.timings_.items()))")
    for repeat in range(3):
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True).stdout.split(maxsplit=3)
        print(f"tanni whole path: {out[0]} steps, fit {out[1]} s, peak RSS {out[2]} MiB "
              f"(repeat {repeat}; {out[3].strip()})", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=[*ROOMS, "tanni"])
    p.add_argument("--routes", nargs="+", default=list(ROUTES), choices=ROUTES)
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--settings", nargs="*", type=int, default=None, metavar="I",
                   help="the unseen sensor settings (all, or those of these indices of SETTINGS)")
    p.add_argument("--curve", action="store_true", help="4,500 to 36,000 training steps")
    p.add_argument("--steps", type=int, default=18_000,
                   help="training steps of the random walks (72,000: 30 minutes at 40 Hz)")
    p.add_argument("--timing", action="store_true", help="the whole rat path in a fresh process")
    p.add_argument("--log", default="bench_continuous.jsonl")
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench"))
    p.add_argument("--png", default="bench_continuous.png")
    a = p.parse_args()
    log, cache = Path(a.log), Path(a.cache)
    if a.timing:
        return timing(cache)
    picked = None if a.settings is None else (a.settings or range(len(SETTINGS)))
    settings = [BASE] if picked is None else [dict(BASE, **SETTINGS[i]) for i in picked]
    steps = [4_500, 9_000, 18_000, 36_000] if a.curve else [a.steps]
    run(a.cases, a.routes, a.seeds, settings, steps, log, cache)
    print_table([r for r in table(log) if r["case"] in a.cases])
    print(f"peak RSS of this process: "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024} MiB")
    if a.curve:
        plot_curve(log, Path(a.png))


if __name__ == "__main__":
    main()
