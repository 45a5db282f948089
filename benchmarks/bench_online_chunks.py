"""``partial_fit`` with ``refine="em"`` over a FourRooms walk in big chunks, against ``fit``.

    python benchmarks/bench_online_chunks.py                    # 50,000 steps, seeds 0 1 2
    python benchmarks/bench_online_chunks.py --steps 20000 --seeds 0
    python benchmarks/bench_online_chunks.py report             # reprint the last results

The walk: ``MiniGridWorld("MiniGrid-FourRooms-v0", 0)`` (noise-free 147-D views) walked by
``RandomExplorer`` from ``numpy.random.default_rng(seed)`` for ``--steps`` steps.  The learner:
``MapLearner(n_clusters=<the walk's distinct views>, n_states=<its distinct places>,
refine="em")``, every other setting at its default (``window=20000``, ``refit_every=2000``;
``--window`` sets another window).
In one fresh process per seed: ``fit`` on the whole walk (numba's compilation included, so a
second ``fit`` follows the calls), then ``partial_fit`` on the first half of the walk and then
chunks of a tenth of it (25,000 then 5,000 steps each at 50,000: the first chunk holds fewer
distinct views than the count asked for, so the count is capped and grown), then ``fit`` again.
Printed per seed: CPU (``time.process_time``) and wall seconds of the calls and of the second
``fit``, their ratio, and the ARI of every step's label against the true places, online and
batch; then the medians over the seeds.  Results go to
``benchmarks/results/online_chunks.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "online_chunks.json"


def child(steps: int, seed: int, window: int) -> dict:
    import numpy as np
    from sklearn.base import clone
    from sklearn.metrics import adjusted_rand_score

    from topomap import MapLearner
    from topomap.worlds import MiniGridWorld, RandomExplorer

    world = MiniGridWorld("MiniGrid-FourRooms-v0", 0)
    traj = world.simulate(steps, RandomExplorer(), np.random.default_rng(seed))
    X, u, places = traj.observations, traj.actions, np.asarray(traj.places)
    views, n_places = np.unique(X, axis=0).shape[0], np.unique(places).size
    learner = MapLearner(n_clusters=views, n_states=n_places, refine="em")
    if window:
        learner.set_params(window=window)

    def timed(step):
        c, w = time.process_time(), time.perf_counter()
        step()
        return [time.process_time() - c, time.perf_counter() - w]

    first = timed(lambda: learner.fit(X, u, n_actions=traj.n_actions))
    online, calls, passes = clone(learner), [0.0, 0.0], []
    bounds = [0, steps // 2, *range(steps // 2 + steps // 10, steps, steps // 10), steps]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            cost = timed(lambda: online.partial_fit(X[lo:hi], u[lo:hi],
                                                    n_actions=traj.n_actions))
            calls = [calls[0] + cost[0], calls[1] + cost[1]]
            passes.append({"steps": hi, "cpu": cost[0], "wall": cost[1],
                           "pass": online.online_["last_work"]["pass"],
                           "ari": adjusted_rand_score(places[:hi], online.labels_[:hi])})
    again = timed(lambda: clone(learner).fit(X, u, n_actions=traj.n_actions))
    return {"steps": steps, "seed": seed, "window": learner.window, "views": int(views),
            "places": int(n_places),
            "views_first_half": int(np.unique(X[:steps // 2], axis=0).shape[0]),
            "fit": first, "fit_again": again, "calls": calls, "passes": passes,
            "warnings": [str(w.message) for w in said],
            "clusters": online.online_.get("clusters"), "n_passes": online.online_["n_passes"],
            "batch": adjusted_rand_score(places, learner.labels_),
            "online": adjusted_rand_score(places, online.labels_)}


def report(runs) -> None:
    ok = [r for r in runs if "error" not in r]
    for r in runs:
        if "error" in r:
            print(f"seed {r['seed']}: failed: {r['error']}")
            continue
        (cc, cw), (fc, fw) = r["calls"], r["fit_again"]
        print(f"seed {r['seed']} ({r['steps']:,} steps, window {r['window']:,}, {r['views']} "
              f"views, {r['views_first_half']} in the first half, {r['places']} places): fit "
              f"{r['fit'][1]:.1f} / {fw:.1f} s wall ({fc:.1f} s CPU), calls {cw:.1f} s wall "
              f"({cc:.1f} s CPU), {r['n_passes']} passes: online / batch {cw / fw:.2f}x wall "
              f"({cc / fc:.2f}x CPU); ARI online {r['online']:.3f}, batch {r['batch']:.3f}; "
              f"{len(r['warnings'])} warning(s); clusters {r['clusters']}")
        for p in r["passes"]:
            print(f"    call to {p['steps']:>6,} steps: {p['cpu']:6.1f} s CPU ({p['wall']:6.1f} "
                  f"wall), pass on {p['pass']:,} steps, ARI so far {p['ari']:.3f}")
    if ok:
        med = statistics.median
        print(f"medians over {len(ok)} seed(s): online / batch "
              f"{med(r['calls'][1] / r['fit_again'][1] for r in ok):.2f}x wall "
              f"({med(r['calls'][0] / r['fit_again'][0] for r in ok):.2f}x CPU); ARI online "
              f"{med(r['online'] for r in ok):.3f}, batch {med(r['batch'] for r in ok):.3f}, "
              f"online - batch {med(r['online'] - r['batch'] for r in ok):+.3f}")


def spawn(steps: int, seed: int, window: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", str(steps), str(seed), str(window)],
                         capture_output=True, text=True)
    if out.returncode:
        sys.stderr.write(out.stderr[-3000:])
        last = out.stderr.strip().splitlines()
        return {"seed": seed, "error": last[-1] if last else "failed"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print(json.dumps(child(*map(int, sys.argv[2:5]))))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("part", nargs="?", choices=["run", "report"], default="run")
    ap.add_argument("--steps", type=int, default=50000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--window", type=int, default=0, help="partial_fit's window (0: its default)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args()
    if args.part == "report":
        return report(json.loads(args.out.read_text()))
    runs = []
    for seed in args.seeds:
        runs.append(spawn(args.steps, seed, args.window))
        args.out.parent.mkdir(exist_ok=True)
        args.out.write_text(json.dumps(runs, indent=1))
    report(runs)


if __name__ == "__main__":
    main()
