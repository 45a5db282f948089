"""The paper's split alone vs EM alone (CSCG's recipe) vs split + EM refinement, in every world.

    python benchmarks/bench_em.py                            # every world, T = 10,000 and 50,000
    python benchmarks/bench_em.py --worlds gridroom --sizes 10000 --seeds 0 --methods split em
    python benchmarks/bench_em.py --report                   # the table of the runs logged so far
    python benchmarks/bench_em.py --worlds minigrid_empty16 --sizes 50000 --methods split+em

The quantitative comparison with EM that the paper leaves to future work.  Every world is a
``topomap`` command (``WORLDS``: ``ns`` = the world's symbols, the state target = its places; the
paper's office also at its own T = 2,000; MiniGrid Empty-16x16, ``minigrid_empty16``, only when
asked for with ``--worlds``); for each walk length T and seed the data are those of
``topomap <command> data.n_steps=<T> data.heldout_steps=10000 seed=<seed>`` (the training walk
with the app's sensor noise, and a held-out walk of 10,000 steps), and three learners are fitted:

* ``split`` -- the paper's method (``refine=none``);
* ``em`` -- EM alone from phase 1 with CSCG's recipe (``refine=cscg``: 70 clones per symbol,
  pseudocount 2e-3, Baum-Welch to convergence, Viterbi training); its time is phase 1 + EM;
* ``split+em`` -- the split, then the refinement (``refine=em``).

With ``--cscg PATH`` (the authors' ``chmm_actions.py``, from
https://github.com/vicariousinc/naturecomm_cscg) a fourth learner, ``cscg``, is their code with
their recipe on the phase-1 symbols (70 clones per symbol, pseudocount 2e-3, ``learn_em_T`` up to
1,000 iterations, then ``learn_viterbi_T`` without pseudocount; the states are ``decode``'s
clones; its time is phase 1 + their EM), and a second table sets ``split+em`` beside it: both fit
times, their ratio and both ARIs.  Their model is dense, (actions x clones x clones) float32:
worlds past ``CSCG_MAX_BYTES`` are left out (FourRooms' 450 symbols would need 12 GB).

Columns, medians over the seeds: ARI and NMI against the true places, the states used, the
held-out log-likelihood per step (``TopologicalMap.score``, nats: a log-density, comparable
between rows of one world and T) and the fit time (seconds; phase 1 included).  Every run is
appended as JSON to ``--log``, with the load average and ``threads`` (the threads the compiled
passes may use, ``NUMBA_NUM_THREADS``) and the refinement's stages; runs already there are not
repeated, so an interrupted benchmark resumes.  ``--figure`` draws ARI against fit time.
``--versus KEY=VALUE ...`` fits every case a second time with other overrides, on the same data
and in turn with the first (``--rounds`` times each): one process, so the two times compare
under the same load.
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import json
import os
import statistics
import sys
import time
import types
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from topomap.app.compose.command_line import compose
from topomap.app.run.data import load_data
from topomap.app.compose.registry import Registry
from topomap.core.learner import MapLearner
from topomap.metrics import adjusted_rand, nmi
from topomap.core.split.threads import n_threads

from bench_worlds import EMPTY16, FOURROOMS, GRID12, RG60

WORLDS = {
    "office": ("office (the paper's)", ""),
    "gridroom": ("gridroom 8x6, 4 symbols", "env=gridroom clusters.ns=4 stop.n_states=48"),
    "gridroom_12x12": ("gridroom 12x12, 8 symbols", GRID12),
    "random_graph_60": ("random_graph 60 places, 15 symbols", RG60),
    "minigrid_empty": ("MiniGrid Empty-8x8", "env=minigrid clusters.ns=86 stop.n_states=140"),
    "minigrid_crossing": ("MiniGrid SimpleCrossingS9N1 (seed 0)",
                          "env=minigrid env.name=MiniGrid-SimpleCrossingS9N1-v0 clusters.ns=137 "
                          "stop.n_states=168"),
    "minigrid_fourrooms": ("MiniGrid FourRooms (seed 0)",
                           FOURROOMS.replace("data.n_steps=50000 ", "")),
    # the open room of the refinement's time target (not in the default run: --worlds)
    "minigrid_empty16": ("MiniGrid Empty-16x16", EMPTY16),
}
#: the worlds a plain run measures
DEFAULT_WORLDS = [w for w in WORLDS if w != "minigrid_empty16"]
METHODS = {"split": "none", "em": "cscg", "split+em": "em", "cscg": "none"}
#: the largest dense CSCG model (bytes of its count array) the authors' code is run on
CSCG_MAX_BYTES = 2 * 2**30
#: the authors' ``chmm_actions`` module (``--cscg``), or None
CSCG = None
OFFICE_T = 2000
HELDOUT = 10_000


def fit(registry, command: str, T: int, seed: int, method: str, data=None):
    """One fit; returns the record and the data (trajectory, held-out walk) for the next method.
    ``em_iterations``: the EM iterations of the refinement's hard round (its stages), the
    E-steps that are most of its time."""
    cfg = OmegaConf.to_container(compose(
        [*command.split(), f"data.n_steps={T}", f"data.heldout_steps={HELDOUT}", f"seed={seed}",
         f"refine={METHODS[method]}"], registry), resolve=True)
    parts = registry.build(cfg)
    if data is None:
        data, _ = load_data(cfg, parts, registry)
    traj, heldout = data
    learner = MapLearner(clusters=parts.clusters, metric=parts.metric, split=parts.split,
                         stop=parts.stop, refine=parts.refine, random_state=seed,
                         **cfg["learner"])
    t0 = time.perf_counter()
    learner.fit_trajectory(traj)
    seconds = time.perf_counter() - t0
    t = learner.timings_
    if method == "em":  # EM alone: the split it was handed is not part of its work
        seconds = t["phase1"] + t["refine"]
    if method == "cscg":
        return authors_cscg(learner, traj, T, seed), data
    m = learner.map_
    return {
        "T": T, "seed": seed, "method": method, "places": int(np.unique(traj.places).size),
        "ari": adjusted_rand(traj.places, learner.labels_), "nmi": nmi(traj.places, learner.labels_),
        "states": m.n_states, "seconds": seconds,
        "heldout": m.score(heldout.observations, heldout.actions, gds=heldout.gds,
                           lengths=heldout.lengths),
        "load": os.getloadavg()[0], "threads": n_threads(), "phase1": t["phase1"],
        "refine": t.get("refine"),
        "em_iterations": sum(st[2] for st in getattr(learner, "refine_info_", {}).get("stages",
                                                                                     [])),
        "stages": [list(st) for st in getattr(learner, "refine_info_", {}).get("stages", [])],
    }, data


def load_cscg(path: str):
    """The authors' ``chmm_actions.py`` as a module; without tqdm its progress bars are silent."""
    try:
        import tqdm  # noqa: F401
    except ImportError:
        class Bar:
            def __init__(self, n, **_):
                self.n = n

            def __iter__(self):
                return iter(range(self.n))

            def set_postfix(self, **_):
                pass

        sys.modules["tqdm"] = types.SimpleNamespace(trange=Bar)
    spec = importlib.util.spec_from_file_location("chmm_actions", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def authors_cscg(learner, traj, T: int, seed: int) -> dict:
    """CSCG by its authors' code and recipe on ``learner``'s phase-1 symbols (the episodes
    joined: their code takes one sequence); None fields where the dense model is too large."""
    x = np.unique(learner.labels_phase1_, return_inverse=True)[1].astype(np.int64)
    a = np.asarray(traj.actions, dtype=np.int64)
    n_clones = np.full(int(x.max()) + 1, 70, dtype=np.int64)
    record = {"T": T, "seed": seed, "method": "cscg", "places": int(np.unique(traj.places).size),
              "ari": None, "nmi": None, "states": None, "heldout": None, "seconds": None,
              "load": os.getloadavg()[0]}
    if (int(a.max()) + 1) * int(n_clones.sum()) ** 2 * 4 > CSCG_MAX_BYTES:
        return record
    t0 = time.perf_counter()
    model = CSCG.CHMM(n_clones=n_clones, pseudocount=2e-3, x=x, a=a, seed=seed)
    model.learn_em_T(x, a, n_iter=1000)
    model.pseudocount = 0.0
    model.learn_viterbi_T(x, a, n_iter=100)
    states = model.decode(x, a)[1]
    record.update(ari=adjusted_rand(traj.places, states), nmi=nmi(traj.places, states),
                  states=int(np.unique(states).size),
                  seconds=learner.timings_["phase1"] + time.perf_counter() - t0)
    return record


def warm_up(registry) -> None:
    """Compile (or load from numba's cache) every kernel before any timing."""
    for method in METHODS if CSCG else [m for m in METHODS if m != "cscg"]:
        fit(registry, "env=gridroom env.width=4 env.height=3 clusters.ns=4 stop.n_states=12",
            600, 0, method)


HEADER = ("| world | T | method | ARI | NMI | states (places) | held-out LL/step | fit s "
          "| x faster than EM |")


def table(records) -> list[str]:
    """Markdown rows of the medians per (world, T, method, overrides), in the order first seen
    (a run with ``--overrides`` names them after its method)."""
    groups: dict = {}
    for r in records:
        if r["method"] != "cscg":  # the authors' code: in versus()
            key = (r["world"], r["T"], r["method"], r.get("overrides", ""))
            groups.setdefault(key, []).append(r)
    rows = [HEADER, "|" + "---|" * (HEADER.count("|") - 1)]
    for (world, T, method, extra), rs in groups.items():
        med = {k: statistics.median(r[k] for r in rs)
               for k in ("ari", "nmi", "states", "heldout", "seconds")}
        em = groups.get((world, T, "em", ""))
        speed = statistics.median(r["seconds"] for r in em) / med["seconds"] if em else None
        rows.append(f"| {WORLDS[world][0]} | {T:,} | {method}{f' ({extra})' if extra else ''} | "
                    f"{med['ari']:.3f} | {med['nmi']:.3f} | {med['states']:g} "
                    f"({rs[0]['places']}) | {med['heldout']:.3f} | {med['seconds']:.2f} | "
                    f"{f'{speed:.0f}' if speed and method == 'split+em' else ''} |")
    return rows


VERSUS = ("| world | T | split+em s | CSCG (authors) s | x faster | split+em ARI | CSCG ARI |\n"
          "|---|---|---|---|---|---|---|")


def versus(records) -> list[str]:
    """Markdown rows, medians per (world, T): ``split+em`` beside the authors' CSCG."""
    groups: dict = {}
    for r in records:
        if r["method"] in ("split+em", "cscg"):
            groups.setdefault((r["world"], r["T"]), {}).setdefault(r["method"], []).append(r)
    rows = [VERSUS]
    for (world, T), by in groups.items():
        ours, theirs = by.get("split+em", []), [r for r in by.get("cscg", []) if r["seconds"]]
        if not ours or not by.get("cscg"):
            continue
        o_s, o_a = (statistics.median(r[k] for r in ours) for k in ("seconds", "ari"))
        if not theirs:
            rows.append(f"| {WORLDS[world][0]} | {T:,} | {o_s:.2f} | (model too large) | | "
                        f"{o_a:.3f} | |")
            continue
        c_s, c_a = (statistics.median(r[k] for r in theirs) for k in ("seconds", "ari"))
        rows.append(f"| {WORLDS[world][0]} | {T:,} | {o_s:.2f} | {c_s:.2f} | {c_s / o_s:.1f} | "
                    f"{o_a:.3f} | {c_a:.3f} |")
    return rows


def figure(records, path) -> None:
    """ARI against fit time, one panel per T, a marker per method and a colour per world."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = sorted({r["T"] for r in records if r["T"] != OFFICE_T})
    fig, axes = plt.subplots(1, len(sizes), figsize=(5 * len(sizes) + 3, 4.2), squeeze=False,
                             sharey=True)
    markers = {"split": "o", "em": "s", "split+em": "*", "cscg": "D"}
    colours = dict(zip(WORLDS, plt.get_cmap("tab10").colors))
    for ax, T in zip(axes[0], sizes):
        for world in WORLDS:
            pts = []
            for method in METHODS:
                rs = [r for r in records if (r["world"], r["T"], r["method"]) == (world, T, method)
                      and r["seconds"] is not None]
                if rs:
                    pts.append((statistics.median(r["seconds"] for r in rs),
                                statistics.median(r["ari"] for r in rs), method))
            for x, y, method in pts:
                ax.scatter(x, y, marker=markers[method], color=colours[world],
                           s=90 if method == "split+em" else 35, zorder=3)
        ax.set_xscale("log")
        ax.set_xlabel("fit time (s, log scale)")
        ax.set_title(f"T = {T:,}")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("ARI against the true places")
    handles = [plt.Line2D([], [], color=colours[w], lw=2, label=WORLDS[w][0]) for w in WORLDS]
    handles += [plt.Line2D([], [], color="k", ls="", marker=markers[m], label=m) for m in METHODS]
    fig.legend(handles=handles, loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 1 - 3 / (5 * len(sizes) + 3), 1))
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=DEFAULT_WORLDS, choices=list(WORLDS),
                    help="default: all but minigrid_empty16")
    ap.add_argument("--sizes", nargs="+", type=int, default=[10_000, 50_000])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--methods", nargs="+", default=None, choices=list(METHODS),
                    help="default: all (cscg only with --cscg)")
    ap.add_argument("--cscg", default=None, metavar="PATH",
                    help="the authors' chmm_actions.py: fit it too and print it beside split+em")
    ap.add_argument("--overrides", nargs="+", default=[], metavar="KEY=VALUE",
                    help="config overrides added to every world's command (e.g. "
                         "refine.hard.settle=0.01); kept in each record, which they tell apart")
    ap.add_argument("--versus", nargs="+", default=None, metavar="KEY=VALUE",
                    help="also fit every case with these overrides instead of --overrides, the "
                         "two in turn on the same data (one process: time ratios under load)")
    ap.add_argument("--rounds", type=int, default=1,
                    help="fit every case this many times (with --versus: in turn)")
    ap.add_argument("--log", default="benchmarks/results/bench_em.jsonl")
    ap.add_argument("--figure", default=None, help="write the ARI / fit time figure here")
    ap.add_argument("--report", action="store_true", help="only print the table of --log")
    args = ap.parse_args()
    global CSCG
    if args.cscg:
        CSCG = load_cscg(args.cscg)
    if args.methods is None:
        args.methods = [m for m in METHODS if CSCG or m != "cscg"]
    elif "cscg" in args.methods and not CSCG:
        ap.error("--methods cscg: give --cscg PATH (the authors' chmm_actions.py)")
    log = Path(args.log)
    done = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    if not args.report:
        registry = Registry.load()
        warm_up(registry)
        log.parent.mkdir(parents=True, exist_ok=True)
        extras = [" ".join(args.overrides)] + ([" ".join(args.versus)] if args.versus else [])
        have = {(r["world"], r["T"], r["seed"], r["method"], r.get("overrides", ""),
                 r.get("round", 0)) for r in done}
        for world in args.worlds:
            for T in sorted(set(args.sizes) | ({OFFICE_T} if world == "office" else set())):
                for seed in args.seeds:
                    data = None
                    for method, rnd, extra in itertools.product(
                            args.methods, range(args.rounds), extras):
                        if (world, T, seed, method, extra, rnd) in have:
                            continue
                        record, data = fit(registry, f"{WORLDS[world][1]} {extra}", T, seed,
                                           method, data)
                        record.update(world=world, overrides=extra, round=rnd)
                        done.append(record)
                        with log.open("a") as fh:
                            fh.write(json.dumps(record) + "\n")
                print("\n".join(table([r for r in done if (r["world"], r["T"]) == (world, T)])[2:]),
                      flush=True)
    print("\n".join(table(done)))
    if any(r["method"] == "cscg" for r in done):
        print()
        print("\n".join(versus(done)))
    if args.figure:
        figure(done, args.figure)


if __name__ == "__main__":
    main()
