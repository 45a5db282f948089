"""The sweep report as a Hydra callback: written when a multirun ends, or when it is interrupted.

:class:`SweepReport` is registered in ``conf/config.yaml`` as ``hydra.callbacks.sweep_report``:
when the multirun ends it writes the report into the sweep folder and prints it
(:mod:`topomap.app.report.summary`); before the first job it stops a search that would optimise
its objective the wrong way.  While the sweep runs, Ctrl-C and SIGTERM raise
:class:`SweepInterrupted`: a :class:`KeyboardInterrupt` that carries the sweep, so that whoever
ends the process (the ``topomap`` command) writes the report with the interrupted job and those
that did not start.
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
from pathlib import Path

from hydra.experimental.callback import Callback
from omegaconf import OmegaConf

from ..results import OBJECTIVES, check_metric, objective_direction
from .summary import Report, print_report, write_report

log = logging.getLogger("topomap")

__all__ = ["SweepReport", "SweepInterrupted"]

#: the signals that end a sweep (Ctrl-C and a kill), raised as :class:`SweepInterrupted`
INTERRUPTS = (signal.SIGINT, signal.SIGTERM)
#: what a grid's report shows when no job has an ARI (no places: arena runs, robot logs), the
#: first column some job has
GRID_FALLBACK = ("pos_error", "heldout_loglik")


class SweepReport(Callback):
    """Hydra callback: write the sweep report when a multirun ends.

    Parameters (``hydra.callbacks.sweep_report.<name>=...``)
    ---------------------------------------------------------
    metric : str or None
        Summary column shown in the figure and the printed table, one of
        :data:`~topomap.app.results.METRICS`; None (the default): the run's ``objective`` when
        the sweeper optimises it (Optuna), else ``ari`` (the final ARI), or where no job has one
        the first of :data:`GRID_FALLBACK` some job has (the localisation error of arena runs).
    figure : bool
        Write ``summary_<metric>.png``.
    strict : bool
        Exit with status 1 after writing the report if any job failed (default: failed jobs are
        rows of the report and the command succeeds).
    """

    def __init__(self, metric: str | None = None, figure: bool = True, strict: bool = False):
        if metric is not None:
            check_metric(metric, "hydra.callbacks.sweep_report.metric")
        self.metric, self.figure, self.strict = metric, bool(figure), bool(strict)
        self._replaced: dict = {}  # the signal handlers the sweep's own replace while it runs

    def metric_of(self, config) -> str:
        """The column the report shows for the multirun ``config``."""
        if self.metric is not None:
            return self.metric
        sweeper = OmegaConf.select(config, "hydra.sweeper", default=None)
        if sweeper is not None and "direction" in sweeper:
            objective = OmegaConf.select(config, "objective", default="heldout_loglik")
            return str(getattr(objective, "value", objective))  # an Objective, or its name
        return "ari"

    def on_multirun_start(self, config, **kwargs) -> None:
        """Stop a search before its first job when it would optimise the wrong way: the
        sweeper's ``direction`` against the objective's (:data:`~topomap.app.results.OBJECTIVES`);
        then make Ctrl-C and SIGTERM raise :class:`SweepInterrupted` until the sweep ends."""
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
        if threading.current_thread() is threading.main_thread():  # where Python takes signals

            def interrupted(signum, frame):
                raise SweepInterrupted(f"signal {signal.Signals(signum).name}", self, config)

            self._replaced = {sig: signal.signal(sig, interrupted) for sig in INTERRUPTS}

    def on_multirun_end(self, config, **kwargs) -> None:
        for sig, handler in self._replaced.items():
            signal.signal(sig, handler)
        self._replaced = {}
        report = self.write(Path(str(config.hydra.sweep.dir)), config)
        if report.failed:
            log.warning("%d of %d jobs did not complete; their errors are in %s",
                        len(report.failed), len(report.rows), report.summary)
            if self.strict:
                sys.exit(f"topomap: error: {len(report.failed)} of {len(report.rows)} jobs "
                         f"did not complete; see {report.summary}")

    def write(self, sweep_dir: Path, config) -> Report:
        """Write and print the report of the sweep in ``sweep_dir`` (the multirun ``config``)."""
        metric = self.metric_of(config)
        grid = self.metric is None and metric == "ari"  # not told, and no search's objective
        report = write_report(sweep_dir, metric=metric, figure=self.figure, multirun_cfg=config,
                              fallback=GRID_FALLBACK if grid else ())
        print_report(report)
        return report


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM while a sweep runs: a :class:`KeyboardInterrupt` (a job writes
    ``interrupted`` into its ``status.json`` and raises it again) that carries the sweep, for
    :meth:`write_report` once it has ended the sweep."""

    def __init__(self, message: str, callback: SweepReport, config):
        super().__init__(message)
        self.callback, self.config = callback, config

    def write_report(self) -> Path:
        """Write and print the report of the interrupted sweep (the interrupted job and those
        that did not start are rows of it); returns the summary's path."""
        config, sweep_dir = self.config, Path(str(self.config.hydra.sweep.dir))
        if (sweep_dir / "multirun.yaml").is_file():  # the job config Hydra saved, with the plan
            config = OmegaConf.load(sweep_dir / "multirun.yaml")
        return self.callback.write(sweep_dir, config).summary
