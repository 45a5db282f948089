"""The paper's experiment (office world, T=2000, ns=20 -> 30 states) over several seeds.

    python benchmarks/bench_paper.py --seeds 10

Prints, per seed and as medians, ARI / purity / compound states against the ground-truth places
after phase 1 and after splitting, and the wall time of one run (simulation + learning, no files).
Extra arguments are Hydra overrides, e.g. ``noise=dropout`` or ``env.view_range=5``.
"""

from __future__ import annotations

import argparse
import statistics
import time

from omegaconf import OmegaConf

from topomap.app.compose.command_line import compose
from topomap.app.run.data import load_data
from topomap.app.run.experiment import make_learner
from topomap.app.compose.registry import Registry
from topomap.metrics import evaluate


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("overrides", nargs="*")
    args = ap.parse_args()
    registry = Registry.load()
    rows = []
    for seed in range(args.seeds):
        overrides = [f"seed={seed}", "data.heldout_steps=0", *args.overrides]
        cfg = OmegaConf.to_container(compose(overrides, registry), resolve=True)
        t0 = time.perf_counter()
        parts = registry.build(cfg)
        (traj, _), _ = load_data(cfg, parts, registry)
        learner = make_learner(cfg, parts).fit_trajectory(traj)
        dt = time.perf_counter() - t0
        a, b = evaluate(traj.places, learner.labels_phase1_), evaluate(traj.places, learner.labels_)
        rows.append((a["ari"], b["ari"], a["purity"], b["purity"], a["compound_states"],
                     b["compound_states"], dt))
        print(f"seed {seed}: ARI {a['ari']:.3f} -> {b['ari']:.3f}  purity {a['purity']:.3f} -> "
              f"{b['purity']:.3f}  compound states {a['compound_states']} -> "
              f"{b['compound_states']}  ({dt:.2f} s)", flush=True)
    med = [statistics.median(c) for c in zip(*rows)]
    print(f"median of {len(rows)}: ARI {med[0]:.3f} -> {med[1]:.3f}  purity {med[2]:.3f} -> "
          f"{med[3]:.3f}  compound states {med[4]:g} -> {med[5]:g}  ({med[6]:.2f} s per run)")


if __name__ == "__main__":
    main()
