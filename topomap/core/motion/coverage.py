"""Ground the check's held-out part never tests: a part of the log in places the rest seldom visits.

The ``bootstrap`` check (:mod:`topomap.core.motion.crossfit`) holds out the last quarter of a log.
Where the log's start covers ground it never comes back to -- a room entered in the first
minutes and never again -- the places there are cut from that one visit and the last quarter
never decodes a step there; a new walk that spends its time there can lose with the places
where the check found them better.  :func:`novelty` measures, for a part of the log, the share
of its steps in places (the whole log's) that hold at most :data:`RARE` of their steps outside
it; :func:`novel_span` names the part of the log, of as many as the held-out share makes,
whose novelty is highest, where it reaches :data:`NOVEL_SHARE` and it is not the last part
(the default's part).  Under ``check.rule="coverage"`` that part is held out instead of the
last, the rest learned (:func:`~topomap.core.motion.crossfit.cross_fitted` with ``span``), and
the places give way to the view clusters where the view clusters place it nearer its own pose
graph at all -- not only by two standard errors: on ground one stay made, the places commit
to one of alike rooms where the view clusters hedge (benchmarks/notes/continuous.md,
"2026-12-02: ground the last quarter never visits"); one fold, as ``"bootstrap"``, and a
second where the last part keeps the places within two standard errors
(:func:`~topomap.core.motion.check.undecided`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["RARE", "NOVEL_SHARE", "novelty", "novel_span"]

#: share: a place is new ground to the rest of the log where at most this share of its steps
#: lie outside the part (a tenth: a visit or two of the rest, against the part's own stay)
RARE = 0.1
#: share: a part of the log is held out in place of the last where at least this share of its
#: steps lie in places new to the rest.  The earlier quarters of 27 walks' logs
#: (benchmarks/notes/continuous.md, "2026-12-02: ground the last quarter never visits"): 0.73 on
#: ``corridor`` seed 1, whose new walk stays where only the first quarter went (places 0.920 m
#: against the views' 0.761 m), 0.47 and 0.43 on ``ring`` and ``grid6`` seed 0 (their places
#: win there too), at most 0.27 on the other 24; 0.2 and 0.4 chose alike
NOVEL_SHARE = 0.3


def novelty(places, a: int, b: int, rare: float = RARE) -> float:
    """The share of the steps ``a:b`` of ``places`` ((T,) labels) in places holding at most
    ``rare`` of their steps outside ``a:b``."""
    places = np.asarray(places)
    k = int(places.max()) + 1
    inside = np.bincount(places[a:b], minlength=k)
    total = np.bincount(places, minlength=k)
    new = total - inside <= rare * total
    return float(np.mean(new[places[a:b]]))


def novel_span(places, holdout: float, share: float = NOVEL_SHARE) -> tuple[int, int] | None:
    """``(a, b)``: of the ``round(1 / holdout)`` parts of equal length of ``places`` ((T,)
    labels) but the last (held out already), the one whose :func:`novelty` is highest, where it
    is at least ``share`` (None otherwise; ties go to the earlier part)."""
    T = len(places)
    n = max(int(round(1 / holdout)), 2)
    bounds = [(i * T // n, (i + 1) * T // n) for i in range(n - 1)]
    scores = [novelty(places, a, b) for a, b in bounds]
    i = int(np.argmax(scores))
    return bounds[i] if scores[i] >= share else None
