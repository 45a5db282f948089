"""Split criteria: how the split of a state is proposed and scored.

A split criterion is a small object with ``propose(counts) -> (side, score)`` or ``None``, where
``counts`` is a state's (groups x columns) count matrix of transition instances
(:meth:`topomap.core.split.engine.SplitEngine.count_matrix`), ``side[g]`` is True for the groups
of the second half and a larger ``score`` is a better split.  :class:`EntropyCriterion` is the
paper's.
"""

from __future__ import annotations

import numpy as np

from .engine import merge_and_gain

__all__ = ["EntropyCriterion", "CRITERIA"]


class EntropyCriterion:
    """The paper's split test.

    Groups (rows of ``counts``) are merged bottom-up, each time the pair whose union increases the
    instance-weighted entropy ``n H`` least (ties: the pair of smallest indices), until two remain.
    The score is the entropy gain ``H(I) - (|I'|/|I| H(I') + |I''|/|I| H(I''))`` in bits.
    """

    name = "entropy"
    #: ``propose`` may run on several threads at once (its merge releases the GIL)
    concurrent = True

    def propose(self, counts: np.ndarray):
        """Return ``(side, gain)`` -- ``side[g]`` is True for the groups of the second half -- or
        ``None`` when the state has fewer than two groups."""
        found = merge_and_gain(np.asarray(counts))
        if found is None:
            return None
        side, gain = found
        return side, float(max(gain, 0.0))

    def __repr__(self) -> str:
        return "EntropyCriterion()"


#: the criteria :class:`topomap.MapLearner` knows by name (``split="entropy"``)
CRITERIA = {EntropyCriterion.name: EntropyCriterion}
