"""The columns of a sweep's summary, and how the jobs of one swept setting make a cell.

Each numeric column of ``summary.csv`` is one :class:`Column` of :data:`COLUMNS`: its name, where
its value is in a job's ``metrics.json`` (or ``status.json``), its label and which way is better.
Everything else is derived from that list: the CSV's columns and rows (:func:`header`,
:func:`row`), the best job (:func:`best_row`), the printed table's and the figures' labels.  To
add a column, add a :class:`Column`.

A cell is the jobs of one swept value (or pair of values): its value is the mean over its
completed jobs (:func:`mean`), and a cell none of whose jobs completed says why
(:func:`no_value`).
"""

from __future__ import annotations

import functools
import math
import operator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...core.checks import ParameterError
from ..run.experiment import STATUS_FILE
from .jobs import Job

__all__ = ["Column", "COLUMNS", "METRICS", "header", "row", "best_row", "check_metric"]


@dataclass(frozen=True)
class Column:
    """One numeric column of ``summary.csv``.

    name : str
        The column's name (the CSV header, ``--metric``, ``sweep_report.metric``).
    place : str or tuple of str
        Where the value is in the job's ``file``: keys joined by dots
        (``"ground_truth.final.ari"``); several places are summed (None unless all are there).
    label : str
        What the value is, with its unit: the printed table's and the figures' label.
    better : "max", "min" or None
        Which value is the best job's; None for a column no job is best at (the state counts).
    file : str
        ``metrics.json`` (written by a completed job) or ``status.json`` (by any job that ended).
    """

    name: str
    place: str | tuple[str, ...]
    label: str
    better: str | None = None
    file: str = "metrics.json"

    def value(self, job: Job) -> Any:
        """The column's value for ``job``: None where the job's file does not have it."""
        data = job.status_file if self.file == STATUS_FILE else job.metrics
        places = (self.place,) if isinstance(self.place, str) else self.place
        values = [_lookup(data, place) for place in places]
        if any(v is None for v in values):
            return None
        return values[0] if len(values) == 1 else functools.reduce(operator.add, values)


def _lookup(data: dict, place: str) -> Any:
    """``data[a][b]...`` for ``place`` ``"a.b..."``; None where a level is missing."""
    for key in place.split("."):
        if not isinstance(data, dict):
            return None
        data = data.get(key)
    return data


#: the numeric columns of ``summary.csv``, in its order
COLUMNS = (
    Column("n_states_phase1", "n_states.phase1", "states after phase 1"),
    Column("n_states", "n_states.final", "final states"),
    Column("ari", "ground_truth.final.ari", "final ARI", "max"),
    Column("nmi", "ground_truth.final.nmi", "final NMI", "max"),
    Column("purity", "ground_truth.final.purity", "final purity", "max"),
    Column("compound_states", "ground_truth.final.compound_states", "final compound states",
           "min"),
    Column("ari_phase1", "ground_truth.phase1.ari", "phase-1 ARI", "max"),
    Column("nmi_phase1", "ground_truth.phase1.nmi", "phase-1 NMI", "max"),
    Column("purity_phase1", "ground_truth.phase1.purity", "phase-1 purity", "max"),
    Column("H_o", "entropies.final.H_o", "H(o|x) [bits, differential]"),
    Column("H_u", "entropies.final.H_u", "H(u|x) [bits]", "min"),
    Column("H_x", "entropies.final.H_x", "H(x'|x,u) [bits]", "min"),
    Column("heldout_loglik", "heldout_loglik",
           "held-out log-likelihood per step [nats, a log-density]", "max"),
    Column("nav_success", "navigation.success_rate", "navigation success rate", "max"),
    Column("nav_path_ratio", "navigation.path_ratio", "navigation path length / shortest", "min"),
    Column("fit_time", ("timings.phase1", "timings.phase2"), "fit time [s]", "min"),
    Column("data_time", "timings.data", "data time [s]", "min"),
    Column("job_time", "job_time", "job time [s]", "min", file=STATUS_FILE),
)
#: the columns by name
METRICS = {c.name: c for c in COLUMNS}


def check_metric(metric: str, param: str = "metric") -> Column:
    """The column named ``metric``; a :class:`ParameterError` naming ``param`` if none is."""
    if metric not in METRICS:
        raise ParameterError(param, f"={metric!r} is not a summary column; choose one of "
                                    f"{', '.join(METRICS)}")
    return METRICS[metric]


# ---------------------------------------------------------------------------------- rows
def header(keys) -> list[str]:
    """The columns of ``summary.csv`` for a sweep of ``keys``."""
    return ["job", *keys, "status", *METRICS, "error", "output_dir"]


def row(job: Job, keys, sweep_dir: Path) -> dict[str, Any]:
    """The summary's row of ``job`` (a value for each column of :func:`header`)."""
    return {"job": job.num, **{k: job.overrides.get(k, "") for k in keys}, "status": job.status,
            **{c.name: c.value(job) for c in COLUMNS},
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
