"""Worlds given by tables: the place each action leads to and the symbol each place shows.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``base``            :class:`TableWorld`: observing, walking and the place graph from the tables;
                    the symbols' layout, embedding and legend
``gridroom``        :class:`GridRoom`: a room of cells showing a few symbols (heavy aliasing)
``random_graph``    :class:`RandomGraphWorld`: a random strongly connected digraph of aliased
                    places
==================  ===========================================================================
"""

from .base import TableWorld
from .gridroom import GridRoom
from .random_graph import RandomGraphWorld

__all__ = ["TableWorld", "GridRoom", "RandomGraphWorld"]
