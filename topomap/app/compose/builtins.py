"""topomap's own components, registered through the same hook as any plugin's.

This list is the only place a built-in is declared: its class (whose signature is its typed config,
see :mod:`topomap.app.compose.schemas`), the name users write, and a line for ``topomap --list-plugins``.
Each class is named by its import path, imported when a run builds it: the command lists, checks and
prints configs without loading the learner (scikit-learn, numba) or the worlds.
"""

from __future__ import annotations

from .hookspecs import Component, hookimpl


def _c(kind, name, factory, description):
    return Component(kind, name, factory, description=description)


def nothing():
    """A component switched off (``refine=none``, ``evaluate=none``, ``logger=none``,
    ``odometry=none``)."""
    return None


def _arena():
    """The arena and its parts: its sensors, its action rules and its odometry."""
    return [
        _c("env", "arena", "topomap.worlds.arena:ArenaWorld",
           "continuous motion in a floor plan (optional ratinabox package): random motion or a "
           "recorded rat path, scored in metres"),
        _c("sensor", "range", "topomap.worlds.arena:RangeFinder",
           "the arena's range finder: beams to the nearest wall, compass-aligned or egocentric"),
        _c("sensor", "bvc", "topomap.worlds.arena:BoundaryVectorCells",
           "the arena's boundary-vector cells (ratinabox), firing rates"),
        _c("sensor", "ovc", "topomap.worlds.arena:ObjectVectorCells",
           "the arena's object-vector cells (ratinabox), tuned to the floor plan's objects"),
        _c("sensor", "place_cells", "topomap.worlds.arena:PlaceCells",
           "the arena's place cells (ratinabox): Gaussian fields around centres on the floor"),
        _c("sensor", "grid_cells", "topomap.worlds.arena:GridCells",
           "the arena's grid cells (ratinabox): rectified cosine gratings in three modules"),
        _c("actions", "compass", "topomap.worlds.arena:CompassActions",
           "the arena's moves as compass octants of the velocity, or stop"),
        _c("actions", "turns", "topomap.worlds.arena:TurnActions",
           "the arena's moves as a differential drive's: forward, turn_left, turn_right, stop"),
        _c("odometry", "none", nothing, "no odometry: the walks hold none (the default)"),
        _c("odometry", "wheel", "topomap.worlds.arena:WheelOdometry",
           "the robot's wheel odometry (the arena): dead reckoning with speed and turn-rate "
           "noise, a gyro bias and slips"),
    ]


@hookimpl
def topomap_register_components():
    return [
        _c("env", "office", "topomap.worlds.office:OfficeWorld",
           "the paper's office: 25 objects of 15 types, panoramic size sensor, 17 actions"),
        _c("env", "gridroom", "topomap.worlds.table:GridRoom", "a room of cells showing a few symbols (heavy aliasing), 4 moves"),
        _c("env", "random_graph", "topomap.worlds.table:RandomGraphWorld",
           "random strongly connected digraph, places emit fewer symbols than places"),
        _c("env", "minigrid", "topomap.worlds.minigrid:MiniGridWorld",
           "a MiniGrid environment (optional minigrid package), left/right/forward"),
        *_arena(),
        _c("noise", "none", "topomap.worlds.noise:NoNoise", "noise-free observations"),
        _c("noise", "gaussian", "topomap.worlds.noise:GaussianNoise", "additive Gaussian noise (sigma), clipped at 0"),
        _c("noise", "dropout", "topomap.worlds.noise:DropoutNoise",
           "missed detections: each entry zeroed with probability p"),
        _c("noise", "multiplicative", "topomap.worlds.noise:MultiplicativeNoise", "log-normal gain per entry (sigma)"),
        _c("explorer", "random", "topomap.worlds.explorers:RandomExplorer",
           "uniform choice among executable actions (the paper's)"),
        _c("explorer", "active", "topomap.worlds.explorers:active_explorer",
           "the action least taken from the state (recent symbols and actions) under the map learned while exploring"),
        _c("metric", "euclidean", "topomap.core.phase1.clustering:Euclidean", "Euclidean distance (the paper's)"),
        _c("metric", "standardized", "topomap.core.phase1.clustering:Standardized",
           "Euclidean after scaling every feature to unit variance"),
        _c("metric", "cosine", "topomap.core.phase1.clustering:Cosine", "cosine distance (observations scaled to unit length)"),
        _c("clusters", "fixed", "topomap.core.phase1.clustering:FixedClusters",
           "a fixed number ns of K-means clusters (the paper's)"),
        _c("clusters", "bic", "topomap.core.phase1.clustering:BICClusters",
           "ns in [min_ns, max_ns] with the lowest Gaussian-mixture BIC"),
        _c("split", "entropy", "topomap.core.split.criteria:EntropyCriterion",
           "bottom-up merge and entropy gain of H(u) + H(x'|u) (the paper's)"),
        _c("stop", "n_states", "topomap.core.split.stopping:TargetStates",
           "split until the map has n_states states (the paper's)"),
        _c("stop", "min_gain", "topomap.core.split.stopping:MinGain",
           "split while the best gain is at least min_gain (bits)"),
        _c("stop", "auto", "topomap.core.size:AutoStates",
           "choose the number of states: the held-out log-likelihood (or BIC) of every split size"),
        _c("data", "simulate", "topomap.app.components.data:Simulate", "simulate the configured world for n_steps steps"),
        _c("data", "file", "topomap.app.components.data:FromFile", "learn from a recorded trajectory (.npz or .csv)"),
        _c("data", "rosbag", "topomap.app.components.data:FromRosbag",
           "learn from ROS 1 / ROS 2 bags (optional rosbags package): scans or numeric fields, "
           "String / Int32 / Twist actions"),
        _c("refine", "none", nothing, "the paper's method alone: the split map is the map"),
        _c("refine", "em", "topomap.core.refine.methods:EMRefinement",
           "EM over a clone budget sized by the split, merging and splitting states"),
        _c("refine", "cscg", "topomap.core.refine.methods:CSCGRefinement",
           "EM alone from phase 1 with CSCG's recipe (70 clones per symbol), for comparison"),
        _c("evaluate", "none", nothing, "no evaluation beyond ground truth and held-out data"),
        _c("evaluate", "navigation", "topomap.worlds.navigation:Navigation",
           "localise, plan on the map and act in the world: success rate and path length"),
        _c("logger", "none", nothing, "the run's files only"),
        _c("logger", "mlflow", "topomap.app.components.loggers:MLflowLogger",
           "MLflow tracking (optional mlflow package): config, metrics, map and figures"),
    ]
