"""The figures' shared style: the states' palette and markers, font sizes, the Agg backend, PNG files.

A state has the same style in every figure (:func:`state_styles`): a colour of :data:`PALETTE`
and, once the palette is used up, the next marker of :data:`MARKERS`.
"""

from __future__ import annotations

from pathlib import Path

from ...core.data.atomic import atomic_write

__all__ = ["PALETTE", "MARKERS", "TITLE_SIZE", "LEGEND_SIZE", "MAX_STATE_NUMBERS", "MAX_MAP_NUMBERS",
           "HALO", "pyplot", "save_figure", "state_styles"]

#: qualitative colours of states: saturated, none near white, every two at least 24 CIELAB
#: units apart (tab10 without its gray, then darker and brighter hues)
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#bcbd22", "#393b79", "#05472a", "#be03fd", "#7b4173", "#e6ab02",
           "#000000", "#0165fc", "#ff0789", "#82a67d", "#b15928", "#5f6f81")
#: marker of the states of the palette's first, second, ... round
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
#: font sizes (points) of the titles and of the legends
TITLE_SIZE, LEGEND_SIZE = 9, 7
#: most numbers written on the states figure, and most states whose map nodes are numbered
MAX_STATE_NUMBERS, MAX_MAP_NUMBERS = 300, 100
#: width (points) of the white outline that keeps a number readable on any background
HALO = 2.0


def pyplot():
    """pyplot on the Agg backend (unless a backend was chosen already)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path):
    """Write ``fig`` as a PNG file atomically and close it."""
    plt = pyplot()
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png"))
    plt.close(fig)


def state_styles(n: int) -> list[tuple[str, str]]:
    """``(colour, marker)`` of states ``0..n-1``: the palette's colours in turn, the marker
    changing each time the palette starts again (distinct for up to 160 states)."""
    k = len(PALETTE)
    return [(PALETTE[s % k], MARKERS[(s // k) % len(MARKERS)]) for s in range(n)]
