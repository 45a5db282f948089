"""A short fingerprint of what a simulated benchmark walk depends on, for its cache file's name.

The walks of ``bench_continuous.py`` and ``robot_harness.py`` are cached as npz files keyed by
case, settings and seed; a walk cached by other arena code, another floor plan file or another
ratinabox or numpy release is not the walk the same key gives today (measured: `corridor` seed 2
was placed 0.929 m off from a walk cached earlier and 0.113 m off from one simulated afresh).
:func:`walk_stamp` hashes the arena's sources, the benchmark floor plans and those two releases, so
such a cache file is simply not found and the walk is simulated again.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

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
    ``benchmarks/floorplans/*.yaml``, this folder's walk code and the ratinabox and numpy
    releases."""
    import topomap.worlds.arena as arena

    files = sorted(Path(arena.__file__).parent.rglob("*.py")) + sorted(
        (HERE / "floorplans").glob("*.yaml")) + [HERE / "robot_harness.py"]
    h = hashlib.sha1()
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    for package in ("ratinabox", "numpy"):
        h.update(f"{package}={_release(package)}".encode())
    return h.hexdigest()[:STAMP_DIGITS]
