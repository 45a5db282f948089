"""The map: its data, estimation and entropies (``model``), its files (``files``: JSON, GraphML,
networkx), inference on it (``inference`` over the compiled ``kernels``: forward, filter,
forward-backward, Viterbi), walks drawn from it (``sampling``), its Gaussian observation models
(``observations``) and planning (``planning``)."""

from .model import TopologicalMap

__all__ = ["TopologicalMap"]
