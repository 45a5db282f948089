"""How far odometry from the scans alone drifts from the truth: scan registration
(:func:`topomap.core.motion.registration.scan_odometry`), the same closed by loops
(:func:`~topomap.core.motion.registration.scan_poses`), beside the scans' turns alone
(:func:`topomap.core.motion.reckoning.command_poses`: FFT turns, one unit of travel a moving
step), and the wheel odometry of the harness for scale.

    python benchmarks/registration_drift.py --plans robot_alike@0.3333 --seeds 0 \
        --robot speed_mean=0.1 wall_repel_distance=0.1 slip_size=0.03

Per walk: the median error of the displacement over windows of 10 and 100 steps (each window's
relative pose in the frame of its first step, against the true one: position [m] and heading
[rad]), and the whole walk's median position error after a rigid alignment (the FFT-turn walk,
whose unit of travel is unknown, after a similarity: scale fitted too, and its windows taken at
that scale).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import robot_harness as H  # noqa: E402
from bench_robots import _robot  # noqa: E402

from topomap.core.motion.reckoning import command_poses  # noqa: E402
from topomap.core.motion.registration import scan_odometry, scan_poses  # noqa: E402


def relative(P, H_, a, b):
    """(len(a), 3) the pose at ``b`` in the frame of the pose at ``a``."""
    c, s = np.cos(H_[a]), np.sin(H_[a])
    d = P[b] - P[a]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1],
                            H.wrap(H_[b] - H_[a])])


def window_errors(est, P, H_, k):
    a = np.arange(0, len(P) - k, 3)
    t, e = relative(P, H_, a, a + k), relative(est[:, :2], est[:, 2], a, a + k)
    return (float(np.median(np.linalg.norm(t[:, :2] - e[:, :2], axis=1))),
            float(np.median(np.abs(H.wrap(t[:, 2] - e[:, 2])))))


def aligned(est, P, scale=False):
    """``(median distance, scale)`` of ``est`` (T, 2) from ``P`` after the best rigid (or
    similarity) map; the scale 1 where rigid."""
    A, B = est - est.mean(0), P - P.mean(0)
    U, sv, Vt = np.linalg.svd(A.T @ B)
    d = np.sign(np.linalg.det(U @ Vt))
    R = U @ np.diag([1, d]) @ Vt
    k = (sv * [1, d]).sum() / (A ** 2).sum() if scale else 1.0
    return float(np.median(np.linalg.norm(k * A @ R - B, axis=1))), k


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--plans", nargs="+", default=["robot_alike@0.3333"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    p.add_argument("--robot", nargs="*", default=[], metavar="FIELD=VALUE")
    p.add_argument("--steps", type=int, default=18_000)
    p.add_argument("--cache", default=os.path.expanduser("~/.cache/topomap-bench/robots"))
    a = p.parse_args()
    robot = _robot(a.robot)
    print("| plan | seed | odometry | 10 steps m / rad | 100 steps m / rad | whole walk m | "
          "CPU s |")
    print("|---|---|---|---|---|---|---|")
    for plan in a.plans:
        for seed in a.seeds:
            w = H.walk(plan, 18_000, seed, robot, Path(a.cache))
            X, P, Hd = w.traj.observations[:a.steps], w.traj.positions[:a.steps], w.heading[
                :a.steps]
            runs = {}
            start = time.process_time()
            runs["registration"] = (scan_odometry(X), time.process_time() - start)
            start = time.process_time()
            runs["registration closed by loops"] = (scan_poses(X), time.process_time() - start)
            start = time.process_time()
            runs["scan turns, unit travel"] = (command_poses(X, w.traj.actions[:a.steps]),
                                               time.process_time() - start)
            runs["wheel (harness)"] = (w.odometry[:a.steps], 0.0)
            for name, (est, sec) in runs.items():
                whole, k = aligned(est[:, :2], P, scale=name.startswith("scan turns"))
                est = np.column_stack([est[:, :2] * k, est[:, 2]])
                e10 = window_errors(est, P, Hd, 10)
                e100 = window_errors(est, P, Hd, 100)
                print(f"| {plan} | {seed} | {name} | {e10[0]:.4f} / {e10[1]:.3f} | "
                      f"{e100[0]:.4f} / {e100[1]:.3f} | {whole:.3f} | {sec:.1f} |", flush=True)


if __name__ == "__main__":
    main()
