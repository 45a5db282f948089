"""Fit time and peak memory (RSS) as T grows: ten million steps, MiniGrid FourRooms, scoring.

    python benchmarks/bench_scale.py                                  # this checkout, medians of 3
    python benchmarks/bench_scale.py --baseline /path/to/old/venv/bin/python   # two versions, one run
    python benchmarks/bench_scale.py --baseline-checkout /path/to/old/checkout  # the same, one venv
    python benchmarks/bench_scale.py --repeats 1 --sizes 1e4 1e5 --no-fourrooms
    python benchmarks/bench_scale.py --report                          # reprint the last results
    python benchmarks/bench_scale.py --end-to-end 1e6                 # `topomap data=file` at T = 1e6
    python benchmarks/bench_scale.py --sizes 1e7 --refine-max-T 0 --no-fourrooms --one-thread
    python benchmarks/bench_scale.py --sizes 1e6 1e7 --refine-max-T 0 --no-fourrooms --float32 \
        --baseline-checkout /path/to/old/checkout --baseline-max-T 1e7 --save-labels /tmp/labels
    python benchmarks/bench_scale.py --stream /data/logs --sizes 1e7 1e8 --repeats 1  # fit_stream

``--stream DIR`` times the streamed fit (``MapLearner.fit_stream``) on folders of 100 logs of
``benchmarks/stream_logs.py`` (written under ``DIR`` when missing: 630 MB at 10^7 steps, 6.3 GB
at 10^8), beside the in-memory fit of the same logs (``--runs memory``) and on a local Ray
cluster of 1 and 2 workers (``ray:1``, ``ray:2``), each run's labels compared with the first's
(ARI and identity) and with the places.

``--baseline`` runs every measurement also with another Python interpreter (a virtual environment
with another version of topomap installed, numba included), interleaved with this checkout's, so
that both are timed under the same load; ``--baseline-max-T`` limits its sizes.
``--baseline-checkout DIR`` does the same with this Python and the ``topomap/`` of another
checkout (``DIR`` put first on ``PYTHONPATH`` of the baseline's processes).
``--one-thread`` also times this checkout with ``NUMBA_NUM_THREADS=1`` (rows ``1th``: the split's
passes and proposals on one thread; the same labels).  ``--float32`` also times this checkout on
the walk's observations as float32 (rows ``f32``: half the data's memory).  ``--save-labels DIR``
writes every walk fit's ``labels_`` to ``DIR`` (named by checkout, T and dtype) to compare them.

Worlds:

* ``aliased_walk`` of ``benchmarks/bench_fit.py`` (D = 15, 17 actions, Gaussian noise 0.02):
  ns 50 -> 100 states at T = 1e4 and 1e5, ns 100 -> 200 at T = 1e6 and 1e7.  The data are made in
  blocks (the same numbers as ``aliased_walk``), so that making them peaks at the size of the data.
  Fitted with the split (rows ``new``) and with the split + ``refine="em"`` (rows ``em``, up to
  ``--refine-max-T``, default 1e7).
* MiniGrid FourRooms (``MiniGridWorld("MiniGrid-FourRooms-v0", 0)``, noise-free 147-D views):
  ns = the number of distinct views of the walk, stopping at 1036 states, at T = 10,000 and
  50,000; then held-out scoring (``map.score``) of a second 50,000-step walk on the T = 50,000 map
  (a baseline whose scoring builds a (steps x states x features) array scores 1,000 steps).

Every measurement runs in a fresh subprocess.  Peak RSS: the process's ``ru_maxrss`` right after
the fit (``getrusage(RUSAGE_SELF)``) and, for scoring, the ``ru_maxrss`` that ``os.wait4`` reports
for the finished child; both include the interpreter and the data.  The time is the wall time of
``fit`` (or ``score``) alone, after a warm-up fit (numba compilation excluded), beside the
process's CPU time of the fit (``CPU``: all its threads; less sensitive than the wall time to
other work on the machine).  On the aliased walk the versions take turns within each repeat.
``k`` is the least-squares slope of log(time) on log(T) over the aliased-walk sizes.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

HERE = Path(__file__).resolve().parent
#: this checkout's Python, and the label of its rows
CURRENT = ("new", sys.executable)
#: this checkout with the refinement after the split (``refine="em"``)
REFINED = ("em", sys.executable)
#: this checkout on one thread (``--one-thread``: rows ``1th``)
ONE_THREAD = {"NUMBA_NUM_THREADS": "1"}
#: variables set on top of this process's for the children of a version (by its label)
ENVS = {"1th": ONE_THREAD}
SAVE = []  #: ``save=DIR`` with ``--save-labels DIR``: every walk child writes its labels there
WALK_SIZES = {10**4: (50, 100), 10**5: (50, 100), 10**6: (100, 200), 10**7: (100, 200)}
FOURROOMS = ("MiniGrid-FourRooms-v0", 0, 1036)
TARGETS = {10**5: (1.0, None), 10**6: (8.0, 1.0), 10**7: (100.0, 6.0)}


# ---------------------------------------------------------------------- data
@njit(cache=True)
def _walk(succ, actions):
    places = np.empty(actions.size, dtype=np.int64)
    p = 0
    for t in range(actions.size):
        places[t] = p
        p = succ[p, actions[t]]
    return places


def aliased_walk_blocks(T, D, ns, n_places, n_actions, seed=0, block=1 << 18,
                        dtype=np.float64):
    """``bench_fit.aliased_walk`` (same random streams, same numbers), made block by block (as
    float32: the float64 values rounded)."""
    rng = np.random.default_rng(seed)
    succ = rng.integers(0, n_places, size=(n_places, n_actions))
    symbol = np.concatenate([np.arange(ns), rng.integers(0, ns, n_places - ns)])
    centres = rng.uniform(0, 1, size=(ns, D))
    actions = rng.integers(0, n_actions, size=T)
    places = _walk(succ, actions)
    X = np.empty((T, D), dtype=dtype)
    for start in range(0, T, block):
        stop = min(start + block, T)
        X[start:stop] = centres[symbol[places[start:stop]]] + rng.normal(  # the float64 sum
            0, 0.02, size=(stop - start, D))
    return X, actions, places


def fourrooms_walks(path: Path, T: int) -> None:
    """Simulate a training and a held-out walk of ``T`` steps and store them in ``path``."""
    from topomap.worlds import MiniGridWorld, RandomExplorer

    world = MiniGridWorld(FOURROOMS[0], FOURROOMS[1])
    a = world.simulate(T, RandomExplorer(), np.random.default_rng(0))
    b = world.simulate(T, RandomExplorer(), np.random.default_rng(1))
    np.savez(path, X=a.observations, u=a.actions, places=a.places, Xh=b.observations,
             uh=b.actions)


# ---------------------------------------------------------------------- children
def _learner(**kw):
    from topomap import MapLearner

    return MapLearner(**kw)


def _fit_record(X, u, places, ns, S, **kw):
    from topomap.metrics import adjusted_rand  # the same name in every version

    learner = _learner(n_clusters=ns, n_states=S, random_state=0, **kw)
    t0, c0 = time.perf_counter(), time.process_time()
    learner.fit(X, u)
    total, cpu = time.perf_counter() - t0, time.process_time() - c0
    fit_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
    return learner, {"time": total, "cpu": cpu, "refine": 0.0, **learner.timings_, "S": learner.map_.n_states,
                     "fit_rss_gb": fit_rss,
                     "ari0": adjusted_rand(places, learner.labels_phase1_),
                     "ari1": adjusted_rand(places, learner.labels_),
                     "method": getattr(learner, "phase1_method_", "full")}


def child_walk(T, *flags):
    """Fit the walk of T steps; ``flags``: ``em`` (``refine="em"``), ``f32`` (float32
    observations), ``save=DIR`` (write ``labels_`` to ``DIR/labels-<checkout>-<T>-<dtype>.npy``)."""
    ns, S = WALK_SIZES[T]
    dtype = np.float32 if "f32" in flags else np.float64
    X, u, places = aliased_walk_blocks(T, 15, ns, S, 17, dtype=dtype)
    data_rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    kw = {"refine": "em"} if "em" in flags else {}
    _learner(n_clusters=20, n_states=30, **kw).fit(X[:2000], u[:2000])  # warm caches, compile
    learner, rec = _fit_record(X, u, places, ns, S, **kw)
    for folder in (f[5:] for f in flags if f.startswith("save=")):
        name = Path(sys.modules["topomap"].__file__).resolve().parents[1].name
        np.save(Path(folder) / f"labels-{name}-{T}-{np.dtype(dtype).name}.npy", learner.labels_)
    return {**rec, "data_rss_kb": data_rss}


def child_fourrooms(T, data, score_steps):
    d = np.load(data)
    X, u, places = d["X"][:T], d["u"][:T], d["places"][:T]
    ns = np.unique(X, axis=0).shape[0]
    _learner(n_clusters=20, n_states=30).fit(d["X"][:2000], d["u"][:2000])
    learner, rec = _fit_record(X, u, places, ns, FOURROOMS[2])
    rec["ns"] = ns
    if score_steps:
        learner.map_.score(d["Xh"][:50], d["uh"][:50])  # compile
        t0 = time.perf_counter()
        rec["loglik"] = learner.map_.score(d["Xh"][:score_steps], d["uh"][:score_steps])
        rec["score_time"] = time.perf_counter() - t0
        rec["score_steps"] = score_steps
    return rec


def run_child(python, *args, env=None) -> dict:
    """Run ``bench_scale.py --child ...`` with ``python`` in a fresh process (``env``: variables
    set on top of this one's); its result plus its peak RSS."""
    cmd = [python, str(Path(__file__).resolve()), "--child", *map(str, args)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, **env} if env else None)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed with status {status}")
    rec = json.loads(out.strip().splitlines()[-1])
    rec["rss_gb"] = usage.ru_maxrss * 1024 / 1e9
    return rec


# ---------------------------------------------------------------------- parent
def median_record(records: list) -> dict:
    """Medians of the numeric fields over repeats (the first record's other fields)."""
    out = dict(records[0])
    for key, value in records[0].items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            out[key] = statistics.median(r[key] for r in records)
    out["load"] = statistics.median(r["load"] for r in records)
    return out


def measure(repeats, python, *args, env=None) -> dict:
    """Median over ``repeats`` fresh processes of ``python`` (``env``: see :func:`run_child`)."""
    records = []
    for _ in range(repeats):
        load = os.getloadavg()[0]
        records.append({**run_child(python, *args, env=env), "load": load})
    return median_record(records)


def walk_rows(sizes, repeats, versions, baseline_max_T, refine_max_T):
    """Every size fitted by every version, the versions taking turns within each repeat (so
    that a change of load falls on all of them alike)."""
    rows = []
    for T in sizes:
        todo = [(impl, python) for impl, python in versions
                if not (impl == "old" and T > baseline_max_T)
                and not (impl == "em" and T > refine_max_T)]
        records = {impl: [] for impl, _ in todo}
        for _ in range(repeats):
            for impl, python in todo:
                load = os.getloadavg()[0]
                flags = {"em": ["em"], "f32": ["f32"]}.get(impl, []) + SAVE
                rec = run_child(python, "walk", T, *flags, env=ENVS.get(impl))
                records[impl].append({**rec, "load": load})
        for impl, _ in todo:
            rec = median_record(records[impl])
            rows.append({"world": "aliased_walk", "T": T, "impl": impl, **rec,
                         "times": [r["time"] for r in records[impl]]})
            print(format_row(rows[-1]), flush=True)
    return rows


def fourrooms_rows(repeats, data, versions):
    rows = []
    for T, score in ((10_000, 0), (50_000, 50_000)):
        for impl, python in versions:
            if impl in ("em", "1th", "f32"):
                continue
            steps = min(score, 1000) if impl == "old" else score
            rec = measure(repeats if T < 50_000 or impl == "new" else 1, python, "fourrooms", T,
                          data, steps, env=ENVS.get(impl))
            rows.append({"world": "FourRooms", "T": T, "impl": impl, **rec})
            print(format_row(rows[-1]), flush=True)
    return rows


def format_row(r) -> str:
    text = (f"{r['world']:12s} T={r['T']:>10,} {r['impl']:3s} [{r['method']:8s}] "
            f"-> {r['S']:5d} states | phase1 {r['phase1']:7.2f} s  phase2 {r['phase2']:7.2f} s  "
            f"refine {r.get('refine', 0.0):7.2f} s  fit {r['time']:7.2f} s (CPU {r.get('cpu', 0.0):6.2f} s)  RSS {r['fit_rss_gb']:5.2f} GB | ARI {r['ari0']:.3f} -> "
            f"{r['ari1']:.3f} | load {r['load']:.1f}")
    if r.get("score_steps"):
        text += (f" | score {r['score_steps']:,} steps {r['score_time']:.2f} s, "
                 f"RSS with scoring {r['rss_gb']:.2f} GB")
    return text


def exponent(rows, impl, min_T=0) -> float | None:
    """Least-squares slope of log(fit time) on log(T) over the aliased-walk sizes >= ``min_T``."""
    pts = [(r["T"], r["time"]) for r in rows
           if r["world"] == "aliased_walk" and r["impl"] == impl and r["T"] >= min_T]
    if len(pts) < 2:
        return None
    T, t = np.log(np.array(pts, dtype=float)).T
    return float(np.polyfit(T, t, 1)[0])


def figure(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for impl, style in (("old", "o--"), ("new", "s-"), ("em", "^-")):
        pts = sorted((r["T"], r["time"]) for r in rows
                     if r["world"] == "aliased_walk" and r["impl"] == impl)
        if pts:
            k = exponent(rows, impl)
            name = {"old": "baseline", "new": "this version", "em": "split + refine=em"}[impl]
            ax.loglog(*zip(*pts), style, label=f"{name} (k = {k:.2f})" if k else name)
    ax.set_xlabel("steps T")
    ax.set_ylabel("fit time (s)")
    ax.set_title("aliased_walk, D = 15, 17 actions")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def write_big(path: Path, T: int) -> None:
    """``aliased_walk`` of T steps (ns 100, 200 places) as a trajectory file, with the places and
    a position per place (on a 20 x 10 grid) so that the run draws every figure."""
    from topomap import Trajectory, save_trajectory

    ns, S = WALK_SIZES.get(T, (100, 200))
    X, u, places = aliased_walk_blocks(T, 15, ns, S, 17)
    grid = np.column_stack([np.arange(S) % 20, np.arange(S) // 20]).astype(float)
    save_trajectory(Trajectory(X, u, places=places, positions=grid[places]), path)


def end_to_end(T: int, folder: Path) -> dict:
    """Wall time and peak RSS of ``topomap data=file data.path=big.npz ...`` at T steps, every
    output written; returns the record (also the run's own timings)."""
    ns, S = WALK_SIZES.get(T, (100, 200))
    data, run = folder / "big.npz", folder / "run"
    write_big(data, T)
    cmd = [sys.executable, "-m", "topomap", "data=file", f"data.path={data}", f"clusters.ns={ns}",
           f"stop.n_states={S}", "output.progress=false", f"hydra.run.dir={run}"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate()
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err.strip().splitlines()[-1]}")
    metrics = json.loads((run / "metrics.json").read_text())
    rec = {"T": T, "wall_s": wall, "rss_gb": usage.ru_maxrss * 1024 / 1e9,
           "timings": metrics["timings"], "ari": metrics["ground_truth"]["final"]["ari"],
           "files": sorted(p.name for p in run.iterdir())}
    print(f"end to end, T = {T:,}: {wall:.1f} s wall, peak RSS {rec['rss_gb']:.2f} GB | "
          + ", ".join(f"{k} {v:.1f} s" for k, v in metrics["timings"].items())
          + f" | ARI {rec['ari']:.3f} | {' '.join(rec['files'])}", flush=True)
    return rec


def stream_rows(root: Path, sizes, runs, repeats, files: int = 100) -> list:
    """Every run of ``runs`` ("memory", "local", "ray:<workers>") on a folder of ``files``
    aliased-walk logs of each size (written under ``root`` when missing), the labels compared
    with the first run's (:mod:`stream_logs`)."""
    from stream_logs import compare, format_stream, write_logs

    rows = []
    for T in sizes:
        folder = root / f"logs-{T:.0e}"
        if not folder.is_dir():
            write_logs(folder, T, files)
        ns, S = WALK_SIZES.get(T, (100, 200))
        recs = []
        for run in runs:
            kind = "memory" if run == "memory" else "stream"
            engine, _, workers = ("local" if run == "memory" else run).partition(":")
            out = root / f"labels-{T:.0e}-{run.replace(':', '')}.npy"
            rec = measure(repeats, sys.executable, "fit", kind, folder, ns, S, engine,
                          workers or 0, out)
            recs.append({**rec, "T": T, "labels": str(out)})
        compare(recs, folder)
        for r in recs:
            print(format_stream(r), flush=True)
        rows += recs
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", nargs="+", type=float, default=sorted(WALK_SIZES))
    ap.add_argument("--baseline", help="another Python (virtual environment) to time beside this one")
    ap.add_argument("--baseline-checkout", metavar="DIR",
                    help="time the topomap/ of another checkout (on PYTHONPATH) beside this one")
    ap.add_argument("--baseline-max-T", type=float, default=1e6)
    ap.add_argument("--refine-max-T", type=float, default=1e7,
                    help="largest T also fitted with refine=em (0: none)")
    ap.add_argument("--one-thread", action="store_true",
                    help="also time this checkout with NUMBA_NUM_THREADS=1 (rows 1th)")
    ap.add_argument("--float32", action="store_true",
                    help="also time this checkout on float32 observations (rows f32)")
    ap.add_argument("--save-labels", metavar="DIR",
                    help="every walk fit writes its labels_ to DIR (to compare versions)")
    ap.add_argument("--no-fourrooms", action="store_true")
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--report", action="store_true", help="reprint the last run's results")
    ap.add_argument("--end-to-end", type=float, metavar="T",
                    help="only time `topomap data=file` on a T-step recording")
    ap.add_argument("--stream", metavar="DIR", help="only the streamed fit: folders of 100 logs "
                    "under DIR (written when missing), one per --sizes")
    ap.add_argument("--runs", nargs="+", default=["memory", "local", "ray:1", "ray:2"],
                    help="with --stream: memory (fit), local, ray:<workers> (fit_stream)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(exist_ok=True)
    if args.stream:
        rows = stream_rows(Path(args.stream), [int(s) for s in args.sizes], args.runs,
                           args.repeats)
        (out / "bench_stream.json").write_text(json.dumps(rows, indent=1))
        return None
    if args.end_to_end:
        with tempfile.TemporaryDirectory() as tmp:
            rec = end_to_end(int(args.end_to_end), Path(tmp))
        (out / f"end_to_end_{int(args.end_to_end)}.json").write_text(json.dumps(rec, indent=1))
        return None
    if args.report:
        rows = json.loads((out / "bench_scale.json").read_text())
        for row in rows:
            print(format_row(row))
        return report(rows, out)
    if args.baseline_checkout:
        args.baseline = sys.executable
        ENVS["old"] = {"PYTHONPATH": str(Path(args.baseline_checkout).resolve())}
    versions = ([("old", args.baseline)] if args.baseline else []) + [CURRENT, REFINED]
    if args.one_thread:
        versions.insert(-1, ("1th", sys.executable))
    if args.float32:
        versions.insert(-1, ("f32", sys.executable))  # float32 observations
    if args.save_labels:
        Path(args.save_labels).mkdir(parents=True, exist_ok=True)
        SAVE.append(f"save={Path(args.save_labels).resolve()}")
    rows = walk_rows([int(s) for s in args.sizes], args.repeats, versions, args.baseline_max_T,
                     args.refine_max_T)
    if not args.no_fourrooms:
        with tempfile.TemporaryDirectory() as tmp:
            data = Path(tmp) / "fourrooms.npz"
            fourrooms_walks(data, 50_000)
            rows += fourrooms_rows(args.repeats, data, versions)
    (out / "bench_scale.json").write_text(json.dumps(rows, indent=1))
    report(rows, out)


def report(rows, out: Path) -> None:
    """Print the cost exponents and draw the log-log figure."""
    for impl in ("old", "new", "em"):
        for min_T in (0, 10**5):
            k = exponent(rows, impl, min_T)
            label = "all sizes" if not min_T else "T >= 1e5"
            print(f"cost exponent k ({impl}, {label}): " + (f"{k:.3f}" if k is not None else "-"))
    figure(rows, out / "fit_time_loglog.png")


def child_main(argv):
    kind, T, *rest = argv
    if kind == "fit":
        from stream_logs import child_fit

        rec = child_fit(T, rest[0], int(rest[1]), int(rest[2]), rest[3], int(rest[4]), rest[5])
    elif kind == "walk":
        rec = child_walk(int(T), *rest)
    else:
        rec = child_fourrooms(int(T), rest[0], int(rest[1]))
    import topomap

    rec["checkout"] = str(Path(topomap.__file__).resolve().parents[1])  # the code timed
    print(json.dumps(rec))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child_main(sys.argv[2:])
    else:
        main()
