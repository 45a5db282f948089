"""topomap: learn a robot's topological map from observations and actions.

Implements Yairi, Togami & Hori, "Learning Topological Maps from Sequential Observation and Action
Data under Partially Observable Environment" (PRICAI 2002): K-means symbols as initial states, then
greedy entropy-based splitting of perceptually aliased states.

The package has three floors, each importing only the ones below it:

* :mod:`topomap.core` -- the learning core (numpy and scikit-learn only);
* :mod:`topomap.worlds` -- simulated worlds, sensor noise and explorers, producing trajectories;
* :mod:`topomap.app` -- the ``topomap`` command: Hydra configs, plugins, experiments, sweeps.

``import topomap`` loads the core only.
"""

from . import metrics
from .core import MapLearner, TopologicalMap, Trajectory, load_trajectory, save_trajectory
from .core.data.rosbag import read_rosbag, write_rosbag

__all__ = ["MapLearner", "TopologicalMap", "Trajectory", "load_trajectory", "save_trajectory",
           "read_rosbag", "write_rosbag", "metrics", "hookimpl", "Component"]
__version__ = "0.2.0"


def __getattr__(name):
    """What a plugin imports, ``topomap.hookimpl`` (the plugin marker) and ``topomap.Component``
    (what it registers), is loaded on first use, with pluggy."""
    if name in ("hookimpl", "Component"):
        from .app.compose import hookspecs

        return getattr(hookspecs, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
