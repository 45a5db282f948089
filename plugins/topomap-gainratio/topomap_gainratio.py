"""A stopping rule for topomap: stop when splits stop paying off relative to the first one.

The paper stops at a fixed state count.  This rule needs no count: it stops when the best split's
score has fallen below ``ratio`` times the score of the first split (an elbow criterion), or when
``max_states`` is reached.

    topomap stop=gain_ratio stop.ratio=0.25
"""

from dataclasses import dataclass
from typing import Optional

from topomap import Component, hookimpl


@dataclass
class GainRatioConf:
    component: str = "gain_ratio"
    ratio: float = 0.25
    max_states: Optional[int] = None


class GainRatio:
    """Stop when ``best_score < ratio * first_score`` (or at ``max_states``)."""

    def __init__(self, ratio: float = 0.25, max_states: Optional[int] = None):
        if not 0 < ratio <= 1:
            raise ValueError(f"stop.ratio must lie in (0, 1], got {ratio!r}")
        self.ratio = float(ratio)
        self.max_states = max_states
        self.first_score = None

    def check(self, n_initial):
        if self.max_states is not None and self.max_states < n_initial:
            raise ValueError(f"stop.max_states={self.max_states} is below the {n_initial} initial states")
        self.first_score = None  # a new fit starts

    def should_stop(self, n_states, best_score):
        if self.max_states is not None and n_states >= self.max_states:
            return True
        if self.first_score is None:
            self.first_score = best_score
        return best_score <= 0 or best_score < self.ratio * self.first_score

    def __repr__(self):
        return f"GainRatio(ratio={self.ratio}, max_states={self.max_states})"


@hookimpl
def topomap_register_components():
    return [Component("stop", "gain_ratio", GainRatio, GainRatioConf,
                      "stop when the best gain falls below ratio x the first split's gain")]
