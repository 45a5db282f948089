"""Whether a robot's walk covered the floor its scans saw (:mod:`topomap.core.motion.robot`).

The robot route places a new walk only on the cells its training walk entered: where a new walk
goes onto floor the training walk never drove over, it is placed metres off (``robot_twin``,
9 x 4.2 m, seed 0: 0.58 m on floor within two cell spacings of the training walk, 4.3 m beyond;
48 % of a new walk's steps lay beyond) while K-means on the views, which ranks a scan by its
nearest view alone, hedges.  The walk's own scans show such floor: :func:`unwalked_share` follows
every beam of every cell's mean scan (turned into the map frame) from the cell outwards, a point
every cell spacing up to :data:`MARGIN` spacings short of the beam's range, and counts the points
farther than :data:`FAR` spacings from every cell -- floor seen, never walked.  Measured
(``benchmarks/notes/robots.md``, seeds 0-2): 0-0.17 % on the 12 walks of the four 1 m plans,
1.2-5.2 % on two of three walks of ``robot_office`` at a third of its size (where the map bends
in a corner walked once the share grows: 5.2 % against 1.5 % on the same walk's true poses),
3.0-7.2 % on the six of the two 9 x 4.2 m plans.  On a log with wheel odometry the share is
recorded, not a guard (the held-out check judges); on odometry read from the scans a share
above :data:`MAX_UNWALKED` sends the log to the view clusters.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["unwalked_share", "FAR", "MARGIN", "MAX_UNWALKED"]

#: cell spacings: a point of seen floor farther than this from every cell was never walked (two:
#: the cells' own spread, a spacing, and as much again)
FAR = 2.0
#: cell spacings: a beam's points stop this far short of its range (the wall it hit, and the
#: floor a robot keeps clear of beside it)
MARGIN = 1.0
#: share: on odometry read from the scans, a map whose scans saw more unwalked floor is too
#: thinly walked for the robot route (1 m plans 0-0.17 %, 9 x 4.2 m plans 3.0-7.2 %, seeds 0-2;
#: set between them)
MAX_UNWALKED = 0.01


def unwalked_share(model) -> float:
    """The share of the points along the beams of ``model``'s cells (a
    :class:`~topomap.core.motion.robot.RobotMap`; beam ``j`` of a map-frame scan points at
    ``2 pi j / B`` rad) that lie farther than :data:`FAR` cell spacings from every cell (the
    module docstring); 0 where no beam reaches beyond :data:`MARGIN` spacings."""
    C, M, sp = model.centres, model.scans, float(model.spacing)
    B = M.shape[1]
    angle = 2 * np.pi * np.arange(B) / B
    unit = np.column_stack([np.cos(angle), np.sin(angle)])
    tree = cKDTree(C)
    far = seen = 0
    for s in np.arange(1, int(M.max() / sp) + 1) * sp:
        c, j = np.nonzero(M > s + MARGIN * sp)
        if c.size:
            far += int(np.count_nonzero(tree.query(C[c] + s * unit[j])[0] > FAR * sp))
            seen += c.size
    return far / seen if seen else 0.0
