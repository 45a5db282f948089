"""topomap: learn a robot's topological map from observations and actions.

Implements Yairi, Togami & Hori, "Learning Topological Maps from Sequential Observation and Action
Data under Partially Observable Environment" (PRICAI 2002): K-means symbols as initial states, then
greedy entropy-based splitting of perceptually aliased states.

The package has three floors, each importing only the ones below it:

* :mod:`topomap.core` -- the learning core (numpy, scikit-learn, numba; no Hydra, no simulator);
* :mod:`topomap.worlds` -- simulated worlds, sensor noise and explorers, producing trajectories;
* :mod:`topomap.evaluation` -- beside the worlds, how good a learned map is: its states against
  true places (public as :mod:`topomap.metrics`) and against true positions, in metres;
* :mod:`topomap.app` -- the ``topomap`` command: Hydra configs, plugins, experiments, sweeps.

``import topomap`` loads nothing heavy: each public name is imported on first use (the learner
with scikit-learn and numba, the plugin marker with pluggy), so the ``topomap`` command answers
``--version`` and ``--help`` without them.
"""

import importlib
from typing import TYPE_CHECKING

from .core.lazy import lazy_dir, lazy_getattr

if TYPE_CHECKING:  # what the names below are, for readers and documentation tools
    from . import metrics
    from .app.compose.hookspecs import Component, hookimpl
    from .core.data.rosbag import read_rosbag, write_rosbag
    from .core.data.trajectory import Trajectory, load_trajectory, save_trajectory
    from .core.learner import MapLearner
    from .core.map.model import TopologicalMap

#: where each public name lives, imported on first use (:func:`__getattr__`)
_PUBLIC = {
    "MapLearner": "topomap.core.learner",
    "TopologicalMap": "topomap.core.map.model",
    "Trajectory": "topomap.core.data.trajectory",
    "load_trajectory": "topomap.core.data.trajectory",
    "save_trajectory": "topomap.core.data.trajectory",
    "read_rosbag": "topomap.core.data.rosbag",
    "write_rosbag": "topomap.core.data.rosbag",
    "hookimpl": "topomap.app.compose.hookspecs",
    "Component": "topomap.app.compose.hookspecs",
}

__all__ = ["MapLearner", "TopologicalMap", "Trajectory", "load_trajectory", "save_trajectory",
           "read_rosbag", "write_rosbag", "metrics", "hookimpl", "Component"]
__version__ = "0.2.0"
_public = lazy_getattr(__name__, _PUBLIC)


def __getattr__(name):
    """The public names, imported on first use: ``topomap.metrics`` and the names of
    :data:`_PUBLIC` (``topomap.hookimpl`` and ``topomap.Component``, what a plugin imports, come
    with pluggy)."""
    if name == "metrics":
        return importlib.import_module("topomap.metrics")
    return _public(name)


__dir__ = lazy_dir(__name__, __all__)
