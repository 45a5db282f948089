"""Time :func:`topomap.read_rosbag` on a one-hour 10 Hz bag (36,000 steps of 360-beam scans).

Usage::

    python benchmarks/bench_rosbag.py [--scale 1 10] [--formats ros1 sqlite3 mcap] [--repeats 3] [--dir DIR]

For each scale and format the script writes a bag of ``36000 * scale`` steps (a ``LaserScan`` and
a ``std_msgs/String`` action per step, 10 Hz, random ranges with some ``inf``), then reads it
``--repeats`` times, each time in a fresh Python process so that the peak resident memory
(``ru_maxrss`` from ``os.wait4``) is that read's own.  It prints the median wall time of the
read (imports excluded) and the largest peak RSS, plus the RSS of a process that only imports.
The bags are written under ``--dir`` and kept there for the next run (default: a temporary
folder, removed at the end).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
BEAMS, RATE, ONE_HOUR = 360, 10.0, 36_000
ACTIONS = ["forward", "turn_left", "turn_right", "stop"]


def write_bench_bag(path: Path, n_steps: int, version: int, storage: str) -> None:
    """Write a bag of ``n_steps`` random scans and actions through :func:`topomap.write_rosbag`."""
    from topomap import write_rosbag
    from topomap import Trajectory

    rng = np.random.default_rng(0)
    ranges = rng.uniform(0.1, 10.0, size=(n_steps, BEAMS)).astype(np.float32)
    traj = Trajectory(observations=ranges, actions=rng.integers(0, len(ACTIONS), n_steps),
                      action_names=ACTIONS)
    del ranges
    write_rosbag(traj, path, version=version, storage=storage, rate=RATE)


def child_read(path: str) -> None:
    """In a child process: read the bag once and print the seconds it took as JSON."""
    from topomap import read_rosbag

    start = time.perf_counter()
    traj = read_rosbag(path, "/scan", "/action")
    seconds = time.perf_counter() - start
    print(json.dumps({"seconds": seconds, "steps": len(traj), "dim": traj.observations.shape[1]}))


def run_child(args: list[str]) -> tuple[dict, float]:
    """Run this script with ``args`` in a new process; return its JSON output and peak MiB."""
    proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), *args],
                            stdout=subprocess.PIPE, text=True, cwd=HERE)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stdout.close()
    if proc.returncode != 0:
        raise RuntimeError(f"child {args} failed with exit code {proc.returncode}")
    return (json.loads(out) if out.strip() else {}), usage.ru_maxrss / 1024


def bench_one(workdir: Path, scale: int, fmt: str, repeats: int) -> dict:
    """Write one bag and time ``repeats`` reads of it; return the measurements."""
    version, storage = (1, "sqlite3") if fmt == "ros1" else (2, fmt)
    path = workdir / (f"bench_{fmt}_{scale}x" + (".bag" if version == 1 else ""))
    n_steps = ONE_HOUR * scale
    if not path.exists():
        start = time.perf_counter()
        run_child(["--write", str(path), str(n_steps), str(version), storage])
        print(f"  wrote {path.name} ({n_steps} steps) in {time.perf_counter() - start:.1f} s",
              flush=True)
    runs = [run_child(["--read", str(path)]) for _ in range(repeats)]
    median = statistics.median(r[0]["seconds"] for r in runs)
    return {"format": fmt, "steps": n_steps, "median_s": median,
            "times_s": [round(r[0]["seconds"], 3) for r in runs],
            "peak_rss_mib": max(r[1] for r in runs), "bag_mib": bag_size(path) / 2**20}


def bag_size(path: Path) -> int:
    """Bytes taken by a bag file or folder."""
    return path.stat().st_size if path.is_file() else sum(f.stat().st_size for f in path.iterdir())


def main() -> None:
    """Parse the arguments, dispatch child modes, or run the benchmark and print a table."""
    if sys.argv[1:2] == ["--write"]:
        path, n, version, storage = sys.argv[2:6]
        return write_bench_bag(Path(path), int(n), int(version), storage)
    if sys.argv[1:2] == ["--read"]:
        return child_read(sys.argv[2])
    if sys.argv[1:2] == ["--import-only"]:
        from topomap.core.data.rosbag.common import _rosbags  # the baseline RSS of the imports

        _rosbags()
        return None
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scale", type=int, nargs="+", default=[1, 10])
    parser.add_argument("--formats", nargs="+", default=["ros1", "sqlite3", "mcap"],
                        choices=["ros1", "sqlite3", "mcap"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dir", type=Path, default=None)
    args = parser.parse_args()
    holder = contextlib.nullcontext(args.dir) if args.dir else tempfile.TemporaryDirectory()
    with holder as folder:
        workdir = Path(folder)
        workdir.mkdir(parents=True, exist_ok=True)
        print(f"baseline RSS after imports: {run_child(['--import-only'])[1]:.0f} MiB", flush=True)
        for scale in args.scale:
            for fmt in args.formats:
                r = bench_one(workdir, scale, fmt, args.repeats)
                print(f"{r['format']:8s} {r['steps']:7d} steps  median {r['median_s']:6.2f} s "
                      f"{r['times_s']}  peak RSS {r['peak_rss_mib']:6.0f} MiB  "
                      f"bag {r['bag_mib']:5.0f} MiB", flush=True)
    return None


if __name__ == "__main__":
    main()
