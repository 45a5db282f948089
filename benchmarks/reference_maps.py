"""The reference maps: write the map files of a fixed set of configs, or compare two such sets.

A change that should not alter any map is checked by writing the maps with the version before
and the version after, then comparing the two folders byte for byte::

    python benchmarks/reference_maps.py run /tmp/maps-before      # on the version before
    python benchmarks/reference_maps.py run /tmp/maps-after       # on the version after
    python benchmarks/reference_maps.py compare /tmp/maps-before /tmp/maps-after

``run --only NAME ...`` writes some of them.  Each config is one ``topomap`` run (figures off; the
map files are ``MAP_FILES``); ``compare`` lists every file that differs or is missing and exits 1
if any does.
"""

from __future__ import annotations

import argparse
import filecmp
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: the files of a run that hold the map and the data it was learned from (metrics.json holds
#: timings, so it is not compared)
MAP_FILES = ("trajectory.npz", "map.json", "map.graphml", "states.csv")

#: name -> the command-line overrides of one reference run
CONFIGS = {
    "paper": [],
    "paper_em": ["refine=em"],
    "paper_dropout": ["noise=dropout"],
    "paper_auto": ["clusters=bic", "stop=auto"],
    "paper_10k_em": ["data.n_steps=10000", "refine=em"],
    "gridroom_s0": ["experiment=gridroom", "seed=0"],
    "gridroom_s1": ["experiment=gridroom", "seed=1"],
    "gridroom_split": ["env=gridroom", "clusters.ns=4", "stop.n_states=48"],
    "gridroom_misread": ["experiment=gridroom", "noise.sigma=0.4"],
    "random_graph_em": ["env=random_graph", "refine=em"],
    "random_graph_cscg": ["env=random_graph", "refine=cscg"],
    "minigrid_empty": ["experiment=minigrid_empty"],
    "arena_two_rooms": ["experiment=arena_two_rooms"],
    "arena_robot": ["experiment=arena_two_rooms", "actions=turns", "sensor.frame=egocentric"],
}


def run(out: Path, names) -> int:
    out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for name in names:
        folder = out / name
        cmd = ["topomap", *CONFIGS[name], f"hydra.run.dir={folder}", "output.figures=false",
               "output.progress=false", "output.overwrite=true"]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        took = time.perf_counter() - t0
        status = "ok" if proc.returncode == 0 else f"FAILED ({proc.returncode})"
        print(f"{name:22s} {status:12s} {took:7.1f} s   {' '.join(CONFIGS[name])}", flush=True)
        if proc.returncode:
            failed += 1
            (folder / "error.txt").parent.mkdir(parents=True, exist_ok=True)
            (folder / "error.txt").write_text(proc.stderr)
    return 1 if failed else 0


def _leaves(obj, path=""):
    """``(path, value)`` of every leaf of a JSON value; a list of numbers is one array leaf
    (float where any of them is, so a changed integer among floats counts as a float)."""
    if isinstance(obj, dict):
        for key, value in obj.items():
            yield from _leaves(value, f"{path}/{key}")
    elif isinstance(obj, list) and obj and all(isinstance(v, (int, float)) for v in obj):
        yield path, np.asarray(obj)
    elif isinstance(obj, list):
        for i, value in enumerate(obj):
            yield from _leaves(value, f"{path}[{i}]")
    else:
        yield path, obj


def _arrays_differ(pairs) -> str:
    """``"floats only ..."`` where every ``(where, x, y)`` of ``pairs`` has one shape and kind
    and only floats differ, else the first ``where`` that does not."""
    largest, count = 0.0, 0
    for where, x, y in pairs:
        x, y = np.asarray(x), np.asarray(y)
        if x.shape != y.shape or x.dtype.kind != y.dtype.kind or (
                x.dtype.kind not in "fc" and not np.array_equal(x, y)):
            return f"structure or integers differ at {where}"
        if x.dtype.kind in "fc" and not np.array_equal(x, y, equal_nan=True):
            diff = np.abs(x - y) / np.maximum(np.maximum(np.abs(x), np.abs(y)), 1e-300)
            largest, count = max(largest, float(np.nanmax(diff))), count + int((x != y).sum())
    return f"floats only: {count} values, largest relative difference {largest:.1e}"


def how_they_differ(fa: Path, fb: Path) -> str:
    """Whether two map files differ in their structure (states, arcs, labels, any integer or
    text) or only in the last bits of their floats, as maps of one config do on two CPUs whose
    vector instructions round sums differently (``docs/file-formats.md``)."""
    if fa.suffix == ".json":
        a, b = (dict(_leaves(json.loads(f.read_text()))) for f in (fa, fb))
        if a.keys() != b.keys():
            return f"fields differ: {sorted(a.keys() ^ b.keys())[:3]}"
        return _arrays_differ((k, a[k], b[k]) for k in a)
    if fa.suffix == ".npz":
        with np.load(fa, allow_pickle=False) as x, np.load(fb, allow_pickle=False) as y:
            if set(x.files) != set(y.files):
                return "arrays differ"
            return _arrays_differ((k, x[k], y[k]) for k in x.files)
    return "text differs"


def compare(a: Path, b: Path) -> int:
    differ = 0
    for name in CONFIGS:
        if not (a / name).is_dir() and not (b / name).is_dir():
            continue
        for file in MAP_FILES:
            fa, fb = a / name / file, b / name / file
            if not fa.exists() or not fb.exists():
                print(f"{name}/{file}: missing in {a if not fa.exists() else b}")
                differ += 1
            elif not filecmp.cmp(fa, fb, shallow=False):
                print(f"{name}/{file}: differs ({how_they_differ(fa, fb)})")
                differ += 1
    print("every map the same bytes" if not differ else f"{differ} files differ or are missing")
    return 1 if differ else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="verb", required=True)
    r = sub.add_parser("run", help="write the reference maps into OUT/<name>/")
    r.add_argument("out", type=Path)
    r.add_argument("--only", nargs="+", choices=sorted(CONFIGS), default=list(CONFIGS))
    c = sub.add_parser("compare", help="compare two folders written by run")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = parser.parse_args(argv)
    if args.verb == "run":
        return run(args.out, args.only)
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
