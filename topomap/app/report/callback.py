"""The sweep report as a Hydra callback: written when a multirun ends, or when it ends early.

:class:`SweepReport` is registered in ``conf/config.yaml`` as ``hydra.callbacks.sweep_report``:
when the multirun ends it writes the report into the sweep folder and prints it
(:mod:`topomap.app.report.summary`).  A sweep that ends before Hydra ends the multirun -- Ctrl-C
or SIGTERM, or a search whose every trial failed -- never calls it: the ``topomap`` command then
writes the same report with :func:`report_early_end` (the interrupted job and those that did
not start are rows of it).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from hydra.experimental.callback import Callback
from omegaconf import OmegaConf

from ..results import check_metric
from .summary import Report, print_report, write_report

log = logging.getLogger("topomap")

__all__ = ["SweepReport", "report_early_end", "written_report"]

#: what a grid's report shows when no job has an ARI (no places: arena runs, robot logs), the
#: first column some job has
GRID_FALLBACK = ("pos_error", "heldout_loglik")

#: the file Hydra's basic sweeper keeps the multirun config in, in the sweep folder
MULTIRUN_FILE = "multirun.yaml"

#: sweep folder (resolved) -> the summary of its report, for the reports this process wrote
_written: dict[Path, Path] = {}


def written_report(sweep_dir) -> Path | None:
    """The summary of the report of the sweep in ``sweep_dir`` that this process wrote, None if
    it wrote none."""
    return _written.get(Path(sweep_dir).resolve())


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

    def metric_of(self, config) -> str:
        """The column the report shows for the multirun ``config``."""
        if self.metric is not None:
            return self.metric
        sweeper = OmegaConf.select(config, "hydra.sweeper", default=None)
        if sweeper is not None and "direction" in sweeper:
            objective = OmegaConf.select(config, "objective", default="heldout_loglik")
            return str(getattr(objective, "value", objective))  # an Objective, or its name
        return "ari"

    def on_multirun_end(self, config, **kwargs) -> None:
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
        _written[Path(sweep_dir).resolve()] = report.summary
        return report


def report_early_end(sweep_dir, config) -> Path | None:
    """Write and print the report of a sweep that ended before Hydra ended its multirun, as
    each :class:`SweepReport` among the callbacks of its multirun ``config`` would have; returns
    the summary's path, None when no callback reports (or the sweep made no folder).  The
    config Hydra's basic sweeper saved in the folder (``multirun.yaml``, with the plan of every
    job) is read in place of ``config`` where it exists."""
    sweep_dir = Path(sweep_dir)
    if not sweep_dir.is_dir():
        return None
    if (sweep_dir / MULTIRUN_FILE).is_file():
        config = OmegaConf.load(sweep_dir / MULTIRUN_FILE)
    from hydra.utils import get_class, instantiate

    summary = None
    for callback in (OmegaConf.select(config, "hydra.callbacks", default=None) or {}).values():
        target = OmegaConf.select(callback, "_target_", default=None)
        try:
            reports = target is not None and issubclass(get_class(str(target)), SweepReport)
        except Exception:  # a callback that cannot be imported here reports nothing
            reports = False
        if reports:
            summary = instantiate(callback).write(sweep_dir, config).summary
    return summary
