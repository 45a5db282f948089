"""The learning core: trajectories, the paper's two phases, the refinement, the map.

It needs numpy, scikit-learn, numba (the compiled kernels), threadpoolctl and networkx (the
map's graphs and plans), and ``rosbags`` only to read or write ROS bags; nothing here imports
Hydra, pluggy or a simulator.  The rooms follow the method's order, each holding the kernels it
uses:

==================  ===========================================================================
module              its one job
==================  ===========================================================================
``data``            :class:`Trajectory`, a fit's checked input, ``.npz`` / ``.csv`` files,
                    ROS bags, atomic writes
``phase1``          phase 1: distance metrics, cluster-count policies, K-means symbols
``split``           phase 2: transition instances, the bottom-up merge, split criteria,
                    stopping rules
``refine``          the refinement after the split: EM over clone-structured maps, soft
                    symbol evidence, structure moves, resizing
``map``             :class:`TopologicalMap`: estimation, entropies, inference, files, planning
``size``            ``stop=auto``: the number of states by held-out likelihood or BIC
``motion``          continuous logs: learned odometry and view copies cut into places
``components``      the learner's parameters made into a fit's components
``refining``        the learner's refinement stage: the refined map, the BIC guard
``online``          what :meth:`MapLearner.partial_fit` keeps between calls
``learner``         :class:`MapLearner`, the estimator that runs the phases
``map_methods``     inference the map and the learner share (hmmlearn's names)
``position_scores`` the scores in metres' old name, kept until 0.4 (now
                    :mod:`topomap.evaluation.metres`)
``stats``, ``sums`` counts, entropies and state matching shared by the rooms; numpy's
                    pairwise sums, compiled
``checks``          :class:`~topomap.core.checks.ParameterError`: errors naming a parameter
``progress``        progress reports of long loops, for whoever listens
``lazy``            public names of a package imported on first use
==================  ===========================================================================
"""

from typing import TYPE_CHECKING

from .lazy import lazy_dir, lazy_getattr

if TYPE_CHECKING:  # what the names below are, for readers and documentation tools
    from .data.trajectory import (Trajectory, check_sequences, load_trajectory,
                                  save_trajectory)
    from .learner import MapLearner
    from .map.model import TopologicalMap

__all__ = ["MapLearner", "TopologicalMap", "Trajectory", "check_sequences", "load_trajectory",
           "save_trajectory"]

#: the module of each public name: imported on first use (``import topomap.core.checks`` loads
#: neither scikit-learn nor numba)
_PUBLIC = {"MapLearner": ".learner", "TopologicalMap": ".map.model",
           **dict.fromkeys(("Trajectory", "check_sequences", "load_trajectory",
                            "save_trajectory"), ".data.trajectory")}


__getattr__ = lazy_getattr(__name__, _PUBLIC)
__dir__ = lazy_dir(__name__, __all__)
