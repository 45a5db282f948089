"""Whether a robot route's map is its own point reflection (:mod:`topomap.core.motion.robot`).

Scans in the robot's frame and odometry that starts in an unknown frame cannot tell a walk from
the same walk turned by 180 degrees about a point where the floor plan is so turned into itself
(``two_rooms``: two empty rooms and a corridor): the robot route's decoder then locks a held-out
walk onto its point reflection (1.63 m off where K-means on the views is 0.73 m).
:func:`point_symmetry` measures that on the learned cells alone: each cell turned by 180 degrees
about a centre (searched on a grid of half cell spacings, ``SEARCH`` each way from the cells'
mean) lands near some cell, whose mean scan is compared with the cell's own turned by 180
degrees; the median of those mismatches (infinite where a cell lands off the map), against the
median mismatch of a cell's scan with its nearest neighbour's, is the ``ratio``.  Measured
(``benchmarks/notes/robots.md``): 2.1 on ``two_rooms@1``, 7.6-10.9 on the three furnished plans.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .scans import rotate_scans

__all__ = ["point_symmetry", "SEARCH", "SYMMETRY_RATIO", "SCAN_REACH"]

#: half cell spacings searched each way from the cells' mean for the centre of the reflection
#: (steps; the cells of a point-symmetric plan centre within a spacing or two of it)
SEARCH = 8
#: a map whose ratio is below this is taken for its own point reflection (ratio; seed 0:
#: ``two_rooms@1`` 2.1, ``robot_twin``, ``robot_alike``, ``robot_three`` 7.6, 10.8, 10.9)
SYMMETRY_RATIO = 3.0
#: cell spacings: on odometry read from the scans a cell's reflection is matched with the best of
#: the cells within this reach of where it lands, not only the nearest (the map bends by a few
#: centimetres where wheel odometry's does not: ``two_rooms@1`` seed 0's map, 0.06 m from the
#: truth after a rigid alignment, gave 4.66 with the nearest cell within 1 spacing against 0.33 on
#: the true poses).  Reach 1 / 1.5 / 2 / 3 on the 12 walks of the four 1 m plans (seeds 0-2):
#: ``two_rooms@1`` 4.66, 1.31, 1.16 / 2.51, 0.99, 0.96 / 2.12, 0.99, 0.96 / 1.84, 0.99, 0.96;
#: the furnished plans' least 5.40 / 4.03 / 3.12 / 2.29 (``robot_alike@0.3333`` seed 1's bent
#: map below 3 at every reach)
SCAN_REACH = 1.5


def _mirror_mismatch(tree, scans, turned, spacing, c0) -> float:
    """The median scan mismatch of every cell with the cell nearest its point reflection about
    ``c0`` (infinite where that lies a spacing or more from any cell); ``tree`` the cells'
    :class:`~scipy.spatial.cKDTree`."""
    d, j = tree.query(2 * c0 - tree.data)
    e = ((scans[j] - turned) ** 2).mean(1)
    return float(np.median(np.where(d < spacing, e, np.inf)))


def _reach_mismatch(tree, pair, spacing, reach, c0) -> float:
    """:func:`_mirror_mismatch` with each cell's reflection about ``c0`` matched with the best of
    the cells within ``reach`` spacings of where it lands; ``pair`` (N, N): cell ``j``'s mean scan
    against cell ``i``'s turned by 180 degrees, at ``[j, i]``."""
    e = [pair[n, i].min() if n else np.inf
         for i, n in enumerate(tree.query_ball_point(2 * c0 - tree.data, reach * spacing))]
    return float(np.median(e))


def point_symmetry(model, reach: float | None = None) -> dict:
    """``{"ratio", "centre"}``: the best point reflection of ``model``'s cells (a
    :class:`~topomap.core.motion.robot.RobotMap`; see the module docstring) and its centre [m].
    ``reach`` (cell spacings): each reflection matched with the best cell within it (None: the
    nearest cell, within a spacing; :data:`SCAN_REACH` on odometry read from the scans)."""
    C, M, sp = model.centres, model.scans, model.spacing
    if len(C) < 2:
        return {"ratio": float("inf"), "centre": C.mean(0).tolist()}
    turned = rotate_scans(M, np.full(len(M), np.pi))
    d = np.linalg.norm(C[:, None] - C[None], axis=2) + np.diag(np.full(len(C), np.inf))
    own = float(np.median(((M - M[d.argmin(1)]) ** 2).mean(1)))
    pair = None if reach is None else ((M[:, None, :] - turned[None, :, :]) ** 2).mean(2)
    steps = np.arange(-SEARCH, SEARCH + 1) * sp / 2
    best, centre, tree = np.inf, C.mean(0), cKDTree(C)
    for dx in steps:
        for dy in steps:
            c0 = C.mean(0) + (dx, dy)
            e = (_mirror_mismatch(tree, M, turned, sp, c0) if reach is None
                 else _reach_mismatch(tree, pair, sp, reach, c0))
            if e < best:
                best, centre = e, c0
    return {"ratio": best / max(own, 1e-12), "centre": [round(float(v), 3) for v in centre]}
