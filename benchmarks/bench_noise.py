"""Map quality against symbol errors: the split, the refinement (hard and soft symbol evidence)
and EM alone, as sensor noise grows.

    python benchmarks/bench_noise.py                 # every world, every noise level, seeds 0-2
    python benchmarks/bench_noise.py --quick         # gridroom 8x6 and random_graph 60, 3 levels, seed 0
    python benchmarks/bench_noise.py --worlds gridroom_8x6 --seeds 0 1 2 --methods split em_hard em_soft
    python benchmarks/bench_noise.py --worlds gridroom_8x6 --methods em_soft --soft growth.stage_cap=15 rtol=0.001
    python benchmarks/bench_noise.py --worlds gridroom_8x6 --methods em_soft --accelerate squarem
    python benchmarks/bench_noise.py --worlds gridroom_8x6 --methods em_soft --overrides refine.growth.start=auto
    python benchmarks/bench_noise.py --worlds gridroom_8x6 --levels 2 3 --side-by-side rs=reading.read_share=0.001

Each world is a ``topomap`` command (``WORLDS``); its noise is the Gaussian noise of the
observations (``noise.sigma``; ``SIGMAS`` per world, chosen so that the symbol error spans about
0-25 %).  The *symbol error* of a run is measured, not set: the fraction of non-GDS steps whose
phase-1 K-means symbol differs from the symbol most steps of their place got.  Per (world, sigma,
seed) the trajectory is simulated once (the run's config, ``data.heldout_steps=0``) and each
method fits a :class:`topomap.MapLearner` on it:

* ``split``    -- the paper's method (``refine=none``), from the ``em_hard`` fit's split;
* ``em_hard``  -- ``refine=em refine.evidence=hard`` (the refinement with exact symbols);
* ``em_soft``  -- ``refine=em`` (``evidence=auto``: soft symbol evidence when misreads are found);
* ``cscg``     -- ``refine=cscg refine.evidence=hard`` (EM alone);
* ``cscg_soft``-- ``refine=cscg`` (EM alone with soft evidence).

Every fit keeps the number of states its method finds (``learner.refined_size=free``), so the
table shows how misreads multiply states.  Reported: medians over the seeds of the symbol error,
ARI (states against the true places), states, fit seconds (phase 1 + split + refinement;
simulation and scoring excluded) and the process's CPU seconds over the fit, then the ARI of every
seed.  ``--overrides`` adds config overrides to every world's command; those of ``refine.*``
instead set the same parameters of every refinement method that has them
(``refine.growth.start=auto`` the EM methods', ``refine.soft.rtol=0.001`` the soft settings of
all four, the rest of ``soft`` as the config's), each method keeping its own ``evidence``.
Prints a Markdown table and draws ARI against symbol error, one line per method, into
``docs/img/noise.png`` (``--figure``).  ``--soft`` and ``--side-by-side`` take settings as
``GROUP.FIELD=VALUE`` (``reading.read_share=0.001``; a bare ``FIELD`` is a ``soft`` field, or
an old soft setting's name, :data:`~topomap.core.refine.renamed.SOFT_FIELDS`).
``--side-by-side NAME=KEY=VALUE[,KEY=VALUE]...`` instead
fits ``em_soft`` with its default soft settings and with each variant's, in turn on every
trajectory (the order rotated by the seed), and prints per variant the ARI, the E-steps (hard and
soft forward passes) and the CPU seconds of every seed, and its CPU time over the default's.  The machine's load average is printed with the table:
fit times are wall-clock seconds.
"""

from __future__ import annotations

import argparse
import os
import shlex
import statistics
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

from topomap.app.compose.command_line import compose
from topomap.app.run.data import load_data
from topomap.app.run.experiment import _as_dict, make_learner
from topomap.app.compose.registry import Registry
from topomap import metrics as M
from topomap.core.refine.first_stage import HARD_ACCELERATIONS
from topomap.core.refine.methods import CSCGRefinement, EMRefinement
from topomap.core.refine.renamed import SOFT_FIELDS
from topomap.core.refine.settings import Growth, HardRounds, Reading, SoftRounds

TEN_K = "data.n_steps=10000"
WORLDS = {
    "gridroom_8x6": f"env=gridroom clusters.ns=4 stop.n_states=48 {TEN_K}",
    "gridroom_12x12": ("env=gridroom env.width=12 env.height=12 env.n_symbols=8 clusters.ns=8 "
                       f"stop.n_states=144 {TEN_K}"),
    "random_graph_60": ("env=random_graph env.n_places=60 env.n_symbols=15 env.out_degree=3 "
                        f"clusters.ns=15 stop.n_states=60 {TEN_K}"),
    "office": f"{TEN_K}",
}
SIGMAS = {  # symbol errors measured at seed 0 in brackets
    "gridroom_8x6": [0.01, 0.3, 0.4, 0.5, 0.55],          # 0, 2.6, ?, 18 %
    "gridroom_12x12": [0.01, 0.3, 0.35, 0.4, 0.45],       # 0, 4.9, ?, 17 %
    "random_graph_60": [0.01, 0.17, 0.19, 0.22, 0.3],     # 0, 2.0, ?, ?, 11 %
    "office": [0.01, 0.1, 0.13, 0.16, 0.2],               # 0, 1.1, ?, ?, 22 %
}
QUICK = {"worlds": ["gridroom_8x6", "random_graph_60"], "levels": [0, 1, 3], "seeds": [0]}
METHODS = {
    "em_hard": lambda: EMRefinement(evidence="hard"),
    "em_soft": lambda: EMRefinement(evidence="auto"),
    "cscg": lambda: CSCGRefinement(evidence="hard"),
    "cscg_soft": lambda: CSCGRefinement(evidence="auto"),
}
ALL_METHODS = ["split", *METHODS]


def symbol_error(symbols, places, gds) -> float:
    """Fraction of non-GDS steps whose symbol is not their place's most frequent symbol."""
    keep = np.ones(symbols.size, bool) if gds is None else np.asarray(gds) < 0
    s, p = symbols[keep], places[keep]
    pairs = np.unique(p * (s.max() + 1) + s, return_counts=True)
    best = {}
    for code, n in zip(*pairs):
        place = code // (s.max() + 1)
        best[place] = max(best.get(place, 0), n)
    return 1.0 - sum(best.values()) / s.size


def run_level(world: str, sigma: float, seed: int, methods, registry, extra=()) -> dict:
    """Every method on one simulated trajectory: ``{method: {err, ari, states, fit, cpu}}``
    (``extra``: config overrides added to the world's command, :func:`refine_params`)."""
    overrides = [*shlex.split(WORLDS[world]), f"noise.sigma={sigma}", f"seed={seed}",
                 "data.heldout_steps=0", "output.figures=false", "output.progress=false",
                 "learner.refined_size=free",  # the states each method finds by itself
                 *(o for o in extra if not o.startswith("refine"))]  # those: refinement()
    cfg = _as_dict(compose(overrides, registry))
    parts = registry.build(cfg)
    (traj, _), _ = load_data(cfg, parts, registry)
    out = {}
    for name in methods:
        if name == "split" and "em_hard" in methods:
            continue  # read from em_hard's fit
        learner = make_learner(cfg, parts)
        learner.set_params(refine=None if name == "split" else refinement(name, extra, registry))
        cpu = time.process_time()
        learner.fit_trajectory(traj)
        cpu = time.process_time() - cpu
        t = learner.timings_
        err = symbol_error(learner.labels_phase1_, traj.places, traj.gds)
        out[name] = {"err": err, "ari": M.evaluate(traj.places, learner.labels_)["ari"],
                     "states": int(np.unique(learner.labels_).size),
                     "fit": t["phase1"] + t["phase2"] + t.get("refine", 0.0), "cpu": cpu}
        if name == "em_hard" and "split" in methods:
            out["split"] = {"err": err,
                            "ari": M.evaluate(traj.places, learner.labels_split_)["ari"],
                            "states": int(np.unique(learner.labels_split_).size),
                            "fit": t["phase1"] + t["phase2"], "cpu": float("nan")}
    return out


def refine_params(extra, component: str, registry) -> dict:
    """The parameters of ``refine=<component>`` the ``refine.*`` overrides of ``extra`` set, as
    the config gives them (a nested key such as ``refine.soft.rtol`` gives the whole ``soft``);
    overrides of keys the component does not have are left out."""
    own = _as_dict(compose([f"refine={component}"], registry))["refine"]
    mine = [o for o in extra if o.startswith("refine.")
            and o.split("=", 1)[0].split(".")[1] in own]
    if not mine:
        return {}
    cfg = _as_dict(compose([f"refine={component}", *mine], registry))["refine"]
    return {k: cfg[k] for k in sorted({o.split("=", 1)[0].split(".")[1] for o in mine})}


def refinement(name: str, extra, registry):
    """The refinement of method ``name`` (``METHODS``) with the ``refine.*`` overrides of
    ``extra`` (:func:`refine_params`; its ``evidence`` stays the method's)."""
    ref = METHODS[name]()
    params = refine_params(extra, ref.name, registry)
    return ref.set_params(**{k: v for k, v in params.items() if k != "evidence"})


def _med(runs, key):
    return statistics.median(r[key] for r in runs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--levels", nargs="+", type=int, default=None,
                    help="indices into each world's SIGMAS (default: all)")
    ap.add_argument("--methods", nargs="+", default=ALL_METHODS, choices=ALL_METHODS)
    ap.add_argument("--quick", action="store_true",
                    help=f"{QUICK['worlds']}, levels {QUICK['levels']}, seed 0")
    ap.add_argument("--soft", nargs="+", default=[], metavar="KEY=VALUE",
                    help="settings of em_soft and cscg_soft (e.g. growth.stage_cap=15)")
    ap.add_argument("--accelerate", default="auto", choices=HARD_ACCELERATIONS,
                    help="EM's acceleration in em_hard and em_soft (refine.hard.accelerate)")
    ap.add_argument("--overrides", nargs="+", default=[], metavar="KEY=VALUE",
                    help="config overrides added to every world's command (e.g. "
                         "refine.growth.start=auto: the refinements' own parameters)")
    ap.add_argument("--figure", default="docs/img/noise.png", help="'' for none")
    ap.add_argument("--side-by-side", nargs="+", default=[], metavar="NAME=KEY=VALUE[,...]",
                    help="em_soft with these soft settings beside the default, fit by fit")
    ap.add_argument("--from-table", nargs="+", metavar="FILE",
                    help="draw the figure from tables this script printed (no runs)")
    args = ap.parse_args()
    if args.from_table:
        results, methods = read_tables(args.from_table)
        draw(results, methods, Path(args.figure))
        return
    if args.quick:
        args.worlds, args.levels, args.seeds = QUICK["worlds"], QUICK["levels"], QUICK["seeds"]
    set_soft(args.soft, args.accelerate)
    registry = Registry.load()
    # compile the kernels outside the timings
    if "em_soft" in args.methods or args.side_by_side:
        run_level("gridroom_8x6", 0.3, 0, ["em_soft"], registry, args.overrides)
    if args.side_by_side:
        return side_by_side(args, registry)
    results = table(args, registry)
    if args.figure:
        draw(results, args.methods, Path(args.figure))


def table(args, registry) -> dict:
    """Print the table of ``args``' worlds, levels, seeds and methods; return its results
    (``{world: [(symbol error, {method: ARI median})]}``) for the figure."""
    results = {}
    print(f"medians over seeds {args.seeds}; load average at start {os.getloadavg()[0]:.2f} "
          f"on {os.cpu_count()} cores" + "; overrides " * bool(args.overrides)
          + " ".join(args.overrides))
    header = "| world | sigma | symbol error | " + " | ".join(
        f"{m} ARI / states / s / CPU s / ARI per seed" for m in args.methods) + " |"
    print(header)
    print("|" + "---|" * (header.count("|") - 1), flush=True)
    t_start = time.perf_counter()
    for world in args.worlds:
        sigmas = SIGMAS[world]
        for level in (args.levels if args.levels is not None else range(len(sigmas))):
            sigma = sigmas[level]
            runs = [run_level(world, sigma, s, args.methods, registry, args.overrides)
                    for s in args.seeds]
            per = {m: [r[m] for r in runs] for m in args.methods}
            err = _med(per[args.methods[0]], "err")
            results.setdefault(world, []).append((err, {m: _med(per[m], "ari")
                                                        for m in args.methods}))
            cells = " | ".join(
                f"{_med(per[m], 'ari'):.4f} / {'/'.join(str(r['states']) for r in per[m])} / "
                f"{_med(per[m], 'fit'):.2f} / {_med(per[m], 'cpu'):.2f} / "
                f"{','.join(format(r['ari'], '.4f') for r in per[m])}"
                for m in args.methods)
            print(f"| {world} | {sigma} | {err:.1%} | {cells} |", flush=True)
    print(f"total {time.perf_counter() - t_start:.0f} s; load average at end "
          f"{os.getloadavg()[0]:.2f}")
    return results


def soft_values(pairs) -> dict:
    """The settings ``GROUP.FIELD=VALUE`` of ``pairs`` (groups ``soft``, ``reading``,
    ``growth``, ``hard``; a bare ``FIELD`` of ``soft``, or an old soft setting's name), each
    value read as its setting's type: ``{group: {field: value}}``."""
    kinds = {f"{g}.{f.name}": f.type for g, cls in
             (("soft", SoftRounds), ("reading", Reading), ("growth", Growth),
              ("hard", HardRounds)) for f in fields(cls)}
    groups = {}
    for pair in pairs:
        key, _, value = pair.partition("=")
        key = key if "." in key else SOFT_FIELDS.get(key, f"soft.{key}")
        if key not in kinds:
            raise SystemExit(f"{key!r} is not a setting ({', '.join(kinds)})")
        group, name = key.split(".")
        groups.setdefault(group, {})[name] = {
            "int": int, "float": float, "str": str,
            "bool": lambda v: v.lower() == "true"}[kinds[key]](value)
    return groups


def side_by_side(args, registry) -> None:
    """``--side-by-side``: ``em_soft`` with the default soft settings and each variant's, in
    turn on every trajectory; one row per world, level and variant."""
    from topomap.core.refine import clones, evidence as evidence_module
    variants = [("default", {})] + [(v.split("=", 1)[0], soft_values(v.split("=", 1)[1].split(",")))
                                    for v in args.side_by_side]
    count = {"hard": 0, "soft": 0}

    def counted(kind, fn):
        def run(*a):
            count[kind] += 1
            return fn(*a)
        return run
    clones.clone_forward_into = counted("hard", clones.clone_forward_into)
    evidence_module.soft_forward = counted("soft", evidence_module.soft_forward)
    evidence_module.soft_forward_read = counted("soft", evidence_module.soft_forward_read)
    print(f"load average at start {os.getloadavg()[0]:.2f}; variants {variants}")
    print("| world | level | symbol error | variant | ARI median | ARI per seed | hard + soft "
          "E-steps per seed | CPU s per seed | CPU / default |")
    print("|---|---|---|---|---|---|---|---|---|")
    for world in args.worlds:
        for level in (args.levels if args.levels is not None else range(len(SIGMAS[world]))):
            runs = {name: [] for name, _ in variants}
            for seed in args.seeds:
                k = seed % len(variants)
                for name, soft in variants[k:] + variants[:k]:
                    METHODS["em_soft"] = lambda soft=soft: EMRefinement(evidence="auto", **soft)
                    count.update(hard=0, soft=0)
                    out = run_level(world, SIGMAS[world][level], seed, ["em_soft"], registry,
                                    args.overrides)["em_soft"]
                    runs[name].append({**out, **count})
            base = sum(r["cpu"] for r in runs["default"])
            for name, rs in runs.items():
                aris = " / ".join(format(r["ari"], ".4f") for r in rs)
                steps = " / ".join(f"{r['hard']} + {r['soft']}" for r in rs)
                cpus = " / ".join(format(r["cpu"], ".2f") for r in rs)
                print(f"| {world} | {level} | {_med(rs, 'err'):.1%} | {name} | "
                      f"{_med(rs, 'ari'):.4f} | {aris} | {steps} | {cpus} | "
                      f"{sum(r['cpu'] for r in rs) / base:.2f} |", flush=True)
    print(f"load average at end {os.getloadavg()[0]:.2f}")


def set_soft(pairs, accelerate: str = "auto") -> None:
    """The soft methods of ``METHODS`` with the settings ``GROUP.FIELD=VALUE`` of ``pairs``
    (:func:`soft_values`), and EM's ``hard.accelerate`` in ``em_hard`` and ``em_soft``."""
    hard = {"hard": {"accelerate": accelerate}}
    if accelerate != "auto":
        print(f"accelerate: {accelerate}")
        METHODS["em_hard"] = lambda: EMRefinement(evidence="hard", **hard)
        METHODS["em_soft"] = lambda: EMRefinement(evidence="auto", **hard)
    if not pairs:
        return
    groups = soft_values(pairs)
    print(f"soft settings: {groups}")
    METHODS["em_soft"] = lambda: EMRefinement(evidence="auto", **groups, **hard)
    METHODS["cscg_soft"] = lambda: CSCGRefinement(
        evidence="auto", **{g: v for g, v in groups.items() if g != "growth"})


def read_tables(files):
    """``(results, methods)`` as :func:`main` collects them, from printed tables (a method's
    cell is ``ARI / states / s``; rows of one world and sigma from several files are joined, the
    first file's symbol error and ARIs winning)."""
    rows, methods = {}, []
    for name in files:
        cols = None
        for line in Path(name).read_text().splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if line.startswith("| world"):
                cols = [c.split()[0] for c in cells[3:]]
                methods += [m for m in cols if m not in methods]
            elif line.startswith("| ") and cols and not line.startswith("|---"):
                err = float(cells[2].rstrip("%")) / 100
                aris = {m: float(c.split("/")[0]) for m, c in zip(cols, cells[3:])}
                old = rows.setdefault((cells[0], cells[1]), (err, {}))
                old[1].update({m: v for m, v in aris.items() if m not in old[1]})
    results = {}
    for (world, _), row in rows.items():
        results.setdefault(world, []).append(row)
    return results, methods


def draw(results, methods, path: Path) -> None:
    """ARI against symbol error, one panel per world, one line per method."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(4 * len(results), 3.4), squeeze=False,
                             sharey=True)
    for ax, (world, rows) in zip(axes[0], results.items()):
        rows = sorted(rows, key=lambda r: r[0])
        x = [100 * r[0] for r in rows]
        for m in methods:
            pts = [(xi, r[1][m]) for xi, r in zip(x, rows) if m in r[1]]
            if pts:
                ax.plot(*zip(*pts), marker="o", label=m)
        ax.set_title(world)
        ax.set_xlabel("symbol error (%)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("ARI (states vs places)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
