"""A rectangular room of cells that show a few observation symbols (heavy perceptual aliasing).

The room is ``width x height`` cells.  Every cell shows one of ``n_symbols`` symbols, drawn at
random from ``seed`` (every symbol appears at least once), so with a few symbols many cells look
alike -- the kind of room used to test clone-structured cognitive graphs.  The robot moves one cell
with four actions, ``north``, ``east``, ``south`` and ``west``; a move into the outer wall is not
executable (the explorer never picks it), so every executed action changes the cell.

Coordinates: cell ``(x, y)`` with ``x`` in ``[0, width)`` growing east and ``y`` in
``[0, height)`` growing north; its place id is ``y * width + x`` and its position the cell centre
``(x + 0.5, y + 0.5)``.

Observations: the symbol's embedding, noise-free -- a one-hot vector (``obs_dim=0``, the default;
dimension ``n_symbols``) or, with ``obs_dim > 0``, a random vector in ``[0, 1]^obs_dim`` per symbol
drawn from ``seed``.  Both are non-negative, so the app's clipped Gaussian noise only biases the
zero entries upwards by about ``0.4 sigma``.  Sensor noise is added by the app's ``noise``
component, not here.

Ground truth: the cell (``places``) and its centre (``positions``).
"""

from __future__ import annotations

import numpy as np

from ...core.checks import check_count
from ..checks import check_no_extra_actions
from .base import TableWorld, assign_symbols, symbol_embedding, symbol_legend

__all__ = ["GridRoom"]

#: the four moves as (dx, dy)
MOVES = np.array([[0, 1], [1, 0], [0, -1], [-1, 0]], dtype=np.int64)
MOVE_NAMES = ["north", "east", "south", "west"]


class GridRoom(TableWorld):
    """A ``width x height`` room of cells, each showing one of ``n_symbols`` symbols.

    A :class:`~topomap.worlds.table.base.TableWorld`: it observes, walks (``simulate``) and gives
    its place graph from its tables.

    Parameters
    ----------
    width, height : int
        Room size in cells (for example 8 x 6 up to 30 x 30); at least two cells in all.
    n_symbols : int
        Number of distinct observation symbols, ``1 <= n_symbols <= width * height``.
    obs_dim : int
        0 for one-hot observations (dimension ``n_symbols``), else the dimension of random
        non-negative symbol vectors.
    seed : int
        Seeds the symbol layout and the embedding (not the walk: ``simulate`` takes its own rng).
    extra_actions : list, optional
        Not supported: a non-empty list raises ValueError (the four moves are the only actions).
    """

    def __init__(self, width: int = 8, height: int = 6, n_symbols: int = 4, obs_dim: int = 0,
                 seed: int = 0, extra_actions=None):
        self.width = check_count(width, "width")
        self.height = check_count(height, "height")
        if self.width * self.height < 2:
            raise ValueError(f"the room needs at least two cells, got width={width}, height={height}")
        self.n_places = self.width * self.height
        self.n_symbols = check_count(n_symbols, "n_symbols")
        if self.n_symbols > self.n_places:
            raise ValueError(f"n_symbols={n_symbols} exceeds the {self.n_places} cells of the room")
        self.obs_dim = check_count(obs_dim, "obs_dim", minimum=0)
        self.seed = int(seed)
        check_no_extra_actions("gridroom", extra_actions)
        rng = np.random.default_rng(self.seed)
        #: symbol shown by each cell, indexed by place id
        self.place_symbols = assign_symbols(self.n_places, self.n_symbols, rng)
        #: observation vector of each symbol
        self.embedding = symbol_embedding(self.n_symbols, self.obs_dim, rng)
        xs, ys = np.arange(self.n_places) % self.width, np.arange(self.n_places) // self.width
        self.cells = np.column_stack([xs, ys])
        #: cell centres, indexed by place id
        self.place_positions = self.cells + 0.5
        nx_, ny_ = xs[:, None] + MOVES[:, 0], ys[:, None] + MOVES[:, 1]
        inside = (nx_ >= 0) & (nx_ < self.width) & (ny_ >= 0) & (ny_ < self.height)
        #: place reached by each move, -1 where the wall blocks it
        self.successors = np.where(inside, ny_ * self.width + nx_, -1)
        self.action_names = list(MOVE_NAMES)

    def place_of(self, x: int, y: int) -> int:
        """Place id of cell ``(x, y)``."""
        if not (0 <= x < self.width and 0 <= y < self.height):
            raise ValueError(f"cell ({x}, {y}) is outside the {self.width} x {self.height} room")
        return int(y) * self.width + int(x)

    def step(self, place: int, action: int) -> int:
        """The place one move away; raises ValueError when the wall blocks the move."""
        nxt = int(self.successors[place, action])
        if nxt < 0:
            raise ValueError(f"{self.action_names[action]} from cell {tuple(self.cells[place])} "
                             "runs into the wall")
        return nxt

    @property
    def place_names(self) -> list[str]:
        """Each place's name, for the interactive map: its cell, ``cell (x, y)``."""
        return [f"cell ({int(x)}, {int(y)})" for x, y in self.cells]

    def meta(self) -> dict:
        """What a walk's trajectory records of the room: its size, symbols and seed."""
        return {
            "world": "gridroom", "width": self.width, "height": self.height,
            "n_symbols": self.n_symbols, "obs_dim": self.obs_dim, "seed": self.seed,
            "place_symbols": self.place_symbols.tolist(),
        }

    def plot_room(self, ax, labels: bool = False):
        """Draw the cells, tinted by symbol (with a legend of the symbols beside the room), and the
        walls.  ``labels`` writes each cell's symbol.  Returns ``ax``."""
        import matplotlib.pyplot as plt
        from matplotlib.patches import Rectangle

        cmap = plt.get_cmap("Pastel1" if self.n_symbols <= 9 else "tab20", max(self.n_symbols, 1))
        colours = [cmap(k % cmap.N)[:3] + (0.6,) for k in range(self.n_symbols)]
        img = np.array([colours[s] for s in self.place_symbols]).reshape(self.height, self.width, 4)
        ax.imshow(img, origin="lower", extent=(0, self.width, 0, self.height),
                  interpolation="nearest", zorder=0)
        for k in range(1, self.width):
            ax.axvline(k, color="white", lw=0.6, zorder=1)
        for k in range(1, self.height):
            ax.axhline(k, color="white", lw=0.6, zorder=1)
        ax.add_patch(Rectangle((0, 0), self.width, self.height, fill=False, lw=2.5, ec="black"))
        if labels:
            for p, (cx, cy) in enumerate(self.place_positions):
                ax.annotate(str(self.place_symbols[p]), (cx, cy), ha="center", va="center",
                            fontsize=6, color="dimgray")
        ax.set_xlim(-0.3, self.width + 0.3)
        ax.set_ylim(-0.3, self.height + 0.3)
        ax.set_aspect("equal")
        symbol_legend(ax, colours)
        return ax

    def __repr__(self) -> str:
        return (f"GridRoom(width={self.width}, height={self.height}, n_symbols={self.n_symbols}, "
                f"obs_dim={self.obs_dim}, seed={self.seed})")
