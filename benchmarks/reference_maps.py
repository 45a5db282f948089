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
import subprocess
import sys
import time
from pathlib import Path

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
                print(f"{name}/{file}: differs")
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
