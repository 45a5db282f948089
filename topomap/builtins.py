"""topomap's own components, registered through the same hook as any plugin's."""

from __future__ import annotations

from . import clustering, explorers, noise, schema, splitting
from .envs.gridroom import GridRoom
from .envs.minigrid_env import MiniGridWorld
from .envs.office import OfficeWorld
from .envs.random_graph import RandomGraphWorld
from .hookspecs import Component, hookimpl


@hookimpl
def topomap_register_components():
    C = Component
    return [
        C("env", "office", OfficeWorld, schema.OfficeEnvConf,
          "the paper's office: 25 objects of 15 types, panoramic size sensor, 17 actions"),
        C("env", "gridroom", GridRoom, schema.GridRoomEnvConf,
          "a room of cells showing a few symbols (heavy aliasing), 4 moves"),
        C("env", "random_graph", RandomGraphWorld, schema.RandomGraphEnvConf,
          "random strongly connected digraph, places emit fewer symbols than places"),
        C("env", "minigrid", lambda name, **kw: MiniGridWorld(env_id=name, **kw), schema.MiniGridEnvConf,
          "a MiniGrid environment (optional minigrid package), left/right/forward"),
        C("noise", "none", noise.NoNoise, schema.NoNoiseConf, "noise-free observations"),
        C("noise", "gaussian", noise.GaussianNoise, schema.GaussianNoiseConf,
          "additive Gaussian noise (sigma), clipped at 0"),
        C("noise", "dropout", noise.DropoutNoise, schema.DropoutNoiseConf,
          "missed detections: each entry zeroed with probability p"),
        C("noise", "multiplicative", noise.MultiplicativeNoise, schema.MultiplicativeNoiseConf,
          "log-normal gain per entry (sigma)"),
        C("explorer", "random", explorers.RandomExplorer, schema.RandomExplorerConf,
          "uniform choice among executable actions (the paper's)"),
        C("metric", "euclidean", clustering.Euclidean, schema.EuclideanConf,
          "Euclidean distance (the paper's)"),
        C("metric", "standardized", clustering.Standardized, schema.StandardizedConf,
          "Euclidean after scaling every feature to unit variance"),
        C("metric", "cosine", clustering.Cosine, schema.CosineConf,
          "cosine distance (observations scaled to unit length)"),
        C("clusters", "fixed", clustering.FixedClusters, schema.FixedClustersConf,
          "a fixed number ns of K-means clusters (the paper's)"),
        C("clusters", "bic", clustering.BICClusters, schema.BICClustersConf,
          "ns in [min_ns, max_ns] with the lowest Gaussian-mixture BIC"),
        C("split", "entropy", splitting.EntropyCriterion, schema.EntropySplitConf,
          "bottom-up merge and entropy gain of H(u) + H(x'|u) (the paper's)"),
        C("stop", "n_states", splitting.TargetStates, schema.TargetStatesConf,
          "split until the map has n_states states (the paper's)"),
        C("stop", "min_gain", splitting.MinGain, schema.MinGainConf,
          "split while the best gain is at least min_gain (bits)"),
    ]
