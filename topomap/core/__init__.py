"""The learning core: trajectories, the paper's two phases, the map and its metrics.

numpy and scikit-learn only: nothing here imports Hydra, pluggy or a simulator.

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``trajectory``      :class:`Trajectory`, input validation, ``.npz`` / ``.csv`` files
``clustering``      phase 1: distance metrics, cluster-count policies, K-means symbols
``splitting``       phase 2: transition instances, bottom-up merge, split criteria, stopping rules
``learner``         :class:`MapLearner`, the estimator that runs the phases
``map``             :class:`TopologicalMap`: probabilities, entropies, decoding, JSON, GraphML
``metrics``         learned states against ground-truth places (ARI, NMI, purity, ...)
``stats``           counts and entropies shared by the modules above
``files``           atomic file writes
==================  ===========================================================================
"""

from .learner import MapLearner
from .map.model import TopologicalMap
from .data.trajectory import Trajectory, check_sequences, load_trajectory, save_trajectory

__all__ = ["MapLearner", "TopologicalMap", "Trajectory", "check_sequences", "load_trajectory",
           "save_trajectory"]
