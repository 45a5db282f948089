"""Folders of logs for the streamed fit (``bench_scale.py --stream``): an aliased walk cut into
files, and the streamed fit timed beside the in-memory one.

The world is ``aliased_walk``'s (:mod:`bench_scale`): ``n_places`` places, 17 actions, each place
showing one of ``ns`` views (the first ``ns`` places one each, the others a random one of them:
perceptual aliasing), a view a point of [0, 1]^15 read with Gaussian noise 0.02.  Log ``i`` is a
random walk of its own (its seed ``[seed, i]``) from a random place: one episode.  Files are
``.npz`` without compression: ``observations`` float32 (as a sensor log holds them), ``actions``
int8, ``places`` int16 -- 10^6 steps are 63 MB, 10^8 steps 6.3 GB.

    python benchmarks/stream_logs.py write DIR --steps 1e8 --files 100
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from numba import njit

D, N_ACTIONS, NOISE = 15, 17, 0.02


def world(ns: int, n_places: int, seed: int = 0):
    """``(succ, symbol, centres)`` of the aliased world (``aliased_walk``'s, drawn alike)."""
    rng = np.random.default_rng(seed)
    succ = rng.integers(0, n_places, size=(n_places, N_ACTIONS))
    symbol = np.concatenate([np.arange(ns), rng.integers(0, ns, n_places - ns)])
    centres = rng.uniform(0, 1, size=(ns, D))
    return succ, symbol, centres


@njit(cache=True)
def _walk_from(succ, actions, start):
    places = np.empty(actions.size, dtype=np.int16)
    p = start
    for t in range(actions.size):
        places[t] = p
        p = succ[p, actions[t]]
    return places


def one_log(w, steps: int, seed: int, i: int):
    """``(observations float32, actions int8, places int16)`` of log ``i``."""
    succ, symbol, centres = w
    rng = np.random.default_rng([seed, i])
    actions = rng.integers(0, N_ACTIONS, size=steps).astype(np.int8)
    places = _walk_from(succ, actions, int(rng.integers(0, succ.shape[0])))
    X = centres[symbol[places]].astype(np.float32)
    X += rng.normal(0, NOISE, size=X.shape).astype(np.float32)
    return X, actions, places


def write_logs(folder: Path, steps: int, files: int, ns: int = 100, n_places: int = 200,
               seed: int = 0) -> list[Path]:
    """``files`` logs of ``steps / files`` steps each in ``folder`` (``log-000.npz``, ...)."""
    folder.mkdir(parents=True, exist_ok=True)
    w = world(ns, n_places, seed)
    per = steps // files
    paths = []
    for i in range(files):
        X, u, p = one_log(w, per + (steps - per * files if i == files - 1 else 0), seed, i)
        path = folder / f"log-{i:03d}.npz"
        tmp = path.with_suffix(".part")
        with open(tmp, "wb") as fh:
            np.savez(fh, observations=X, actions=u, places=p)
        tmp.rename(path)
        paths.append(path)
    return paths


def read_logs(folder: Path, dtype=np.float64):
    """Every log of ``folder`` in memory: ``(X, u, places, lengths)`` (the in-memory fit's
    input)."""
    paths = sorted(folder.glob("log-*.npz"))
    parts = [np.load(p) for p in paths]
    lengths = np.array([d["actions"].size for d in parts])
    X = np.empty((lengths.sum(), D), dtype=dtype)
    start = 0
    for d, n in zip(parts, lengths):
        X[start:start + n] = d["observations"]
        start += n
    u = np.concatenate([d["actions"].astype(np.int64) for d in parts])
    places = np.concatenate([d["places"] for d in parts])
    return X, u, places, lengths


# ---------------------------------------------------------------------- children
def child_fit(kind: str, folder: str, ns: int, S: int, engine: str, workers: int, out: str):
    """One fit of the logs of ``folder`` in this process: ``kind`` "stream" (``fit_stream``
    on ``engine`` with ``workers``) or "memory" (``fit`` on every log read into float64 arrays,
    ``lengths`` one per log); its labels saved to ``out`` (.npy), its record returned."""
    import resource

    from topomap import MapLearner

    folder = Path(folder)
    warm = sorted(folder.glob("log-*.npz"))[:1]
    MapLearner(n_clusters=20, n_states=30).fit_stream(warm)  # compile
    learner = MapLearner(n_clusters=ns, n_states=S, random_state=0)
    if kind == "memory":
        X, u, _, lengths = read_logs(folder)
        MapLearner(n_clusters=20, n_states=30).fit(X[:2000], u[:2000])
        t0, c0 = time.perf_counter(), time.process_time()
        learner.fit(X, u, lengths=lengths)
    else:
        t0, c0 = time.perf_counter(), time.process_time()
        learner.fit_stream(folder, engine=None if engine == "local" else engine,
                           workers=workers or None)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
    np.save(out, learner.labels_)
    return {"kind": kind, "steps": int(learner.labels_.size), "engine": engine, "workers": workers, "time": wall, "cpu": cpu,
            "fit_rss_gb": rss, **learner.timings_, **getattr(learner, "stream_info_", {}),
            "S": learner.map_.n_states, "method": learner.phase1_method_}


def compare(rows, folder: Path) -> None:
    """ARI of every row's labels against the places of the logs of ``folder`` and against the
    first row's labels, and whether they are the same labels (the rows' ``labels`` files)."""
    from topomap.metrics import adjusted_rand

    places = np.concatenate([np.load(p)["places"] for p in sorted(folder.glob("log-*.npz"))])
    first = np.load(rows[0]["labels"])
    for r in rows:
        lab = np.load(r["labels"])
        r["ari"] = adjusted_rand(places, lab)
        r["ari_vs_first"] = adjusted_rand(first, lab)
        r["same_labels"] = bool(np.array_equal(first, lab))


def format_stream(r) -> str:
    return (f"{r['kind']:6s} {r['engine']:5s} x{r['workers'] or 1} T={r.get('steps', 0):>11,} "
            f"[{r['method']}] -> {r['S']} states | phase1 {r['phase1']:7.1f} s phase2 "
            f"{r['phase2']:6.1f} s | fit {r['time']:7.1f} s (CPU {r['cpu']:6.1f} s) "
            f"RSS {r['fit_rss_gb']:5.2f} GB | ARI {r.get('ari', float('nan')):.4f}, vs first "
            f"{r.get('ari_vs_first', float('nan')):.4f}, same labels {r.get('same_labels')} "
            f"| load {r['load']:.1f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("action", choices=["write"])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--steps", type=float, default=1e7)
    ap.add_argument("--files", type=int, default=100)
    args = ap.parse_args()
    t0 = time.perf_counter()
    write_logs(args.folder, int(args.steps), args.files)
    print(f"{int(args.steps):,} steps in {args.files} files: {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
