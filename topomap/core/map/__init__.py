"""The map: its data, its files (JSON, GraphML), inference on it (forward, filter, Viterbi), planning."""

from .model import TopologicalMap

__all__ = ["TopologicalMap"]
