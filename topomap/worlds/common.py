"""Helpers shared by the worlds: argument checks, the random walk of table-driven worlds and
their symbol layouts.

A *table-driven* world (gridroom, random_graph) has ``successors[p, a]`` (the place action ``a``
leads to from place ``p``, -1 where it is not executable), ``place_symbols``, an ``embedding`` of
the symbols as observation vectors, ``place_positions`` and ``action_names``.
"""

from __future__ import annotations

import numpy as np

from ..core.checks import check_count
from ..core.data.trajectory import Trajectory
from .explorers import show

__all__ = ["check_no_extra_actions", "check_simulate_args", "check_choice", "walk",
           "symbol_embedding", "assign_symbols", "symbol_legend"]


def check_no_extra_actions(world: str, extra_actions) -> None:
    """Worlds with a fixed action set refuse actions added by plugins, naming the world."""
    if extra_actions:
        names = ", ".join(repr(getattr(a, "name", a)) for a in extra_actions)
        raise ValueError(f"the {world} world has a fixed set of actions and takes no extra actions "
                         f"(plugins offered {names}); disable those plugins for env={world}")


def check_simulate_args(n_steps, explorer) -> int:
    """Validate the arguments of ``simulate`` and return ``n_steps`` as an int."""
    n_steps = check_count(n_steps, "n_steps")
    if not callable(getattr(explorer, "choose", None)):
        raise ValueError("explorer must have a choose(executable_mask, rng) method")
    return n_steps


def check_choice(a, mask: np.ndarray, t: int) -> int:
    """Return the explorer's choice ``a`` as an int, or raise if it is not executable."""
    if (isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 0 <= a < mask.size
            or not mask[a]):
        raise ValueError(f"explorer chose action {a!r}, which is not executable at step {t}")
    return int(a)


def walk(world, n_steps, explorer, rng: np.random.Generator, meta: dict) -> Trajectory:
    """Random walk on a table-driven world and its noise-free :class:`Trajectory`.

    ``world`` has ``successors[p, a]`` (-1 where ``a`` is not executable), ``place_symbols``,
    ``embedding``, ``place_positions`` and ``action_names``.  The walk starts at a place drawn with
    ``rng`` and asks ``explorer.choose(mask, rng)`` once per step; the last step's action is
    chosen but not executed.
    """
    n_steps = check_simulate_args(n_steps, explorer)
    successors = world.successors
    masks = successors >= 0
    places = np.empty(n_steps, dtype=np.int64)
    actions = np.empty(n_steps, dtype=np.int64)
    p = int(rng.integers(successors.shape[0]))
    sees = hasattr(explorer, "see")
    for t in range(n_steps):
        places[t] = p
        mask = masks[p].copy()
        if sees:
            show(explorer, world.embedding[world.place_symbols[p]], mask, -1, t)
        a = check_choice(explorer.choose(mask, rng), mask, t)
        actions[t] = a
        p = int(successors[p, a])
    return Trajectory(
        observations=world.embedding[world.place_symbols[places]], actions=actions,
        places=places, positions=world.place_positions[places],
        action_names=list(world.action_names), meta=meta,
    )


def symbol_embedding(n_symbols: int, obs_dim: int, rng: np.random.Generator) -> np.ndarray:
    """Observation vector of every symbol, ``(n_symbols, D)``, all entries in ``[0, 1]``.

    ``obs_dim == 0`` gives one-hot vectors (``D = n_symbols``); ``obs_dim > 0`` draws each symbol's
    vector uniformly from ``[0, 1]^obs_dim`` with ``rng`` (distinct with probability one, but
    nothing keeps two of them far apart).
    """
    if obs_dim == 0:
        return np.eye(n_symbols)
    return rng.uniform(0.0, 1.0, size=(n_symbols, obs_dim))


def assign_symbols(n_places: int, n_symbols: int, rng: np.random.Generator) -> np.ndarray:
    """A symbol for every place: each symbol at least once, the rest uniform, shuffled."""
    sym = np.concatenate([np.arange(n_symbols), rng.integers(0, n_symbols, n_places - n_symbols)])
    return rng.permutation(sym).astype(np.int64)


#: most symbols listed in a room's legend (more are told apart by their labels only)
MAX_LEGEND_SYMBOLS = 20


def symbol_legend(ax, colours) -> None:
    """A legend of the symbols' tints (one entry per colour) beside the room, for at most
    :data:`MAX_LEGEND_SYMBOLS` symbols."""
    from matplotlib.patches import Patch

    if len(colours) > MAX_LEGEND_SYMBOLS:
        return
    handles = [Patch(fc=c, ec="0.5", lw=0.5, label=f"symbol {k}") for k, c in enumerate(colours)]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6.5,
              title="observed symbol", title_fontsize=7, frameon=False)
