"""The sweep report as a Hydra callback: written when a multirun ends.

:class:`SweepReport` is registered in ``conf/config.yaml`` as ``hydra.callbacks.sweep_report``:
when the multirun ends it writes the report into the sweep folder and prints it
(:mod:`topomap.app.report.summary`); before the first job it stops a search that would optimise
its objective the wrong way.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from hydra.experimental.callback import Callback

from ..results import OBJECTIVES, check_metric, objective_direction
from .summary import print_report, write_report

log = logging.getLogger("topomap")

__all__ = ["SweepReport", "interrupted_sweep_report"]


# ---------------------------------------------------------------------------------- entry points
class SweepReport(Callback):
    """Hydra callback: write the sweep report when a multirun ends.

    Parameters (``hydra.callbacks.sweep_report.<name>=...``)
    ---------------------------------------------------------
    metric : str or None
        Summary column shown in the figure and the printed table, one of :data:`~topomap.app.results.METRICS`; None
        (the default): the run's ``objective`` when the sweeper optimises it (Optuna), else
        ``ari`` (the final ARI).
    figure : bool
        Write ``summary_<metric>.png``.
    strict : bool
        Exit with status 1 after writing the report if any job failed (default: failed jobs are
        rows of the report and the command succeeds).
    """

    #: the sweep under way in this process (its report and multirun config), for
    #: :func:`interrupted_sweep_report`
    running = None

    def __init__(self, metric: str | None = None, figure: bool = True, strict: bool = False):
        if metric is not None:
            check_metric(metric, "hydra.callbacks.sweep_report.metric")
        self.metric, self.figure, self.strict = metric, bool(figure), bool(strict)

    def metric_of(self, config) -> str:
        """The column the report shows for the multirun ``config``."""
        from omegaconf import OmegaConf

        if self.metric is not None:
            return self.metric
        sweeper = OmegaConf.select(config, "hydra.sweeper", default=None)
        if sweeper is not None and "direction" in sweeper:
            objective = OmegaConf.select(config, "objective", default="heldout_loglik")
            return str(getattr(objective, "value", objective))  # an Objective, or its name
        return "ari"

    def on_multirun_start(self, config, **kwargs) -> None:
        """Stop a search before its first job when it would optimise the wrong way: the
        sweeper's ``direction`` against the objective's (:data:`~topomap.app.results.OBJECTIVES`)."""
        from omegaconf import OmegaConf

        SweepReport.running = (self, config)
        direction = OmegaConf.select(config, "hydra.sweeper.direction", default=None)
        direction = getattr(direction, "name", direction)  # the plugin's Direction enum, or text
        objective = OmegaConf.select(config, "objective", default=None)
        objective = getattr(objective, "value", objective)
        wanted = objective_direction(objective) if objective in OBJECTIVES else None
        if isinstance(direction, str) and wanted and direction != wanted:
            sys.exit(f"topomap: error: hydra.sweeper.direction={direction}, but "
                     f"objective={objective} is better when "
                     f"{'larger' if wanted == 'maximize' else 'smaller'}; give "
                     f"hydra.sweeper.direction={wanted}")

    def on_multirun_end(self, config, **kwargs) -> None:
        SweepReport.running = None
        sweep_dir = Path(str(config.hydra.sweep.dir))
        report = write_report(sweep_dir, metric=self.metric_of(config), figure=self.figure,
                              multirun_cfg=config)
        print_report(report)
        if report.failed:
            log.warning("%d of %d jobs did not complete; their errors are in %s",
                        len(report.failed), len(report.rows), report.summary)
            if self.strict:
                sys.exit(f"topomap: error: {len(report.failed)} of {len(report.rows)} jobs "
                         f"did not complete; see {report.summary}")


def interrupted_sweep_report() -> Path | None:
    """After Ctrl-C or SIGTERM ended the sweep under way in this process: write and print its
    report (the interrupted job and those that did not start are rows of it); returns the
    summary's path, None when no sweep was under way."""
    if SweepReport.running is None:
        return None
    callback, config = SweepReport.running
    SweepReport.running = None
    sweep_dir = Path(str(config.hydra.sweep.dir))
    from omegaconf import OmegaConf

    if (sweep_dir / "multirun.yaml").is_file():  # the job config Hydra saved, with the plan
        config = OmegaConf.load(sweep_dir / "multirun.yaml")
    report = write_report(sweep_dir, metric=callback.metric_of(config), figure=callback.figure,
                          multirun_cfg=config)
    print_report(report)
    return report.summary
