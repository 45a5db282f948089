"""topomap's own components, registered through the same hook as any plugin's.

This list is the only place a built-in is declared: its class (whose signature is its typed config,
see :mod:`topomap.app.compose.schemas`), the name users write, and a line for ``topomap --list-plugins``.
"""

from __future__ import annotations

from ...core.phase1 import clustering
from ...core.split import criteria, stopping
from ...worlds import arena, explorers, noise
from ...worlds.table import GridRoom
from ...worlds.minigrid import MiniGridWorld
from ...worlds.navigation import Navigation
from ...worlds.office import OfficeWorld
from ...worlds.table import RandomGraphWorld
from ...core import size as auto
from ...core.refine import methods as refine
from ..components import data, loggers
from .hookspecs import Component, hookimpl


def _c(kind, name, factory, description):
    return Component(kind, name, factory, description=description)


def nothing():
    """A component switched off (``refine=none``, ``evaluate=none``, ``logger=none``)."""
    return None


def _arena():
    """The arena and its parts: its sensors and its action rules."""
    return [
        _c("env", "arena", arena.ArenaWorld,
           "continuous motion in a floor plan (optional ratinabox package): random motion or a "
           "recorded rat path, scored in metres"),
        _c("sensor", "range", arena.RangeFinder,
           "the arena's range finder: beams to the nearest wall, compass-aligned or egocentric"),
        _c("sensor", "bvc", arena.BoundaryVectorCells,
           "the arena's boundary-vector cells (ratinabox), firing rates"),
        _c("sensor", "ovc", arena.ObjectVectorCells,
           "the arena's object-vector cells (ratinabox), tuned to the floor plan's objects"),
        _c("actions", "compass", arena.CompassActions,
           "the arena's moves as compass octants of the velocity, or stop"),
        _c("actions", "turns", arena.TurnActions,
           "the arena's moves as a differential drive's: forward, turn_left, turn_right, stop"),
    ]


@hookimpl
def topomap_register_components():
    return [
        _c("env", "office", OfficeWorld,
           "the paper's office: 25 objects of 15 types, panoramic size sensor, 17 actions"),
        _c("env", "gridroom", GridRoom, "a room of cells showing a few symbols (heavy aliasing), 4 moves"),
        _c("env", "random_graph", RandomGraphWorld,
           "random strongly connected digraph, places emit fewer symbols than places"),
        _c("env", "minigrid", MiniGridWorld,
           "a MiniGrid environment (optional minigrid package), left/right/forward"),
        *_arena(),
        _c("noise", "none", noise.NoNoise, "noise-free observations"),
        _c("noise", "gaussian", noise.GaussianNoise, "additive Gaussian noise (sigma), clipped at 0"),
        _c("noise", "dropout", noise.DropoutNoise,
           "missed detections: each entry zeroed with probability p"),
        _c("noise", "multiplicative", noise.MultiplicativeNoise, "log-normal gain per entry (sigma)"),
        _c("explorer", "random", explorers.RandomExplorer,
           "uniform choice among executable actions (the paper's)"),
        _c("explorer", "active", explorers.active_explorer,
           "the action least taken from the state (recent symbols and actions) under the map learned while exploring"),
        _c("metric", "euclidean", clustering.Euclidean, "Euclidean distance (the paper's)"),
        _c("metric", "standardized", clustering.Standardized,
           "Euclidean after scaling every feature to unit variance"),
        _c("metric", "cosine", clustering.Cosine, "cosine distance (observations scaled to unit length)"),
        _c("clusters", "fixed", clustering.FixedClusters,
           "a fixed number ns of K-means clusters (the paper's)"),
        _c("clusters", "bic", clustering.BICClusters,
           "ns in [min_ns, max_ns] with the lowest Gaussian-mixture BIC"),
        _c("split", "entropy", criteria.EntropyCriterion,
           "bottom-up merge and entropy gain of H(u) + H(x'|u) (the paper's)"),
        _c("stop", "n_states", stopping.TargetStates,
           "split until the map has n_states states (the paper's)"),
        _c("stop", "min_gain", stopping.MinGain,
           "split while the best gain is at least min_gain (bits)"),
        _c("stop", "auto", auto.AutoStates,
           "choose the number of states: the held-out log-likelihood (or BIC) of every split size"),
        _c("data", "simulate", data.Simulate, "simulate the configured world for n_steps steps"),
        _c("data", "file", data.FromFile, "learn from a recorded trajectory (.npz or .csv)"),
        _c("data", "rosbag", data.FromRosbag,
           "learn from ROS 1 / ROS 2 bags (optional rosbags package): scans or numeric fields, "
           "String / Int32 / Twist actions"),
        _c("refine", "none", nothing, "the paper's method alone: the split map is the map"),
        _c("refine", "em", refine.EMRefinement,
           "EM over a clone budget sized by the split, merging and splitting states"),
        _c("refine", "cscg", refine.CSCGRefinement,
           "EM alone from phase 1 with CSCG's recipe (70 clones per symbol), for comparison"),
        _c("evaluate", "none", nothing, "no evaluation beyond ground truth and held-out data"),
        _c("evaluate", "navigation", Navigation,
           "localise, plan on the map and act in the world: success rate and path length"),
        _c("logger", "none", nothing, "the run's files only"),
        _c("logger", "mlflow", loggers.MLflowLogger,
           "MLflow tracking (optional mlflow package): config, metrics, map and figures"),
    ]
