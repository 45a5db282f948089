"""The figures of a run (:mod:`.run`, :mod:`.graph`, :mod:`.path` and :mod:`.curves`, after the
paper's Figs. 4-7), in one style (:mod:`.style`) that the sweep's figure
(:mod:`topomap.app.report.figure`) shares; what they share (:mod:`.common`: the room, where states
sit) and how their numbers stay readable (:mod:`.labels`); the interactive map
(:mod:`.interactive`)."""

from .common import compound_mask
from .curves import plot_entropy, plot_mapping
from .graph import plot_map
from .path import plot_path
from .run import plot_split, plot_states, write_figures
from .style import LEGEND_SIZE, MARKERS, PALETTE, TITLE_SIZE, pyplot, save_figure, state_styles

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "plot_path", "plot_entropy",
           "plot_mapping", "compound_mask", "state_styles", "pyplot", "save_figure", "PALETTE", "MARKERS",
           "TITLE_SIZE", "LEGEND_SIZE"]
