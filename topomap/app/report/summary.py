"""The sweep report: the table that compares the jobs of ``topomap -m ...``.

Every job of a sweep (any Hydra launcher: the basic one, ``joblib``, ``submitit_local`` or
``submitit_slurm``) runs :func:`topomap.app.run.job.run_job`, which learns from the trajectory
cached in ``<sweep dir>/.cache/`` and writes ``status.json`` into its folder: ``completed``, or
``failed`` with the error (the job then returns normally, so the sweep goes on and Hydra still ends
it with the report).

:func:`write_report` reads every job's folder and writes into the sweep folder

* ``summary.csv``: one row per job (swept values, status, states, ARI/NMI/purity, entropies,
  held-out log-likelihood, times, error), and
* ``summary_<metric>.png``: the metric over the swept values (a heat map for two swept keys, a
  line for one; no figure otherwise);

:func:`print_report` prints the metric as a table.  The Hydra callback
:class:`~topomap.app.report.callback.SweepReport` does both when a multirun ends, and
``python -m topomap.app.report`` (:mod:`topomap.app.report.cli`) at any time, e.g. for another
metric or after an interrupted sweep.

The job folders are read by :mod:`topomap.app.report.jobs`, the figures drawn by
:mod:`topomap.app.report.figure`; the CSV's columns, the table's and the figures' labels and the best
job all follow the column list :data:`topomap.app.results.COLUMNS`.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from ...core.data.atomic import atomic_write
from ..results import METRICS, STUDY_FILE, check_metric
from .columns import axis_values, best_row, header, mean, no_value, number, row, short
from .figure import is_grid
from .jobs import not_started, planned_jobs, read_jobs, read_study, swept_keys

log = logging.getLogger("topomap")

__all__ = ["Report", "write_report", "print_report", "SUMMARY_FILE"]

SUMMARY_FILE = "summary.csv"


@dataclass
class Report:
    """What :func:`write_report` wrote and found."""

    summary: Path
    figure: Path | None
    keys: list[str]
    rows: list[dict]
    metric: str
    best: dict | None
    study_best: dict | None = None

    @property
    def failed(self) -> list[dict]:
        """Rows of jobs that did not complete (``failed``, ``interrupted``, ``incomplete`` or
        ``not started``)."""
        return [r for r in self.rows if r["status"] != "completed"]


def write_report(sweep_dir, *, metric: str = "ari", figure: bool = True,
                 multirun_cfg=None, fallback=()) -> Report:
    """Write ``summary.csv`` (and ``summary_<metric>.png``) for the sweep in ``sweep_dir``.

    ``multirun_cfg`` (the multirun config; by default ``sweep_dir/multirun.yaml``) names the swept
    keys and, for Hydra's basic sweeper, every job the sweep was to run: a job without a folder
    is a row ``not started``.  ``fallback``: the columns shown instead, the first that some job
    has, when no job has ``metric`` (a grid of arena runs has no ARI, but a localisation error).
    A search's folder holds its study (:data:`~topomap.app.results.STUDY_FILE`), with the
    trials of the searches it went on from: the best is the study's best trial
    (:func:`study_best`), and a job of this folder is the report's ``best`` only if it is that
    trial.  Returns a :class:`Report`.
    """
    check_metric(metric)
    for other in fallback:
        check_metric(other)
    sweep_dir = Path(sweep_dir)
    if multirun_cfg is None and (sweep_dir / "multirun.yaml").is_file():
        from omegaconf import OmegaConf

        multirun_cfg = OmegaConf.load(sweep_dir / "multirun.yaml")
    jobs = read_jobs(sweep_dir)
    if jobs:
        jobs = sorted(jobs + not_started(jobs, planned_jobs(multirun_cfg), sweep_dir),
                      key=lambda j: j.num)
    keys = swept_keys(multirun_cfg, jobs)
    rows = [row(j, keys, sweep_dir) for j in jobs]
    metric = _shown(rows, metric, fallback)
    summary = _write_summary(sweep_dir / SUMMARY_FILE, header(keys), rows)
    best = best_row(rows, metric)
    overall = study_best(sweep_dir, metric)
    if overall is not None and not overall["here"]:
        best = None  # an earlier search's trial: no job of this folder is the best
    fig_path = None
    if figure and rows and 1 <= len(keys) <= 2:
        if all(math.isnan(number(r[metric])) for r in rows):
            log.warning("sweep report: no job has a value for %s; no figure", metric)
        else:
            from .figure import write_sweep_figure

            fig_path = sweep_dir / f"summary_{metric}.png"
            write_sweep_figure(fig_path, rows, keys, metric, best)
    elif figure and rows:
        log.info("sweep report: %d swept keys, so no figure (one or two make a line or a heat map)",
                 len(keys))
    return Report(summary=summary, figure=fig_path, keys=keys, rows=rows, metric=metric, best=best,
                  study_best=overall)


def study_best(sweep_dir, metric: str) -> dict | None:
    """The best completed trial at ``metric`` of the study in ``sweep_dir`` (ties: the first),
    over every trial it holds, those of the searches it went on from included: ``value``,
    ``params``, ``number`` (in the study), ``sweep_dir`` and ``job`` (where it ran), ``here``
    (whether that is ``sweep_dir``) and ``n_trials`` (the study's finished trials).  None
    without a study, or when its values are not ``metric``'s."""
    sweep_dir = Path(sweep_dir)
    if not (sweep_dir / STUDY_FILE).is_file():
        return None
    try:
        study = read_study(sweep_dir)
    except ValueError as exc:
        log.warning("sweep report: %s", exc)
        return None
    better = METRICS[metric].better
    done = [t for t in study["trials"] if t["state"] == "COMPLETE" and t["values"]]
    if study["objective"] != metric or not better or not done:
        return None
    sign = 1 if better == "max" else -1
    best = max(done, key=lambda t: (sign * t["values"][0], -t["number"]))
    here = best["sweep_dir"] == study["sweep_dir"]
    return {"value": best["values"][0], "params": best["params"], "number": best["number"],
            "sweep_dir": best["sweep_dir"], "job": best["job"], "here": here,
            "n_trials": len(study["trials"])}


def _shown(rows, metric: str, fallback) -> str:
    """``metric``, or the first of ``fallback`` some row has a value for when none has one."""
    def held(name):
        return any(not math.isnan(number(r[name])) for r in rows)

    if held(metric):
        return metric
    return next((other for other in fallback if held(other)), metric)


def _write_summary(path: Path, columns: list[str], rows) -> Path:
    """Write ``rows`` as the CSV file ``path`` of ``columns`` (atomically); returns ``path``."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for r in rows:
        writer.writerow([_fmt(r[c]) for c in columns])
    atomic_write(path, lambda tmp: Path(tmp).write_text(buf.getvalue()))
    return path


def _fmt(v) -> str:
    """A CSV cell: "" for a missing value, the shortest exact text of a float."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


# ---------------------------------------------------------------------------------- the console
def _table(report: Report) -> str:
    """The metric as a text table over the two swept keys (or a column for one; the ten best
    jobs when they do not make a grid)."""
    rows, keys, metric = report.rows, report.keys, report.metric

    def cell(rs):
        if not rs or no_value(rs):
            return no_value(rs)
        value = mean([number(r[metric]) for r in rs])
        return "-" if math.isnan(value) else short(value)

    if len(keys) == 2 and not is_grid(rows, keys):  # a search: the jobs, best first
        done = sorted((r for r in rows if not math.isnan(number(r[metric]))),
                      key=lambda r: number(r[metric]), reverse=METRICS[metric].better != "min")
        lines = [["job", *keys, metric]] + [[str(r["job"]), *(str(r[k]) for k in keys),
                                             short(number(r[metric]))] for r in done[:10]]
        if len(done) > 10:
            lines.append(["...", *("" for _ in keys), f"{len(done) - 10} more"])
    elif len(keys) == 1:
        (key,) = keys
        lines = [[key, metric]] + [[x, cell([r for r in rows if str(r[key]) == x])]
                                   for x in axis_values(rows, key)]
    elif len(keys) == 2:
        ykey, xkey = keys
        xs = axis_values(rows, xkey)
        lines = [[f"{ykey} \\ {xkey}", *xs]]
        for y in axis_values(rows, ykey):
            lines.append([y, *(cell([r for r in rows if str(r[ykey]) == y and str(r[xkey]) == x])
                               for x in xs)])
    else:
        return ""
    widths = [max(len(line[c]) for line in lines) for c in range(len(lines[0]))]
    return "\n".join("  ".join(v.rjust(w) for v, w in zip(line, widths)) for line in lines)


def _best_line(report: Report) -> str | None:
    """The line naming the best job, or for a search that went on with earlier searches' trials
    the best of its whole study (which may be one of theirs)."""
    overall = report.study_best
    if overall is None and report.best is None:
        return None
    of_study = ""
    if overall is not None and overall["n_trials"] > len(report.rows):
        of_study = f", the best of the study's {overall['n_trials']} trials"
    if overall is not None:
        setting = " ".join(f"{k}={v}" for k, v in overall["params"].items())
    else:
        setting = " ".join(f"{k}={report.best[k]}" for k in report.keys)
    if overall is not None and not overall["here"]:
        return (f"topomap: best {report.metric}: {overall['value']:.4g} (trial "
                f"{overall['number']}{of_study}, an earlier search's: job {overall['job']} of "
                f"{overall['sweep_dir']}, {setting})")
    value = overall["value"] if overall is not None else number(report.best[report.metric])
    job = overall["job"] if overall is not None else report.best["job"]
    return f"topomap: best {report.metric}: {value:.4g} (job {job}: {setting}{of_study})"


def print_report(report: Report, file=None) -> None:
    """Print ``report``: the jobs by status, the metric as a table, the best job, the first
    failures and where the report is."""
    file = sys.stdout if file is None else file
    n, failed = len(report.rows), report.failed
    counts = {st: sum(r["status"] == st for r in failed)
              for st in ("interrupted", "incomplete", "not started")}
    print(f"topomap: sweep of {n} jobs, {n - len(failed)} completed, "
          f"{len(failed) - sum(counts.values())} failed" +
          "".join(f", {k} {st}" for st, k in counts.items() if k), file=file)
    table = _table(report)
    if table:
        print(f"{METRICS[report.metric].label}:\n{table}", file=file)
    best_line = _best_line(report)
    if best_line:
        print(best_line, file=file)
    listed = [r for r in failed if r["status"] != "not started"]
    for r in listed[:5]:
        print(f"topomap: job {r['job']} {r['status']}" + (f": {r['error']}" if r["error"] else ""),
              file=file)
    if len(listed) > 5:
        print(f"topomap: ... and {len(listed) - 5} more (see {report.summary.name})", file=file)
    print(f"topomap: report in {report.summary}" +
          (f" and {report.figure.name}" if report.figure else ""), file=file)
