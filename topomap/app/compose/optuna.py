"""``hydra/sweeper=optuna`` set for topomap: the Optuna sweeper plugin's config, maximising,
seeded by the run's ``seed`` (:func:`store_optuna_sweeper`, called by
:func:`~topomap.app.compose.store.store_configs`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

from omegaconf import II

__all__ = ["store_optuna_sweeper"]


def store_optuna_sweeper(cs) -> None:
    """``hydra/sweeper=optuna`` set for topomap, when the Optuna sweeper plugin is installed
    (``pip install "topomap[optuna]"``): the plugin's own config (``OptunaSweeperConf``), but
    maximising (both of topomap's objectives are better when larger; the plugin minimises by
    default), one trial at a time, and going on past jobs that cannot run (``max_failure_rate``:
    such a job is a failed trial and a row of ``summary.csv``, as in a grid), its study kept in
    the sweep folder (:class:`~topomap.app.compose.study.SweepStudy`: a later search given
    ``hydra.sweeper.storage.resume_from=<that folder>`` goes on with its trials); and its default
    sampler, ``hydra/sweeper/sampler=tpe``, seeded by the run's ``seed`` (the same command
    proposes the same trials).  Every field can still be set: ``hydra.sweeper.n_trials=30``."""
    try:
        from hydra_plugins.hydra_optuna_sweeper.config import OptunaSweeperConf, TPESamplerConfig
    except ImportError:
        return
    import logging

    from hydra.core.plugins import Plugins

    logging.getLogger("alembic").setLevel(logging.WARNING)  # Optuna's database migrations, a
    # line for each of its plugins when the sweeper imports Optuna

    Plugins.instance()  # Hydra's first plugin scan stores the plugin's options: let it come first

    @dataclass
    class TopomapOptunaSweeperConf(OptunaSweeperConf):
        direction: Any = "maximize"
        storage: Optional[Any] = field(default_factory=lambda: {
            "_target_": "topomap.app.compose.study.SweepStudy", "folder": II("hydra.sweep.dir"),
            "resume_from": None, "n_trials": II("hydra.sweeper.n_trials"),
            "objective": II("objective")})
        study_name: Optional[str] = "topomap"
        n_jobs: int = 1
        max_failure_rate: float = 1.0

    @dataclass
    class SeededTPESamplerConf(TPESamplerConfig):
        seed: Optional[int] = II("seed")

    cs.store(group="hydra/sweeper", name="optuna", node=TopomapOptunaSweeperConf, provider="topomap")
    cs.store(group="hydra/sweeper/sampler", name="tpe", node=SeededTPESamplerConf,
             provider="topomap")
