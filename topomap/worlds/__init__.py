"""Simulated worlds, sensor noise and explorers: they produce :class:`topomap.Trajectory` data.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``office/``         the paper's office (layout, actions, motion, sensing, world, plot)
``gridroom``        a room of cells showing a few symbols (heavy aliasing)
``random_graph``    a random strongly connected digraph of aliased places
``minigrid``        an adapter for Farama MiniGrid environments (optional package)
``common``          helpers the worlds share: argument checks, the table-driven random walk
``noise``           sensor noise models applied to noise-free observations
``explorers/``      how the simulated robot picks its next action, one module per policy
``mapping``         mapping while exploring: the learner fed as the robot walks
==================  ===========================================================================
"""

from .explorers import ActiveExplorer, HistoryExplorer, PlanExplorer, RandomExplorer, View
from .mapping import map_while_exploring
from .gridroom import GridRoom
from .minigrid import MiniGridWorld
from .noise import DropoutNoise, GaussianNoise, MultiplicativeNoise, NoNoise
from .office import OfficeWorld
from .random_graph import RandomGraphWorld

__all__ = ["DropoutNoise", "GaussianNoise", "GridRoom", "MiniGridWorld", "MultiplicativeNoise",
           "NoNoise", "OfficeWorld", "RandomExplorer", "ActiveExplorer", "HistoryExplorer",
           "PlanExplorer", "View", "RandomGraphWorld", "map_while_exploring"]
