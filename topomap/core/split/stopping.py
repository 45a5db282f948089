"""Stopping rules: when phase 2 stops splitting.

A stopping rule is a small object with ``check(n_initial)`` -- called once phase 1 has created
``n_initial`` states, before any split; it raises a :class:`~topomap.core.checks.ParameterError`
when its settings cannot work with that many -- and ``should_stop(n_states, best_score)``, asked
before every split.  :class:`TargetStates` is the paper's ("until the number of states reaches a
specified number"); :class:`MinGain` stops when splits stop gaining.
"""

from __future__ import annotations

import numpy as np

from ..checks import ParameterError, check_count

__all__ = ["TargetStates", "MinGain"]


class TargetStates:
    """Stop when the map has ``n_states`` states (the paper: 30)."""

    name = "n_states"

    def __init__(self, n_states: int = 30):
        self.n_states = check_count(n_states, "n_states")

    def check(self, n_initial: int) -> None:
        if self.n_states < n_initial:
            raise ParameterError(
                "n_states", f"={self.n_states} is below the {n_initial} states that phase 1 "
                            "creates (clusters plus GDS); splitting can only add states")

    def should_stop(self, n_states: int, best_score: float) -> bool:
        return n_states >= self.n_states

    def __repr__(self) -> str:
        return f"TargetStates(n_states={self.n_states})"


class MinGain:
    """Stop when the best split scores below ``min_gain`` (bits), or when the map reaches
    ``max_states`` states (None: three times the states phase 1 creates, so that a small
    ``min_gain`` cannot split a map into fragments without end)."""

    name = "min_gain"

    def __init__(self, min_gain: float = 0.05, max_states: int | None = None):
        if not np.isfinite(min_gain) or min_gain < 0:
            raise ParameterError("min_gain", f"must be a finite number >= 0, got {min_gain!r}")
        self.max_states = check_count(max_states, "max_states", allow_none=True)
        self.min_gain = float(min_gain)
        self._limit = self.max_states

    def check(self, n_initial: int) -> None:
        if self.max_states is not None and self.max_states < n_initial:
            raise ParameterError("max_states", f"={self.max_states} is below the {n_initial} states "
                                               "that phase 1 creates")
        self._limit = self.max_states if self.max_states is not None else 3 * int(n_initial)

    def should_stop(self, n_states: int, best_score: float) -> bool:
        if self._limit is not None and n_states >= self._limit:
            return True
        return best_score < self.min_gain

    def __repr__(self) -> str:
        return f"MinGain(min_gain={self.min_gain}, max_states={self.max_states})"
