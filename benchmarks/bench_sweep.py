"""Wall time of a sweep with different Hydra launchers.

    python benchmarks/bench_sweep.py                          # experiment=sweep_pricai2002, basic vs joblib(2)
    python benchmarks/bench_sweep.py --repeats 3 --n-jobs 2 4
    python benchmarks/bench_sweep.py --overrides clusters.ns=10,20 stop.n_states=30,40

Each launcher runs the same sweep as a fresh ``python -m topomap`` process in a temporary folder
(so the wall time includes start-up, simulating the shared trajectory once, every job and the sweep
report); the median of ``--repeats`` runs is shown, with a check that every launcher wrote the same
``map.json`` for every job.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run_sweep(overrides, launcher_args):
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "topomap", *overrides, *launcher_args],
                              cwd=tmp, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            sys.exit(f"sweep failed ({' '.join(launcher_args) or 'basic'}):\n{proc.stderr}")
        (sweep,) = (Path(tmp) / "outputs" / "sweeps").glob("*/*")
        with open(sweep / "summary.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
        maps = {r["output_dir"]: (sweep / r["output_dir"] / "map.json").read_bytes()
                for r in rows if r["status"] == "completed"}
        failed = sum(r["status"] != "completed" for r in rows)
    return wall, len(rows), failed, maps


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--overrides", nargs="*", default=["experiment=sweep_pricai2002"],
                        help="the sweep (default: experiment=sweep_pricai2002)")
    parser.add_argument("--n-jobs", nargs="*", type=int, default=[2],
                        help="joblib worker counts to time (default: 2)")
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args(argv)
    overrides = list(args.overrides)
    if not any(o.startswith("experiment=sweep") for o in overrides):
        overrides = ["-m", *overrides]
    launchers = {"basic": []}
    for n in args.n_jobs:
        launchers[f"joblib n_jobs={n}"] = ["hydra/launcher=joblib", f"hydra.launcher.n_jobs={n}"]
    print(f"sweep: {' '.join(overrides)}   ({os.cpu_count()} CPUs, {args.repeats} repeat(s))")
    print(f"{'launcher':<18} {'jobs':>5} {'failed':>6} {'wall [s]':>9}  same maps as basic")
    reference = None
    for name, extra in launchers.items():
        walls = []
        for _ in range(args.repeats):
            wall, n_rows, failed, maps = run_sweep(overrides, extra)
            walls.append(wall)
        reference = maps if reference is None else reference
        same = "yes" if maps == reference else "NO"
        print(f"{name:<18} {n_rows:>5} {failed:>6} {statistics.median(walls):>9.1f}  {same}")


if __name__ == "__main__":
    main()
