"""Every figure topomap draws: a run's (:mod:`.run` and :mod:`.curves`, after the paper's
Figs. 4-7) and a sweep's (:mod:`topomap.app.report.figure`), in one style (:mod:`.style`)."""

from .curves import plot_entropy, plot_mapping
from .run import compound_mask, plot_map, plot_split, plot_states, write_figures
from .style import LEGEND_SIZE, MARKERS, PALETTE, TITLE_SIZE, pyplot, save_figure, state_styles

__all__ = ["write_figures", "plot_states", "plot_split", "plot_map", "plot_entropy",
           "plot_mapping", "compound_mask", "state_styles", "pyplot", "save_figure", "PALETTE", "MARKERS",
           "TITLE_SIZE", "LEGEND_SIZE"]
