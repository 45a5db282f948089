"""A short fingerprint of what a simulated benchmark walk depends on, for its cache file's name.

The walks of ``bench_continuous.py`` and ``robot_harness.py`` are cached as npz files keyed by
case, settings and seed; a walk cached by other arena code, another floor plan file, another
ratinabox or numpy release, or on a machine whose numeric kernels round otherwise is not the walk
the same key gives here. The kernels matter most: ratinabox's motion calls BLAS (a 2 x 2 rotation,
dot products) and numpy's vector loops, and carries a last-bit difference to metres within
1,800-10,500 steps (all 24 walks of ``bench_continuous.py``'s eight base plans, seeds 0-2, with
OpenBLAS's Haswell kernels against its SkylakeX ones; `corridor` seed 2's view clusters place
the held-out walk 0.357 against 0.714 m off). :func:`walk_stamp` hashes the arena's sources, the
benchmark floor plans, those two releases and
:func:`topomap.app.run.outputs.numeric_kernels`, so such a cache file is simply not found and the
walk is simulated again.
"""

from __future__ import annotations

import hashlib
import json
import sys
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

from topomap.app.run.outputs import numeric_kernels

HERE = Path(__file__).resolve().parent

#: hex digits of the fingerprint kept in a file name (32 bits: a chance collision between two
#: code versions is about one in four billion)
STAMP_DIGITS = 8


def _release(package: str) -> str:
    try:
        return version(package)
    except PackageNotFoundError:
        return "absent"


@lru_cache(maxsize=1)
def walk_stamp() -> str:
    """:data:`STAMP_DIGITS` hex digits of a SHA-1 over the sources of ``topomap.worlds.arena``,
    ``benchmarks/floorplans/*.yaml``, this folder's walk code, the ratinabox and numpy
    releases and the machine's numeric kernels."""
    import topomap.worlds.arena as arena

    files = sorted(Path(arena.__file__).parent.rglob("*.py")) + sorted(
        (HERE / "floorplans").glob("*.yaml")) + [HERE / "robot_harness.py"]
    h = hashlib.sha1()
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    for package in ("ratinabox", "numpy"):
        h.update(f"{package}={_release(package)}".encode())
    h.update(json.dumps(numeric_kernels(), sort_keys=True).encode())
    return h.hexdigest()[:STAMP_DIGITS]


def of_these_walks(row: dict) -> bool:
    """Whether a benchmark log's row was measured on the walks :func:`walk_stamp` names here (a
    row without a ``"walks"`` field is taken to be)."""
    return row.get("walks", walk_stamp()) == walk_stamp()


def warn_mixed_walks(rows) -> None:
    """Say on stderr when a benchmark log's rows (their ``"walks"`` field: :func:`walk_stamp`)
    come from more than one set of walks -- other arena code, releases or numeric kernels --
    whose medians a table would mix."""
    stamps = {r["walks"] for r in rows if "walks" in r}
    if len(stamps) > 1:
        print(f"note: this log holds rows of {len(stamps)} sets of walks "
              f"({', '.join(sorted(stamps))}: other arena code, releases or numeric kernels); "
              "their medians mix them", file=sys.stderr)
