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
