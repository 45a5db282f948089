"""topomap: learn a robot's topological map from observations and actions.

Implements Yairi, Togami & Hori, "Learning Topological Maps from Sequential Observation and Action
Data under Partially Observable Environment" (PRICAI 2002): K-means symbols as initial states, then
greedy entropy-based splitting of perceptually aliased states.
"""

from .hookspecs import hookimpl
from .learner import MapLearner
from .map import TopologicalMap
from .trajectory import Trajectory, load_trajectory, save_trajectory

__all__ = ["hookimpl", "MapLearner", "TopologicalMap", "Trajectory", "load_trajectory", "save_trajectory"]
__version__ = "0.1.0"
