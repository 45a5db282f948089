"""What the refinement could gain on misread symbols: the fit's cost if every misread were
corrected perfectly and for free, and how many candidate symbols each step's own observation
would leave.

    python benchmarks/bench_noise_floor.py --worlds gridroom_8x6 --levels 1 2 3
    python benchmarks/bench_noise_floor.py --worlds random_graph_60 --levels 3 4
    python benchmarks/bench_noise_floor.py --worlds office --levels 2 3 4
    python benchmarks/bench_noise_floor.py --worlds gridroom_8x6 office --levels 1 2 --seeds 0 --candidates 1e-3 1e-6

The worlds, noise levels and trajectories are ``bench_noise.py``'s (``WORLDS``, ``SIGMAS``).  A
step's *true symbol* is the symbol most steps of its place got in phase 1.

* The floor (default): per world and level (default: every level but the clean one), the
  default refinement (``em_soft``) beside a hard refinement on the true symbols (``ambiguity=0``,
  as on exact readings) followed by one soft round without spare clones on the symbols as read,
  from its states -- what a perfect and free correction of the misreads would leave to pay --
  each against the clean fit (level 0) of the same seeds.  Medians over the seeds of the ARI and
  the fit seconds (phase 1 + split + refinement).
* ``--candidates SHARE ...``: per trajectory and share, how many symbols each step would keep as
  candidates if its evidence were its own observation's likelihood under phase 1's Gaussians
  (the symbols whose ``w_k N(o; mu_k, Sigma_k)`` is at least that share of the best one's), and
  on how many misread steps the true symbol stays among them.  Nothing is refined.

The machine's load average is printed with the table: fit times are wall-clock seconds.
"""

from __future__ import annotations

import argparse
import os
import shlex
import time

import numpy as np

from bench_noise import SIGMAS, WORLDS, _med, run_level
from topomap.app.compose.command_line import compose
from topomap.app.compose.registry import Registry
from topomap.app.run.data import load_data
from topomap.app.run.experiment import _as_dict, make_learner
from topomap import metrics as M
from topomap.core.refine.methods import EMRefinement


def _split_fit(world: str, sigma: float, seed: int, registry):
    """The trajectory of (``world``, ``sigma``, ``seed``) and a learner fitted on it without a
    refinement (phase 1 and the split)."""
    overrides = [*shlex.split(WORLDS[world]), f"noise.sigma={sigma}", f"seed={seed}",
                 "data.heldout_steps=0", "output.figures=false", "output.progress=false"]
    cfg = _as_dict(compose(overrides, registry))
    parts = registry.build(cfg)
    (traj, _), _ = load_data(cfg, parts, registry)
    learner = make_learner(cfg, parts)
    learner.set_params(refine=None)
    learner.fit_trajectory(traj)
    return traj, learner


def true_symbols(sym, places, n_symbols: int):
    """Every step's true symbol: the one most steps of its place got (GDS ids, ``>= n_symbols``,
    kept as read)."""
    sym = np.asarray(sym)
    place_ids, place_of = np.unique(places, return_inverse=True)
    top = np.zeros((place_ids.size, int(sym.max()) + 1), dtype=np.int64)
    np.add.at(top, (place_of, sym), 1)
    return np.where(sym >= n_symbols, sym, top.argmax(axis=1)[place_of])


def candidates(world: str, sigma: float, seed: int, shares, registry) -> list[dict]:
    """Per share of ``shares``: the mean candidate symbols per step, the share of steps with one,
    and the share of misread steps whose true symbol stays a candidate (``--candidates``)."""
    from topomap.core.map.observations import log_density_chunks
    traj, learner = _split_fit(world, sigma, seed, registry)
    ns, model, sym = learner.n_clusters_, learner.map_phase1_, learner.labels_phase1_
    keep = sym < ns
    s = sym[keep]
    log_w = np.log(np.bincount(s, minlength=ns) / s.size)
    X = np.asarray(traj.observations, dtype=np.float64)[keep]
    joint = np.concatenate([lp for _, lp in log_density_chunks(X, model.means[:ns],
                                                              model.covariances[:ns])]) + log_w
    rel = joint - joint.max(axis=1, keepdims=True)
    true = true_symbols(sym, traj.places, ns)[keep]
    misread = true != s
    rows = []
    for share in shares:
        kept = rel >= np.log(share)
        n = kept.sum(axis=1)
        rows.append({"share": share, "K": ns, "err": float(misread.mean()),
                     "candidates": float(n.mean()), "one": float(np.mean(n == 1)),
                     "true_kept": float(kept[np.arange(true.size), true][misread].mean())
                     if misread.any() else float("nan")})
    return rows


def floor_fit(world: str, sigma: float, seed: int, registry) -> dict:
    """``--floor``: what a perfect and free correction of the misreads would leave to pay -- the
    hard refinement on every step's true symbol (:func:`true_symbols`; ``ambiguity=0``, as on
    exact readings) and one soft round without spare clones on the symbols as read, from its
    states.  Seconds: phase 1 and the split plus those two; the ARI of the soft round's map."""
    from topomap.core.refine.sequence import SymbolSequence
    from topomap.core.refine.soft import soft_round
    traj, learner = _split_fit(world, sigma, seed, registry)
    ns, sym = learner.n_clusters_, np.asarray(learner.labels_phase1_)
    lengths = traj.lengths if traj.lengths is not None else [sym.size]
    n_actions = learner.map_split_.n_actions
    read = SymbolSequence.build(sym, traj.actions, lengths, n_actions, ns)
    true = SymbolSequence.build(true_symbols(sym, traj.places, ns), traj.actions, lengths,
                                n_actions, ns)
    split_labels = np.asarray(learner.labels_split_)
    split_symbol = np.full(int(split_labels.max()) + 1, -1, dtype=np.int64)
    split_symbol[split_labels] = np.where(sym < ns, sym, -1)  # -1: GDS states
    start = time.perf_counter()
    hard = EMRefinement(evidence="hard").fit(true, split_symbol, learner.random_state,
                                             split_labels=split_labels, ambiguity=0.0)
    mid = time.perf_counter()
    soft = soft_round(read, hard.labels_, hard.state_symbol_)
    end = time.perf_counter()
    t = learner.timings_
    return {"err": float(np.mean(true.sym != sym)), "hard": mid - start, "soft": end - mid,
            "fit": t["phase1"] + t["phase2"] + end - start,
            "ari": M.evaluate(traj.places, soft.labels)["ari"]}


def floor_table(args, registry) -> None:
    """``--floor``: per world and level, the default's fit (``em_soft``) and :func:`floor_fit`
    beside the clean fit of the same seeds (level 0), medians over the seeds."""
    print(f"medians over seeds {args.seeds}; load average at start {os.getloadavg()[0]:.2f}")
    print("| world | symbol error | clean fit s | default: ARI / fit s / x clean | floor: ARI / "
          "fit s (hard on true symbols + one soft round) / x clean |")
    print("|---|---|---|---|---|")
    for world in args.worlds:
        clean = [run_level(world, SIGMAS[world][0], seed, ["em_soft"], registry)["em_soft"]
                 for seed in args.seeds]
        c = _med(clean, "fit")
        for level in (args.levels if args.levels is not None else range(1, len(SIGMAS[world]))):
            runs = [run_level(world, SIGMAS[world][level], seed, ["em_soft"], registry)["em_soft"]
                    for seed in args.seeds]
            floors = [floor_fit(world, SIGMAS[world][level], seed, registry)
                      for seed in args.seeds]
            d, f = _med(runs, "fit"), _med(floors, "fit")
            print(f"| {world} | {_med(runs, 'err'):.1%} | {c:.2f} | {_med(runs, 'ari'):.4f} / "
                  f"{d:.2f} / {d / c:.1f}x | {_med(floors, 'ari'):.4f} / {f:.2f} "
                  f"({_med(floors, 'hard'):.2f} + {_med(floors, 'soft'):.2f}) / {f / c:.1f}x |",
                  flush=True)
    print(f"load average at end {os.getloadavg()[0]:.2f}")


def candidate_table(args, registry) -> None:
    """``--candidates``: one row per world, level, seed and share (:func:`candidates`)."""
    print("| world | sigma | seed | misreads | share kept | candidate symbols per step (of K) | "
          "steps with one candidate | misread steps whose true symbol stays a candidate |")
    print("|---|---|---|---|---|---|---|---|")
    for world in args.worlds:
        for level in (args.levels if args.levels is not None else range(1, len(SIGMAS[world]))):
            for seed in args.seeds:
                for r in candidates(world, SIGMAS[world][level], seed, args.candidates,
                                    registry):
                    print(f"| {world} | {SIGMAS[world][level]} | {seed} | {r['err']:.1%} | "
                          f"{r['share']:g} | {r['candidates']:.2f} of {r['K']} | {r['one']:.0%} "
                          f"| {r['true_kept']:.1%} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--levels", nargs="+", type=int, default=None,
                    help="indices into each world's SIGMAS (default: all but the clean one)")
    ap.add_argument("--candidates", nargs="+", type=float, metavar="SHARE",
                    help="per-step candidate symbols under phase 1's Gaussians (no refinement)")
    args = ap.parse_args()
    registry = Registry.load()
    if args.candidates:
        return candidate_table(args, registry)
    run_level("gridroom_8x6", 0.3, 0, ["em_soft"], registry)  # compile outside the timings
    return floor_table(args, registry)


if __name__ == "__main__":
    main()
