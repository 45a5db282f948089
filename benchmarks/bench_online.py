"""Mapping while exploring: the cost of ``partial_fit``, its maps against batch fits, and the
steps an explorer needs before its map is right.

    python benchmarks/bench_online.py latency        # partial_fit per call and peak RSS, 1e3..1e6 steps
    python benchmarks/bench_online.py agreement      # online vs batch ARI on the README's worlds
    python benchmarks/bench_online.py explore        # steps to ARI 0.95: explorer=random vs active
    python benchmarks/bench_online.py passes         # FourRooms refine=em: fit, the calls, fit again
    python benchmarks/bench_online.py report         # reprint the last results (and the figure)

Options: ``--seeds 0 1 2`` (explore: ``31 32 33``), ``--max-steps 1e6`` (latency),
``--quick`` (smaller sizes, for a look).  Every part runs its measurements in fresh subprocesses
(one per world and seed), so peak memory is the measurement's own; results go to
``benchmarks/results/online_<part>.json``.

* **latency**: a 10 x 7 gridroom walk (5 symbols, Gaussian noise 0.01) handed to
  ``MapLearner(n_clusters=5, n_states=70)`` (the split, ``window=20000``, ``refit_every=2000``) in
  chunks of 1,000 steps up to ``--max-steps``.  For each decade of steps seen: the median wall
  time of the calls that only decode their chunk, of the calls that also make the wider pass,
  the steps the kernels touched, and the process's peak RSS (``ru_maxrss``) at the decade's end,
  beside the bytes the learner keeps (its O(T) labels apart).  The comparison in the same run is
  what a map learned while walking costs without ``partial_fit``: ``fit`` on every step seen
  (sizes up to 1e5).
* **agreement**: every command of the README's table of worlds (``bench_worlds.py``), on the same
  simulated walk: ``fit`` on the whole walk against ``partial_fit`` in chunks of 1,000 steps
  (``learner.window`` and ``learner.refit_every`` at their defaults), ARI of the final labels of
  every step against the true places; medians over the seeds.  Beside them, the seconds of
  the ``fit`` and of all the ``partial_fit`` calls, timed one after the other in the same
  process, and their ratio (online / batch; the FourRooms ``refine=em`` row's is the one
  ``partial_fit`` is held to: at most 5x).
* **passes**: the FourRooms ``refine=em`` row of **agreement** (seed 0; ``--seeds`` for
  others) in one process: ``fit`` on the whole walk, the ``partial_fit`` calls (chunks of
  1,000), ``fit`` again, each in CPU seconds (``time.process_time``: the comparison on a
  machine shared with other work) and wall seconds; every wider pass's steps, seconds, the
  parts of its fit (``timings_``) and the ARI of the steps seen so far.  The ratio is the calls
  against the second ``fit`` (the first includes numba's compilation).
* **explore**: ``topomap <world> explorer=random|active data.update_every=250
  learner.refit_every=500`` as the command line runs it: the map is updated every 250 steps and
  judged on a random walk of the whole world it never learned from (``heldout_ari``, see
  :func:`topomap.worlds.mapping.heldout_judge`); the first step count at which the judged ARI
  reaches 0.95, medians over the seeds (a seed that never reaches it counts as "> max steps").
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
FIGURE = HERE.parent / "docs" / "img" / "exploring.png"

GRIDROOM = ["env=gridroom", "env.width=10", "env.height=7", "env.n_symbols=5", "clusters.ns=5",
            "stop.n_states=70"]

#: bench_worlds.py's commands (the README's table of worlds)
AGREEMENT = [
    [], ["refine=em"], ["data.n_steps=10000"], ["data.n_steps=10000", "refine=em"],
    ["env=gridroom", "clusters.ns=4", "stop.n_states=48", "data.n_steps=10000"],
    ["experiment=gridroom"],
    ["env=gridroom", "env.width=12", "env.height=12", "env.n_symbols=8", "clusters.ns=8",
     "stop.n_states=144", "data.n_steps=10000"],
    ["env=gridroom", "env.width=12", "env.height=12", "env.n_symbols=8", "clusters.ns=8",
     "stop.n_states=144", "data.n_steps=10000", "refine=em"],
    ["env=random_graph"], ["env=random_graph", "data.n_steps=10000"],
    ["env=random_graph", "data.n_steps=10000", "refine=em"],
    ["env=random_graph", "env.n_places=60", "env.n_symbols=15", "env.out_degree=3",
     "clusters.ns=15", "stop.n_states=60", "data.n_steps=10000"],
    ["env=random_graph", "env.n_places=60", "env.n_symbols=15", "env.out_degree=3",
     "clusters.ns=15", "stop.n_states=60", "data.n_steps=10000", "refine=em"],
    ["experiment=minigrid_empty", "refine=none"], ["experiment=minigrid_empty"],
    ["env=minigrid", "env.name=MiniGrid-FourRooms-v0", "data.n_steps=50000", "clusters.ns=450",
     "stop.n_states=1036"],
    ["env=minigrid", "env.name=MiniGrid-FourRooms-v0", "data.n_steps=50000", "clusters.ns=450",
     "stop.n_states=1036", "refine=em"],
]

#: the worlds of the exploration race: (name, overrides, steps walked)
EXPLORE = [
    ("gridroom 10x7", [*GRIDROOM, "refine=em"], 4000),
    ("gridroom 8x6", ["experiment=gridroom"], 4000),
    ("gridroom 12x12", ["env=gridroom", "env.width=12", "env.height=12", "env.n_symbols=8",
                        "clusters.ns=8", "stop.n_states=144", "refine=em"], 10000),
    ("random_graph 60", ["env=random_graph", "env.n_places=60", "env.n_symbols=15",
                         "env.out_degree=3", "clusters.ns=15", "stop.n_states=60", "refine=em"],
     6000),
    ("MiniGrid Empty-8x8", ["experiment=minigrid_empty"], 6000),
]


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def compose(overrides):
    os.environ.setdefault("TOPOMAP_DISABLE_PLUGIN_AUTOLOAD", "1")
    from topomap.app.compose.command_line import compose as hydra_compose
    from topomap.app.run.experiment import _as_dict

    return _as_dict(hydra_compose([*overrides, "output.progress=false", "output.figures=false"]))


def build(overrides):
    from topomap.app.run.experiment import make_learner
    from topomap.app.compose.registry import Registry

    cfg = compose(overrides)
    parts = Registry.load(()).build(cfg)
    return cfg, parts, make_learner(cfg, parts)


# ------------------------------------------------------------------ one measurement (child)
def child_latency(max_steps: int, chunk: int, batch_max: int) -> dict:
    import numpy as np

    from topomap import MapLearner
    from topomap.worlds import GaussianNoise, GridRoom, RandomExplorer

    world = GridRoom(10, 7, 5)
    rng = np.random.default_rng(0)
    traj = world.simulate(max_steps, RandomExplorer(), rng)
    X = GaussianNoise(0.01).apply(traj.observations, rng)
    u, n_actions = traj.actions, traj.n_actions
    learner = MapLearner(n_clusters=5, n_states=70)
    calls, batch = [], []
    decades = [10 ** k for k in range(3, 8) if 10 ** k <= max_steps]
    rss = {}
    for lo in range(0, max_steps, chunk):
        hi = min(lo + chunk, max_steps)
        t0 = time.perf_counter()
        learner.partial_fit(X[lo:hi], u[lo:hi], n_actions=n_actions)
        dt = time.perf_counter() - t0
        work = learner.online_["last_work"]
        calls.append({"steps": hi, "seconds": dt, "pass": work["pass"] > 0,
                      "touched": work["decoded"] + work["pass"]})
        if hi in decades:
            rss[hi] = {"peak_rss_mib": peak_rss_mib(), "kept": learner.online_["memory"]}
            if hi <= batch_max:  # what the same map costs without partial_fit: fit on all seen
                t0 = time.perf_counter()
                MapLearner(n_clusters=5, n_states=70).fit(X[:hi], u[:hi], n_actions=n_actions)
                batch.append({"steps": hi, "seconds": time.perf_counter() - t0})
    return {"calls": calls, "rss": rss, "batch": batch}


def child_agreement(overrides, seed: int, chunk: int) -> dict:
    import numpy as np
    from sklearn.base import clone
    from sklearn.metrics import adjusted_rand_score

    cfg, parts, learner = build([*overrides, f"seed={seed}"])
    traj = parts.data.train(parts, seed)
    online = clone(learner)
    t0 = time.perf_counter()
    learner.fit_trajectory(traj)
    t_batch = time.perf_counter() - t0
    t0 = time.perf_counter()
    for lo in range(0, len(traj), chunk):
        gds = None if traj.gds is None else traj.gds[lo:lo + chunk]
        online.partial_fit(traj.observations[lo:lo + chunk], traj.actions[lo:lo + chunk], gds,
                           n_actions=traj.n_actions)
    t_online = time.perf_counter() - t0
    places = np.asarray(traj.places)
    return {"batch": float(adjusted_rand_score(places, learner.labels_)),
            "online": float(adjusted_rand_score(places, online.labels_)),
            "states": [int(learner.map_.n_states), int(online.map_.n_states)],
            "seconds": [t_batch, t_online], "passes": online.online_["n_passes"]}


def child_passes(seed: int, chunk: int) -> dict:
    import numpy as np
    from sklearn.base import clone
    from sklearn.metrics import adjusted_rand_score

    cfg, parts, learner = build([*AGREEMENT[-1], f"seed={seed}"])
    traj = parts.data.train(parts, seed)
    places, online = np.asarray(traj.places), clone(learner)

    def timed(step):
        c, w = time.process_time(), time.perf_counter()
        step()
        return [time.process_time() - c, time.perf_counter() - w]

    first = timed(lambda: learner.fit_trajectory(traj))
    passes, total = [], [0.0, 0.0]
    for lo in range(0, len(traj), chunk):
        gds = None if traj.gds is None else traj.gds[lo:lo + chunk]
        cost = timed(lambda: online.partial_fit(traj.observations[lo:lo + chunk],
                                                traj.actions[lo:lo + chunk], gds,
                                                n_actions=traj.n_actions))
        total = [total[0] + cost[0], total[1] + cost[1]]
        if online.online_["last_work"]["pass"]:
            seen = online.online_["n_steps"]
            passes.append({"steps": seen, "cpu": cost[0], "wall": cost[1],
                           "timings": dict(online.timings_), "warm": "warm_start" in getattr(
                               online, "refine_info_", {}),
                           "ari": adjusted_rand_score(places[:seen], online.labels_[:seen])})
    again = timed(lambda: clone(learner).fit_trajectory(traj))
    return {"fit": first, "calls": total, "fit_again": again, "passes": passes,
            "batch": adjusted_rand_score(places, learner.labels_),
            "online": adjusted_rand_score(places, online.labels_)}


class PlaceAware:
    """A reference, not a robot's explorer: it knows the true place (it replays the world's
    start from a copy of the walk's random stream and follows the world's table of successors)
    and takes the action of highest count-based novelty on true (place, action) pairs, planned
    over the true graph -- the coverage a map-based explorer could reach with a perfect map."""

    def __init__(self, world, rng, gamma=0.9, horizon=30):
        import numpy as np

        self.succ = world.successors
        self.place = int(rng.integers(self.succ.shape[0]))   # the walk's first draw
        self.n = np.zeros(self.succ.shape)
        self.gamma, self.horizon = gamma, horizon

    def choose(self, executable, rng) -> int:
        import numpy as np

        S, ok = self.succ, self.succ >= 0
        bonus = 1.0 / np.sqrt(self.n + 1.0)
        q = np.where(ok, bonus, -np.inf)
        for _ in range(self.horizon):
            q = np.where(ok, bonus + self.gamma * q.max(1)[np.maximum(S, 0)], -np.inf)
        here = q[self.place]
        best = np.flatnonzero(np.isclose(here, here.max(), rtol=0, atol=1e-12))
        a = int(best[rng.integers(best.size)])
        self.n[self.place, a] += 1
        self.place = int(S[self.place, a])
        return a

    def __repr__(self) -> str:
        return "PlaceAware()"


#: the explorers raced: name -> overrides (``place-aware`` is the reference above)
EXPLORERS = {"random": ["explorer=random"], "active": ["explorer=active"],
             "active (plan)": ["explorer=active", "explorer.route=plan"],
             "place-aware": ["explorer=random"]}


def child_explore(overrides, explorer: str, seed: int, steps: int) -> dict:
    import copy

    from topomap.app.components.data import seed_streams

    cfg, parts, learner = build([*overrides, *EXPLORERS[explorer], f"seed={seed}",
                                 f"data.n_steps={steps}", "data.update_every=250",
                                 "learner.refit_every=500"])
    if explorer == "place-aware":
        if not hasattr(parts.env, "successors"):
            return {"first": None, "curve": [], "skipped": "the world has no table of places"}
        parts.explorer = PlaceAware(parts.env, copy.deepcopy(seed_streams(seed)[0]))
    traj = parts.data.train(parts, seed, learner=learner)
    curve = traj.meta["mapping"]["curve"]
    first = next((c["steps"] for c in curve if c["heldout_ari"] >= 0.95), None)
    return {"first": first, "curve": [[c["steps"], c["heldout_ari"]] for c in curve]}


def child(argv) -> None:
    kind, args = argv[0], json.loads(argv[1])
    rec = {"latency": child_latency, "agreement": child_agreement,
           "explore": child_explore, "passes": child_passes}[kind](**args)
    rec["peak_rss_mib"] = peak_rss_mib()
    print(json.dumps(rec))


def spawn(kind: str, **args) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", kind, json.dumps(args)],
                         capture_output=True, text=True)
    if out.returncode:
        sys.stderr.write(out.stderr[-3000:])
        return {"error": out.stderr.strip().splitlines()[-1] if out.stderr.strip() else "failed"}
    return json.loads(out.stdout.strip().splitlines()[-1])


# ------------------------------------------------------------------ parts (parent)
def run_latency(args) -> dict:
    return spawn("latency", max_steps=int(args.max_steps), chunk=1000,
                 batch_max=int(min(args.max_steps, 1e5)))


def report_latency(rec) -> None:
    calls = rec["calls"]
    print("partial_fit in chunks of 1,000 steps (10 x 7 gridroom, split, window 20000, "
          "refit_every 2000)")
    print(f"{'steps seen':>18} | {'decode call ms':>14} | {'pass call s':>11} | "
          f"{'steps touched':>13} | {'peak RSS MiB':>12} | {'kept MiB (O(T) labels apart)':>28} |"
          f" {'fit on all seen s':>17}")
    batch = {b["steps"]: b["seconds"] for b in rec["batch"]}
    lo = 0
    for hi in sorted(int(k) for k in rec["rss"]):
        span = [c for c in calls if lo < c["steps"] <= hi]
        dec = [c["seconds"] * 1e3 for c in span if not c["pass"]]
        pas = [c["seconds"] for c in span if c["pass"]]
        r = rec["rss"][str(hi)] if str(hi) in rec["rss"] else rec["rss"][hi]
        kept = r["kept"]
        bounded = (kept["window"] + kept["codebook"]) / 2 ** 20
        print(f"{f'{lo + 1:,}-{hi:,}':>18} | {_med(dec, '.2f'):>14} | {_med(pas, '.3f'):>11} | "
              f"{max(c['touched'] for c in span):>13,} | {r['peak_rss_mib']:>12.0f} | "
              f"{bounded:>28.2f} | {batch.get(hi, float('nan')):>17.3f}")
        lo = hi
    early = [c["seconds"] for c in calls if 20000 < c["steps"] <= 100000]
    late = [c["seconds"] for c in calls if c["steps"] > calls[-1]["steps"] - 100000]
    if early and late:
        for label, pick in (("decode", False), ("pass", True)):
            e = [c["seconds"] for c in calls if 20000 < c["steps"] <= 100000 and c["pass"] == pick]
            lt = [c["seconds"] for c in calls if c["steps"] > calls[-1]["steps"] - 80000
                  and c["pass"] == pick]
            if e and lt:
                print(f"  {label} calls: median of the last 80,000 steps / of steps 20,001-100,000"
                      f" = {statistics.median(lt) / statistics.median(e):.2f}")
        mean_e = sum(early) / len(early)
        mean_l = sum(late) / len(late)
        print(f"  all calls, mean per call: last 100,000 steps / steps 20,001-100,000 = "
              f"{mean_l / mean_e:.2f}")


def run_agreement(args) -> list:
    rows = []
    for overrides in AGREEMENT:
        if args.quick and any("FourRooms" in o or "n_steps=10000" in o for o in overrides):
            continue
        seeds = args.seeds if not any("FourRooms" in o for o in overrides) else args.seeds[:1]
        recs = [spawn("agreement", overrides=overrides, seed=s, chunk=1000) for s in seeds]
        rows.append({"command": " ".join(["topomap", *overrides]), "seeds": seeds, "runs": recs})
        print(rows[-1]["command"], [(r.get("batch"), r.get("online")) for r in recs], flush=True)
    return rows


def report_agreement(rows) -> None:
    print("online (partial_fit, chunks of 1,000) vs batch (fit): ARI of every step's final label, "
          "medians over the seeds")
    print("| command | batch ARI | online ARI | online - batch | seeds | fit s (batch / online) |"
          " online / batch time |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        ok = [r for r in row["runs"] if "error" not in r]
        if not ok:
            print(f"| `{row['command']}` | error: {row['runs'][0]['error']} |")
            continue
        b = statistics.median(r["batch"] for r in ok)
        o = statistics.median(r["online"] for r in ok)
        d = statistics.median(r["online"] - r["batch"] for r in ok)
        tb = statistics.median(r["seconds"][0] for r in ok)
        to = statistics.median(r["seconds"][1] for r in ok)
        ratio = statistics.median(r["seconds"][1] / r["seconds"][0] for r in ok)
        print(f"| `{row['command']}` | {b:.3f} | {o:.3f} | {d:+.3f} | "
              f"{len(ok)} | {tb:.1f} / {to:.1f} | {ratio:.1f}x |")


def run_explore(args) -> list:
    rows = []
    for name, overrides, steps in EXPLORE:
        if args.quick:
            steps = min(steps, 2000)
        for explorer in EXPLORERS:
            recs = [spawn("explore", overrides=overrides, explorer=explorer, seed=s, steps=steps)
                    for s in args.seeds]
            rows.append({"world": name, "overrides": overrides, "explorer": explorer,
                         "steps": steps, "seeds": args.seeds, "runs": recs})
            print(name, explorer, [r.get("first", r.get("error")) for r in recs], flush=True)
    return rows


def _med(values, fmt) -> str:
    return format(statistics.median(values), fmt) if values else "-"


def _first_median(runs, steps):
    firsts = [r["first"] if r["first"] is not None else float("inf") for r in runs]
    m = statistics.median(firsts)
    return m, (f"> {steps:,}" if m == float("inf") else f"{m:,.0f}")


def report_explore(rows) -> None:
    print("steps until the map, judged on a random walk of the whole world, reaches ARI 0.95: "
          "median over the seeds (each seed's in brackets; '-': not within the walk), and the "
          "judged ARI at 2,000 steps (median)")
    names = list(EXPLORERS)
    print("| world | " + " | ".join(names) + " | active / random |")
    print("|---|" + "---|" * (len(names) + 1))
    for world in dict.fromkeys(r["world"] for r in rows):
        by = {r["explorer"]: r for r in rows if r["world"] == world}
        cells, meds = [], {}
        for name in names:
            runs = [r for r in by[name]["runs"] if "error" not in r and not r.get("skipped")]
            if not runs:
                cells.append("n/a")
                continue
            meds[name], text = _first_median(runs, by[name]["steps"])
            seeds = "/".join("-" if r["first"] is None else str(r["first"]) for r in runs)
            at = [dict((s, a) for s, a in r["curve"]).get(2000) for r in runs]
            cells.append(f"{text} ({seeds}); {_med([a for a in at if a is not None], '.3f')}")
        finite = all(meds.get(k, float("inf")) != float("inf") for k in ("random", "active"))
        ratio = f"{meds['active'] / meds['random']:.2f}" if finite else "n/a"
        print(f"| {world} | " + " | ".join(cells) + f" | {ratio} |")


def figure_explore(rows) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    worlds = list(dict.fromkeys(r["world"] for r in rows))
    fig, axes = plt.subplots(1, len(worlds), figsize=(3.2 * len(worlds), 2.9), squeeze=False)
    for ax, world in zip(axes[0], worlds):
        for r in (r for r in rows if r["world"] == world):
            runs = [x for x in r["runs"] if "error" not in x and x["curve"]]
            if not runs:
                continue
            steps = np.array([s for s, _ in runs[0]["curve"]])
            aris = np.median([[a for _, a in x["curve"]][:steps.size] for x in runs], axis=0)
            ax.plot(steps, aris, label=r["explorer"],
                    color={"random": "tab:gray", "active": "tab:blue", "active (plan)": "tab:orange",
                           "place-aware": "tab:green"}[r["explorer"]],
                    ls=":" if r["explorer"] == "place-aware" else "-")
        ax.axhline(0.95, color="k", lw=0.6, ls=":")
        ax.set_title(world, fontsize=9)
        ax.set_xlabel("steps taken", fontsize=8)
        ax.set_ylim(0, 1.02)
        ax.tick_params(labelsize=7)
    axes[0][0].set_ylabel("ARI on a held-out walk\n(median of 3 seeds)", fontsize=8)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=110)
    print(f"figure: {FIGURE}")


def run_passes(args) -> list:
    return [spawn("passes", seed=s, chunk=1000) for s in args.seeds[:1]]


def report_passes(runs) -> None:
    for r in runs:
        if "error" in r:
            print("failed:", r["error"])
            continue
        for p in r["passes"]:
            parts = " ".join(f"{k} {v:.2f}" for k, v in p["timings"].items())
            print(f"  pass at {p['steps']:>6,} steps: {p['cpu']:5.2f} s CPU ({p['wall']:5.2f} "
                  f"wall; {parts}){' from the last map' if p['warm'] else ''}, ARI {p['ari']:.3f}")
        (cc, cw), (fc, fw) = r["calls"], r["fit_again"]
        print(f"fit {r['fit'][0]:.1f} / {fc:.1f} s CPU ({r['fit'][1]:.1f} / {fw:.1f} wall), calls "
              f"{cc:.1f} s CPU ({cw:.1f} wall), {len(r['passes'])} passes: online / batch "
              f"{cc / fc:.2f}x CPU ({cw / fw:.2f}x wall); ARI online {r['online']:.3f}, "
              f"batch {r['batch']:.3f}")


PARTS = {"latency": (run_latency, report_latency), "agreement": (run_agreement, report_agreement),
         "explore": (run_explore, report_explore), "passes": (run_passes, report_passes)}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        return child(sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("part", choices=[*PARTS, "report"])
    ap.add_argument("--seeds", type=int, nargs="+")
    ap.add_argument("--max-steps", type=float, default=1e6)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    RESULTS.mkdir(exist_ok=True)
    if args.part == "report":
        for name, (_, rep) in PARTS.items():
            path = RESULTS / f"online_{name}.json"
            if path.exists():
                rep(json.loads(path.read_text()))
                if name == "explore":
                    figure_explore(json.loads(path.read_text()))
                print()
        return
    if args.seeds is None:
        args.seeds = [31, 32, 33] if args.part == "explore" else [0, 1, 2]
    run, rep = PARTS[args.part]
    rec = run(args)
    (RESULTS / f"online_{args.part}.json").write_text(json.dumps(rec, indent=1))
    rep(rec)
    if args.part == "explore":
        figure_explore(rec)


if __name__ == "__main__":
    main()
