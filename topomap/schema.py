"""Typed (structured) configs for the Hydra app.

Every component has a dataclass whose fields are its parameters plus ``component``, the
registered name that selects it; it is stored in Hydra's
ConfigStore as ``<kind>/<name>_schema`` and the YAML file ``conf/<kind>/<name>.yaml`` extends it, so
``topomap clusters.ns=abc`` or a misspelt key fails at once with a message naming the key.
Importing this module registers the schemas (``conf/__init__.py`` does, so Hydra's compose API
finds them too).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

# ---------------------------------------------------------------- environments and sensing
@dataclass
class OfficeEnvConf:
    """The paper's office (Section 4.1); see :class:`topomap.envs.office.OfficeWorld`."""

    component: str = "office"
    layout: str = "paper"
    n_objects: int = 25
    n_types: int = 15
    n_gds: int = 2
    width: float = 20.0
    height: float = 14.0
    reach: float = 1.0
    view_range: float = 3.0
    step_size: float = 0.25
    max_turn_deg: float = 90.0
    max_action_steps: int = 400
    seed: int = 0
    dock: bool = True


@dataclass
class GridRoomEnvConf:
    """A room of cells showing a few symbols; see :class:`topomap.envs.gridroom.GridRoom`."""

    component: str = "gridroom"
    width: int = 8
    height: int = 6
    n_symbols: int = 4
    obs_dim: int = 0
    seed: int = 0


@dataclass
class RandomGraphEnvConf:
    """A random strongly connected digraph; see :class:`topomap.envs.random_graph.RandomGraphWorld`."""

    component: str = "random_graph"
    n_places: int = 30
    out_degree: int = 4
    n_symbols: int = 20
    obs_dim: int = 0
    layout: str = "spring"
    seed: int = 0


@dataclass
class MiniGridEnvConf:
    """A MiniGrid environment; see :class:`topomap.envs.minigrid_env.MiniGridWorld`."""

    component: str = "minigrid"
    #: the MiniGrid environment id (``topomap env=minigrid env.name=MiniGrid-FourRooms-v0``)
    name: str = "MiniGrid-Empty-8x8-v0"
    seed: int = 0


@dataclass
class NoNoiseConf:
    component: str = "none"


@dataclass
class GaussianNoiseConf:
    component: str = "gaussian"
    sigma: float = 0.01


@dataclass
class DropoutNoiseConf:
    component: str = "dropout"
    p: float = 0.1


@dataclass
class MultiplicativeNoiseConf:
    component: str = "multiplicative"
    sigma: float = 0.1


@dataclass
class RandomExplorerConf:
    component: str = "random"


# ---------------------------------------------------------------- learner pieces
@dataclass
class EuclideanConf:
    component: str = "euclidean"


@dataclass
class StandardizedConf:
    component: str = "standardized"


@dataclass
class CosineConf:
    component: str = "cosine"


@dataclass
class FixedClustersConf:
    component: str = "fixed"
    ns: int = 20


@dataclass
class BICClustersConf:
    component: str = "bic"
    min_ns: int = 5
    max_ns: int = 40
    step: int = 1
    covariance_type: str = "diag"
    n_init: int = 1


@dataclass
class EntropySplitConf:
    component: str = "entropy"


@dataclass
class TargetStatesConf:
    component: str = "n_states"
    n_states: int = 30


@dataclass
class MinGainConf:
    component: str = "min_gain"
    min_gain: float = 0.05
    max_states: Optional[int] = None


# ---------------------------------------------------------------- the app
@dataclass
class SimulateDataConf:
    """Simulate the configured world for ``n_steps`` steps."""

    component: str = "simulate"
    n_steps: int = 2000
    #: length of the held-out walk the map is scored on (null: n_steps; 0: none)
    heldout_steps: Optional[int] = None


@dataclass
class FileDataConf:
    """Learn from a recorded trajectory (``.npz`` or ``.csv``); no simulation."""

    component: str = "file"
    path: str = MISSING
    #: a second recording of the same world the map is scored on (null: no held-out score)
    heldout_path: Optional[str] = None


@dataclass
class LearnerConf:
    covariance_type: str = "diag"
    reg_covar: float = 1e-3
    n_init: int = 3


@dataclass
class OutputConf:
    #: arcs drawn and exported to GraphML when P(x'|x,u) exceeds this (the paper: 0.8)
    min_prob: float = 0.8
    #: write PNG figures
    figures: bool = True
    #: the phase-1 state shown before/after its split (None: the first state that was split)
    compound_state: Optional[int] = None
    #: show progress bars on the terminal
    progress: bool = True


@dataclass
class Config:
    seed: int = 0
    plugins: list[str] = field(default_factory=list)
    env: Any = MISSING
    noise: Any = MISSING
    explorer: Any = MISSING
    metric: Any = MISSING
    clusters: Any = MISSING
    split: Any = MISSING
    stop: Any = MISSING
    data: Any = MISSING
    learner: LearnerConf = field(default_factory=LearnerConf)
    output: OutputConf = field(default_factory=OutputConf)


#: (group, option name, schema) of every built-in option; conf/<group>/<name>.yaml extends each
BUILTIN_SCHEMAS = [
    ("env", "office", OfficeEnvConf),
    ("env", "gridroom", GridRoomEnvConf),
    ("env", "random_graph", RandomGraphEnvConf),
    ("env", "minigrid", MiniGridEnvConf),
    ("noise", "none", NoNoiseConf),
    ("noise", "gaussian", GaussianNoiseConf),
    ("noise", "dropout", DropoutNoiseConf),
    ("noise", "multiplicative", MultiplicativeNoiseConf),
    ("explorer", "random", RandomExplorerConf),
    ("metric", "euclidean", EuclideanConf),
    ("metric", "standardized", StandardizedConf),
    ("metric", "cosine", CosineConf),
    ("clusters", "fixed", FixedClustersConf),
    ("clusters", "bic", BICClustersConf),
    ("split", "entropy", EntropySplitConf),
    ("stop", "n_states", TargetStatesConf),
    ("stop", "min_gain", MinGainConf),
    ("data", "simulate", SimulateDataConf),
    ("data", "file", FileDataConf),
]


def store_schemas() -> None:
    cs = ConfigStore.instance()
    cs.store(name="topomap_schema", node=Config)
    for group, name, node in BUILTIN_SCHEMAS:
        cs.store(group=group, name=f"{name}_schema", node=node)


store_schemas()
