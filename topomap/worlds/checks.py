"""The checks every world makes: its fixed set of actions, ``simulate``'s arguments, and each
choice of the explorer."""

from __future__ import annotations

import numpy as np

from ..core.checks import check_count

__all__ = ["check_no_extra_actions", "check_simulate_args", "check_choice"]


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
        raise ValueError(f"explorer must have a choose(executable_mask, rng) method, got "
                         f"{type(explorer).__name__}; topomap.worlds.RandomExplorer() walks at "
                         f"random")
    return n_steps


def check_choice(a, mask: np.ndarray, t: int) -> int:
    """Return the explorer's choice ``a`` as an int, or raise if it is not executable."""
    if (isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 0 <= a < mask.size
            or not mask[a]):
        raise ValueError(f"explorer chose action {a!r}, which is not executable at step {t}")
    return int(a)
