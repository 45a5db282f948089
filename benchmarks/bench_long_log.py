"""A long robot log's fit, this checkout against another version, in turn in fresh processes:
wall and CPU seconds, peak RSS, the map chosen.

    python benchmarks/bench_long_log.py                              # 73,000 steps, 3 rounds
    python benchmarks/bench_long_log.py --against /tmp/old --odometry --rounds 5
    python benchmarks/bench_long_log.py --steps 18000 --against /tmp/old

Each fit is ``MapLearner(n_clusters=32, n_states=64, random_state=0).fit(X, u[, odometry=])`` on
the ``--steps``-step walk of :mod:`robot_harness` (``robot_alike@0.3333`` seed 0 by default; its
wheel odometry with ``--odometry``), after a 6,000-step warm-up fit in the same process (numba's
caches, the thread pools), one process a fit.  ``--against DIR``: a checkout of another version
(``git worktree add DIR REV``), put first on ``PYTHONPATH`` in its processes; the two alternate,
this one first, and the ratios are taken pair by pair.  Time it on an idle machine: a test
suite beside it doubles its seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def one_fit(args) -> dict:
    """The timed fit of this process (``--child``): its figures as a dict."""
    sys.path.insert(0, str(HERE))
    warnings.simplefilter("ignore")
    import robot_harness as H
    from topomap import MapLearner

    cache = Path(args.cache)
    walk = H.walk(args.plan, args.steps, args.seed, H.Robot(), cache)
    warm = H.walk(args.plan, 6000, args.seed + 5, H.Robot(), cache)

    def fit(w):
        kw = {"odometry": w.odometry} if args.odometry else {}
        return MapLearner(n_clusters=32, n_states=64, random_state=0).fit(
            w.traj.observations, w.traj.actions, n_actions=w.traj.n_actions, **kw)

    fit(warm)
    w0, c0 = time.perf_counter(), time.process_time()
    m = fit(walk)
    return {"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0,
            "rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "chosen": m.motion_info_.get("chosen"), "load": os.getloadavg()[0]}


def run(args, checkout: Path) -> dict:
    """One fit in a fresh process with ``checkout`` first on ``PYTHONPATH``."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(checkout)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    cmd = [sys.executable, __file__, "--child", "--plan", args.plan, "--seed", str(args.seed),
           "--steps", str(args.steps), "--cache", args.cache] + (
        ["--odometry"] if args.odometry else [])
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plan", default="robot_alike@0.3333")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=73_000)
    ap.add_argument("--odometry", action="store_true", help="fit with the wheel odometry")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--against", type=Path, default=None, help="a checkout of another version")
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench/robots"))
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(one_fit(args)))
        return
    sides = [("this", ROOT)] + ([("against", args.against.resolve())] if args.against else [])
    got: dict[str, list[dict]] = {name: [] for name, _ in sides}
    for r in range(args.rounds):
        for name, checkout in sides:
            f = run(args, checkout)
            got[name].append(f)
            print(f"round {r} {name:7s} wall {f['wall']:6.2f} s  CPU {f['cpu']:6.2f} s  peak RSS "
                  f"{f['rss_mib']:6.0f} MiB  load {f['load']:.2f}  chosen {f['chosen']}",
                  flush=True)
    for name, _ in sides:
        w = np.array([f["wall"] for f in got[name]])
        print(f"{name:7s} median wall {np.median(w):.2f} s (min {w.min():.2f}, max {w.max():.2f})")
    if args.against:
        ratio = [a["wall"] / b["wall"] for a, b in zip(got["this"], got["against"])]
        print(f"this / against, pair by pair: {' '.join(f'{x:.2f}' for x in ratio)}; "
              f"median {np.median(ratio):.2f}")


if __name__ == "__main__":
    main()
