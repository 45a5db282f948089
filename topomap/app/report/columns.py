"""The rows of a sweep's summary, and how the jobs of one swept setting make a cell.

Each numeric column of ``summary.csv`` is one :class:`~topomap.app.results.Column` of
:data:`~topomap.app.results.COLUMNS`: its name, where its value is in a job's ``metrics.json``
(or ``status.json``), its label and which way is better.  Everything else is derived from that
list: the CSV's columns and rows (:func:`header`, :func:`row`), the best job (:func:`best_row`),
the printed table's and the figures' labels.  To add a column, add a
:class:`~topomap.app.results.Column`.

A cell is the jobs of one swept value (or pair of values): its value is the mean over its
completed jobs (:func:`mean`), and a cell none of whose jobs completed says why
(:func:`no_value`).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..results import COLUMNS, METRICS, STATUS_FILE
from .jobs import Job

__all__ = ["header", "row", "best_row", "number", "mean", "axis_values", "cell_value", "no_value",
           "short"]


# ---------------------------------------------------------------------------------- rows
def header(keys) -> list[str]:
    """The columns of ``summary.csv`` for a sweep of ``keys``."""
    return ["job", *keys, "status", *METRICS, "error", "output_dir"]


def row(job: Job, keys, sweep_dir: Path) -> dict[str, Any]:
    """The summary's row of ``job`` (a value for each column of :func:`header`)."""
    return {"job": job.num, **{k: job.overrides.get(k, "") for k in keys}, "status": job.status,
            **{c.name: c.read(job.status_file if c.file == STATUS_FILE else job.metrics)
               for c in COLUMNS},
            "error": " ".join(str(job.error).split()) if job.error else "",
            "output_dir": job.path.relative_to(sweep_dir).as_posix()}


def best_row(rows, metric: str) -> dict | None:
    """The completed job best at ``metric`` (ties: the lowest job number); None when no job has
    a value or the column has no best."""
    better = METRICS[metric].better
    done = [r for r in rows if r["status"] == "completed" and not math.isnan(number(r[metric]))]
    if not better or not done:
        return None
    if better == "max":
        return max(done, key=lambda r: (number(r[metric]), -r["job"]))
    return min(done, key=lambda r: (number(r[metric]), r["job"]))


# ---------------------------------------------------------------------------------- cells
def number(value) -> float:
    """``value`` as a float; NaN for a missing or non-numeric value."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def mean(values) -> float:
    """Mean of the finite values (NaN if none): cells a sweep visits more than once."""
    vals = [v for v in values if not math.isnan(v)]
    return sum(vals) / len(vals) if vals else math.nan


def axis_values(rows, key) -> list[str]:
    """The values of ``key`` in ``rows`` (as text), in numeric order if all are numbers, else in
    the jobs' order."""
    values = list(dict.fromkeys(str(r[key]) for r in rows))
    if all(not math.isnan(number(v)) for v in values):
        values.sort(key=number)
    return values


def cell_value(rows, metric: str) -> float:
    """The mean of ``metric`` over the completed jobs of ``rows`` (NaN if none has a value)."""
    return mean([number(r[metric]) for r in rows if r["status"] == "completed"])


def no_value(rows) -> str:
    """Why a cell of jobs has no value: the statuses of its jobs ("failed", "incomplete") when
    none completed; "" when one did (or there are none)."""
    status = {r["status"] for r in rows}
    return "" if not rows or "completed" in status else "/".join(sorted(status))


def short(v: float) -> str:
    """A cell's value in a few characters."""
    return f"{v:.3f}" if abs(v) < 10 else f"{v:.2f}" if abs(v) < 100 else f"{v:.4g}"
