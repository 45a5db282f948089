"""What every explorer shares: the view a world hands it, the checked mask, the uniform choice,
and the base of the explorers that use the map learned while exploring.

:class:`RandomExplorer` (the paper's) is the uniform choice alone.  :class:`MapExplorer` is the
base of :class:`~topomap.worlds.explorers.history.HistoryExplorer` and
:class:`~topomap.worlds.explorers.plan.PlanExplorer`: the pace of the map's updates, the share of
random actions, and the last view.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...core.checks import ParameterError, check_count

__all__ = ["View", "show", "check_mask", "pick", "RandomExplorer", "MapExplorer"]


class View(NamedTuple):
    """What the robot has at a step: its observation (as the sensor gives it), the boolean mask
    of the actions it can start, the GDS it recognises there (-1: none) and the step index."""

    observation: np.ndarray
    executable: np.ndarray
    gds: int
    t: int


def show(explorer, observation, executable, gds: int, t: int) -> None:
    """Hand an explorer that has ``see`` the step's :class:`View` (the worlds call this)."""
    see = getattr(explorer, "see", None)
    if see is not None:
        see(View(np.array(observation, dtype=np.float64), np.array(executable, dtype=bool),
                 int(gds), int(t)))


def check_mask(executable) -> np.ndarray:
    """``executable`` as a 1-D boolean array (not a copy: explorers only read it), or a
    ValueError when it is not one or marks no action."""
    mask = np.asarray(executable)
    if mask.ndim != 1 or mask.dtype.kind != "b":
        raise ValueError(f"executable must be a 1-D boolean mask, got {mask.dtype} array of shape {mask.shape}")
    if not mask.any():
        raise ValueError("executable marks no action as executable; cannot choose one")
    return mask


def pick(idx: np.ndarray, rng: np.random.Generator) -> int:
    """One of the action ids ``idx``, drawn uniformly with ``rng``."""
    return int(idx[rng.integers(idx.size)])


def check_share(value, param: str) -> float:
    """``value`` as a float if it lies in [0, 1], else a :class:`ParameterError` naming
    ``param``."""
    if not (isinstance(value, (int, float)) and 0 <= value <= 1):
        raise ParameterError(param, f"must lie in [0, 1], got {value!r}")
    return float(value)


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
        return pick(np.flatnonzero(check_mask(executable)), rng)

    def __repr__(self) -> str:
        return "RandomExplorer()"


class MapExplorer:
    """The base of the explorers that use the map learned while exploring.

    Such an explorer has what a real robot has, and nothing more: its views (``see``), the
    actions it took (``choose``) and the map learned so far (``update(learner)``, every
    ``update_every`` steps: the run maps while exploring at that pace).  Until it has a map it
    walks at random, drawing as :class:`RandomExplorer` does.

    Parameters
    ----------
    update_every : int
        Steps between two updates of the map.
    epsilon : float
        Share of random actions, in [0, 1].
    """

    def __init__(self, update_every: int = 250, epsilon: float = 0.0):
        self.update_every = check_count(update_every, "update_every")
        self.epsilon = check_share(epsilon, "epsilon")
        self._view = None          # the view of the current step (None before the first)

    def see(self, view: View) -> None:
        """Take the view of the current step."""
        self._view = view

    def update(self, learner) -> None:  # pragma: no cover - every explorer defines it
        """Take the map the learner has now (``learner.map_``)."""
        raise NotImplementedError

    def choose(self, executable, rng: np.random.Generator) -> int:  # pragma: no cover
        """The executable action to take at the current step."""
        raise NotImplementedError
