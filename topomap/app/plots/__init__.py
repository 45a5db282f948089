"""The figures of a run (:mod:`.run` and :mod:`.curves`, after the paper's Figs. 4-7), in one
style (:mod:`.style`) that the sweep's figure (:mod:`topomap.app.report.figure`) shares."""

from .curves import plot_entropy, plot_mapping
from .run import compound_mask, plot_map, plot_split, plot_states, write_figures
from .style import LEGEND_SIZE, MARKERS, PALETTE, TITLE_SIZE, pyplot, save_figure, state_styles

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "plot_entropy",
           "plot_mapping", "compound_mask", "state_styles", "pyplot", "save_figure", "PALETTE", "MARKERS",
           "TITLE_SIZE", "LEGEND_SIZE"]
