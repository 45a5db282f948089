"""Simulate a walk in topomap's gridroom world and write it as a ROS bag, to try the bag route.

Usage (needs ``pip install "topomap[ros]"``)::

    python docs/examples/export_bag.py walk.bag                       # ROS 1, 2000 steps
    python docs/examples/export_bag.py walk --version 2 --storage mcap --steps 5000 --npz walk.npz

The bag holds ``/scan`` (``sensor_msgs/LaserScan``: the observation vector as ranges) and
``/action`` (``std_msgs/String``: north, east, south or west), one of each per step at 10 Hz,
and the action names in id order on ``/action/names``.
``--npz`` also saves the world's own trajectory, so that learning from the bag can be compared
with learning from the file.  The script prints how to read the bag back.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from topomap import save_trajectory
from topomap.core.data.rosbag import write_rosbag
from topomap.worlds import GridRoom, RandomExplorer


def simulate(steps: int, seed: int):
    """A random walk of ``steps`` steps in the default gridroom, drawn from ``seed``."""
    return GridRoom().simulate(steps, RandomExplorer(), np.random.default_rng(seed))


def parse_args(argv=None) -> argparse.Namespace:
    """The command-line arguments."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", type=Path, help="the bag: a .bag file (ROS 1) or a folder (ROS 2)")
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--version", type=int, choices=[1, 2], default=1)
    parser.add_argument("--storage", choices=["sqlite3", "mcap"], default="sqlite3")
    parser.add_argument("--rate", type=float, default=10.0, help="steps per second")
    parser.add_argument("--npz", type=Path, default=None,
                        help="also save the world's trajectory to this .npz file")
    return parser.parse_args(argv)


def main(argv=None) -> Path:
    """Simulate, write the bag (and optionally the .npz) and print how to read it back."""
    args = parse_args(argv)
    traj = simulate(args.steps, args.seed)
    out = write_rosbag(traj, args.out, version=args.version, storage=args.storage, rate=args.rate)
    print(f"wrote {out}: {len(traj)} steps on /scan (LaserScan) and /action (String)")
    if args.npz is not None:
        print(f"wrote {save_trajectory(traj, args.npz)}: the same walk as a trajectory file")
    print(f"read it back: topomap.read_rosbag({str(out)!r}, '/scan', '/action') (the bag "
          "records the action names in id order on /action/names)")
    return out


if __name__ == "__main__":
    main()
