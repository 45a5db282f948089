"""Exploration policies: how the simulated robot picks its next action.

An explorer has one method, ``choose(executable, rng) -> int``, which receives the boolean mask of
the actions that can be started at the current place and returns the index of one of them.
"""

from __future__ import annotations

import numpy as np

__all__ = ["RandomExplorer"]


def _check_mask(executable) -> np.ndarray:
    mask = np.asarray(executable)
    if mask.ndim != 1 or mask.dtype.kind != "b":
        raise ValueError(f"executable must be a 1-D boolean mask, got {mask.dtype} array of shape {mask.shape}")
    if not mask.any():
        raise ValueError("executable marks no action as executable; cannot choose one")
    return mask


class RandomExplorer:
    """Pick uniformly at random among the executable actions (the paper's exploration)."""

    def choose(self, executable, rng: np.random.Generator) -> int:
        """Return the index of an executable action, drawn uniformly with ``rng``.

        Parameters
        ----------
        executable : (n_actions,) bool array
        rng : numpy.random.Generator

        Raises
        ------
        ValueError
            If no action is executable.
        """
        idx = np.flatnonzero(_check_mask(executable))
        return int(idx[rng.integers(idx.size)])

    def __repr__(self) -> str:
        return "RandomExplorer()"
