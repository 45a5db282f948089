"""Simulated worlds, sensor noise and explorers: they produce :class:`topomap.Trajectory` data.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``office/``         the paper's office (layout, actions, motion, sensing, world, plot)
``table/``          worlds given by tables: a room of cells (``gridroom``) and a random digraph
                    (``random_graph``) of aliased places, on one base
``arena/``          continuous motion in a floor plan on ratinabox (optional package): layouts,
                    recorded paths, sensors, action rules
``minigrid``        an adapter for Farama MiniGrid environments (optional package)
``checks``          the checks every world makes: its actions, simulate's arguments, choices
``noise``           sensor noise models applied to noise-free observations
``explorers/``      how the simulated robot picks its next action, one module per policy
``mapping``         mapping while exploring: the learner fed as the robot walks
``navigation``      a world's true place graph; navigation episodes with a learned map
==================  ===========================================================================
"""

from typing import TYPE_CHECKING

from ..core.lazy import lazy_dir, lazy_getattr

if TYPE_CHECKING:  # what the names below are, for readers and documentation tools
    from .explorers import HistoryExplorer, PlanExplorer, RandomExplorer, View, active_explorer
    from .mapping import map_while_exploring
    from .minigrid import MiniGridWorld
    from .noise import DropoutNoise, GaussianNoise, MultiplicativeNoise, NoNoise
    from .office import OfficeWorld
    from .table import GridRoom, RandomGraphWorld

#: the module of each public name: imported on first use
_PUBLIC = {
    **dict.fromkeys(("active_explorer", "HistoryExplorer", "PlanExplorer", "RandomExplorer",
                     "View"), ".explorers"),
    "map_while_exploring": ".mapping", "MiniGridWorld": ".minigrid",
    **dict.fromkeys(("DropoutNoise", "GaussianNoise", "MultiplicativeNoise", "NoNoise"), ".noise"),
    "OfficeWorld": ".office", "GridRoom": ".table", "RandomGraphWorld": ".table",
}

__all__ = ["DropoutNoise", "GaussianNoise", "GridRoom", "MiniGridWorld", "MultiplicativeNoise",
           "NoNoise", "OfficeWorld", "RandomExplorer", "active_explorer", "HistoryExplorer",
           "PlanExplorer", "View", "RandomGraphWorld", "map_while_exploring"]


__getattr__ = lazy_getattr(__name__, _PUBLIC)
__dir__ = lazy_dir(__name__, __all__)
