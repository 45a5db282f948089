"""The sweep report: the table that compares the jobs of ``topomap -m ...``.

Every job of a sweep (any Hydra launcher: the basic one, ``joblib``, ``submitit_local`` or
``submitit_slurm``) runs :func:`topomap.app.experiment.run_job`, which learns from the trajectory
cached in ``<sweep dir>/.cache/`` and writes ``status.json`` into its folder: ``completed``, or
``failed`` with the error (the job then returns normally, so the sweep goes on and Hydra still ends
it with the report).

When the multirun ends, the :class:`SweepReport` callback (registered in ``conf/config.yaml`` as
``hydra.callbacks.sweep_report``) reads every job's folder and writes into the sweep folder

* ``summary.csv``: one row per job (swept values, status, states, ARI/NMI/purity, entropies,
  held-out log-likelihood, times, error), and
* ``summary_<metric>.png``: the metric over the swept values (a heat map for two swept keys, a
  line for one; no figure otherwise).

The report can be rebuilt at any time, e.g. for another metric or after an interrupted sweep::

    python -m topomap.app.sweep outputs/sweeps/2026-01-01/12-00-00-000000 --metric heldout_loglik
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import logging
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

from ..core.data.files import atomic_write
from .experiment import CACHE_DIR, STATUS_FILE

log = logging.getLogger("topomap")

__all__ = ["SweepReport", "write_report", "read_jobs", "swept_keys", "METRICS", "SUMMARY_FILE"]

SUMMARY_FILE = "summary.csv"

#: numeric summary columns: (label, which value is best: "max", "min" or None)
METRICS = {
    "n_states_phase1": ("states after phase 1", None),
    "n_states": ("final states", None),
    "ari": ("final ARI", "max"),
    "nmi": ("final NMI", "max"),
    "purity": ("final purity", "max"),
    "compound_states": ("final compound states", "min"),
    "ari_phase1": ("phase-1 ARI", "max"),
    "nmi_phase1": ("phase-1 NMI", "max"),
    "purity_phase1": ("phase-1 purity", "max"),
    "H_o": ("H(o|x) [bits, differential]", None),
    "H_u": ("H(u|x) [bits]", "min"),
    "H_x": ("H(x'|x,u) [bits]", "min"),
    "heldout_loglik": ("held-out log-likelihood per step [nats, a log-density]", "max"),
    "nav_success": ("navigation success rate", "max"),
    "nav_path_ratio": ("navigation path length / shortest", "min"),
    "fit_time": ("fit time [s]", "min"),
    "data_time": ("data time [s]", "min"),
    "job_time": ("job time [s]", "min"),
}


# ---------------------------------------------------------------------------------- reading a sweep
@dataclass
class Job:
    """What one job folder of a sweep holds."""

    num: int
    path: Path
    overrides: dict[str, str]
    status: str
    error: str | None = None
    metrics: dict = field(default_factory=dict)
    job_time: float | None = None


def _key_value(override: str) -> tuple[str, str]:
    key, _, value = str(override).partition("=")
    return key.lstrip("+~"), value


def _job_num(path: Path, fallback: int) -> int:
    from omegaconf import OmegaConf

    try:
        return int(OmegaConf.load(path / ".hydra" / "hydra.yaml").hydra.job.num)
    except Exception:
        try:
            return int(path.name)
        except ValueError:
            return fallback


def read_jobs(sweep_dir) -> list[Job]:
    """Every job folder under ``sweep_dir`` (a folder holding ``.hydra/``), by job number.

    A job's status is that of its ``status.json``; without one it is ``completed`` if it wrote
    ``metrics.json`` and ``incomplete`` otherwise (still running, killed or lost).  Reading never
    fails on what a crash or a kill leaves behind: a ``.hydra`` folder without ``overrides.yaml``,
    a truncated ``status.json`` or ``metrics.json``; the job's error says what is wrong, and a job
    without a readable ``metrics.json`` is never ``completed``.
    """
    sweep_dir = Path(sweep_dir)
    jobs = []
    for i, hydra_dir in enumerate(sorted(sweep_dir.rglob(".hydra"))):
        path = hydra_dir.parent
        if hydra_dir.is_dir() and CACHE_DIR not in path.relative_to(sweep_dir).parts:
            jobs.append(_read_job(path, i))
    return sorted(jobs, key=lambda j: j.num)


def _read_job(path: Path, index: int) -> Job:
    """The job in folder ``path`` (``index``: its number if Hydra's files do not tell)."""
    problems: list[str] = []
    overrides = _read_overrides(path, problems)
    status = _read_json(path / STATUS_FILE, problems)
    metrics = _read_json(path / "metrics.json", problems)
    state = status.get("status")
    if state is None:  # no status.json: the job ended (or was stopped) before writing it
        state = "completed" if metrics else "incomplete"
        if not (path / STATUS_FILE).exists() and not (path / "metrics.json").exists():
            problems.append(f"no {STATUS_FILE} or metrics.json: the job is still running, or "
                            "was killed or lost")
    elif state not in ("completed", "failed"):
        problems.append(f"{STATUS_FILE} gives the unknown status {state!r}")
        state = "incomplete"
    if state == "completed" and not metrics:
        state = "incomplete"
        if not (path / "metrics.json").is_file():
            problems.append("metrics.json is missing")
    errors = [str(status["error"])] if status.get("error") else []
    return Job(num=_job_num(path, index), path=path, overrides=overrides, status=state,
               error="; ".join(errors + problems) or None,
               metrics=metrics if state == "completed" else {}, job_time=status.get("job_time"))


def _read_overrides(path: Path, problems: list[str]) -> dict[str, str]:
    """The job's ``.hydra/overrides.yaml`` as ``{key: value}``; ``{}`` (and a note in
    ``problems``) when it is missing or unreadable."""
    from omegaconf import OmegaConf

    file = path / ".hydra" / "overrides.yaml"
    if not file.is_file():
        problems.append(f"{file.relative_to(path)} is missing")
        return {}
    try:
        overrides = OmegaConf.to_container(OmegaConf.load(file))
        if not isinstance(overrides, list):
            raise ValueError("it is not a list of overrides")
        return dict(_key_value(o) for o in overrides)
    except Exception as exc:  # a YAML or OmegaConf error: the file was cut short
        problems.append(f"{file.relative_to(path)} is unreadable ({_one_line(exc)})")
        return {}


def _read_json(path: Path, problems: list[str]) -> dict:
    """The JSON object in ``path``; ``{}`` when there is no such file, and also (with a note in
    ``problems``) when it is unreadable, e.g. cut short by a kill."""
    if not path.is_file():
        return {}
    try:
        value = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        problems.append(f"{path.name} is unreadable ({_one_line(exc)})")
        return {}
    if not isinstance(value, dict):
        problems.append(f"{path.name} does not hold a JSON object")
        return {}
    return value


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line, cut to 120 characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 120 else text[:117] + "..."


def _sweep_overrides(multirun_cfg) -> list[str]:
    """The task overrides of a multirun config and its sweeper's ``params``, as ``key=value``."""
    from omegaconf import OmegaConf

    if multirun_cfg is None:
        return []
    task = OmegaConf.select(multirun_cfg, "hydra.overrides.task", default=None)
    params = OmegaConf.select(multirun_cfg, "hydra.sweeper.params", default=None)
    out = [str(o) for o in (OmegaConf.to_container(task) if task is not None else [])]
    if params is not None:
        out += [f"{k}={v}" for k, v in OmegaConf.to_container(params).items()]
    return out


def swept_keys(multirun_cfg=None, jobs=()) -> list[str]:
    """The keys a sweep varies: the sweep overrides of ``multirun_cfg`` (``a=1,2``,
    ``range(...)``, ``choice(...)``, sweeper ``params``) plus every key whose value differs
    between ``jobs``; ordered as in the first job's overrides."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    keys: list[str] = []
    parser = OverridesParser.create()
    for text in _sweep_overrides(multirun_cfg):
        try:
            (override,) = parser.parse_overrides([text])
        except Exception:  # a sweeper-specific syntax: the job values below still find it
            continue
        if override.is_sweep_override() and override.key_or_group not in keys:
            keys.append(override.key_or_group)
    for job in jobs:
        for key, value in job.overrides.items():
            if key not in keys and any(j.overrides.get(key) != value for j in jobs):
                keys.append(key)
    order = list(jobs[0].overrides) if jobs else []
    return sorted(keys, key=lambda k: (order.index(k) if k in order else len(order), keys.index(k)))


def _row(job: Job, keys, sweep_dir: Path) -> dict[str, Any]:
    m = job.metrics
    gt = m.get("ground_truth") or {}
    fin, p1 = gt.get("final") or {}, gt.get("phase1") or {}
    ent = (m.get("entropies") or {}).get("final") or {}
    t = m.get("timings") or {}
    n = m.get("n_states") or {}
    fit = t.get("phase1", 0.0) + t.get("phase2", 0.0) if "phase1" in t else None
    row = {"job": job.num, **{k: job.overrides.get(k, "") for k in keys}, "status": job.status,
           "n_states_phase1": n.get("phase1"), "n_states": n.get("final"),
           "ari": fin.get("ari"), "nmi": fin.get("nmi"), "purity": fin.get("purity"),
           "compound_states": fin.get("compound_states"),
           "ari_phase1": p1.get("ari"), "nmi_phase1": p1.get("nmi"),
           "purity_phase1": p1.get("purity"),
           "H_o": ent.get("H_o"), "H_u": ent.get("H_u"), "H_x": ent.get("H_x"),
           "heldout_loglik": m.get("heldout_loglik"), "fit_time": fit,
           "nav_success": (m.get("navigation") or {}).get("success_rate"),
           "nav_path_ratio": (m.get("navigation") or {}).get("path_ratio"),
           "data_time": t.get("data"), "job_time": job.job_time,
           "error": " ".join(str(job.error).split()) if job.error else "",
           "output_dir": job.path.relative_to(sweep_dir).as_posix()}
    return row


# ---------------------------------------------------------------------------------- the report
@dataclass
class Report:
    """What :func:`write_report` wrote and found."""

    summary: Path
    figure: Path | None
    keys: list[str]
    rows: list[dict]
    metric: str
    best: dict | None

    @property
    def failed(self) -> list[dict]:
        """Rows of jobs that did not complete (``failed`` or ``incomplete``)."""
        return [r for r in self.rows if r["status"] != "completed"]


def _number(value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return math.nan
    return v


def _mean(values) -> float:
    """Mean of the finite values (NaN if none): cells a sweep visits more than once."""
    vals = [v for v in values if not math.isnan(v)]
    return sum(vals) / len(vals) if vals else math.nan


def _axis(rows, key) -> list[str]:
    values = list(dict.fromkeys(str(r[key]) for r in rows))
    if all(not math.isnan(_number(v)) for v in values):
        values.sort(key=_number)
    return values


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def _short(v: float) -> str:
    return f"{v:.3f}" if abs(v) < 10 else f"{v:.2f}" if abs(v) < 100 else f"{v:.4g}"


def _best(rows, metric) -> dict | None:
    better = METRICS[metric][1]
    done = [r for r in rows if r["status"] == "completed" and not math.isnan(_number(r[metric]))]
    if not better or not done:
        return None
    if better == "max":  # ties: the lowest job number
        return max(done, key=lambda r: (_number(r[metric]), -r["job"]))
    return min(done, key=lambda r: (_number(r[metric]), r["job"]))


def write_report(sweep_dir, *, metric: str = "ari", figure: bool = True,
                 multirun_cfg=None) -> Report:
    """Write ``summary.csv`` (and ``summary_<metric>.png``) for the sweep in ``sweep_dir``.

    ``multirun_cfg`` (the multirun config; by default ``sweep_dir/multirun.yaml``) names the swept
    keys.  Returns a :class:`Report`.
    """
    if metric not in METRICS:
        raise ValueError(f"metric={metric!r} is not a summary column; choose one of "
                         f"{', '.join(METRICS)}")
    sweep_dir = Path(sweep_dir)
    if multirun_cfg is None and (sweep_dir / "multirun.yaml").is_file():
        from omegaconf import OmegaConf

        multirun_cfg = OmegaConf.load(sweep_dir / "multirun.yaml")
    jobs = read_jobs(sweep_dir)
    keys = swept_keys(multirun_cfg, jobs)
    rows = [_row(j, keys, sweep_dir) for j in jobs]
    columns = ["job", *keys, "status", *METRICS, "error", "output_dir"]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for r in rows:
        writer.writerow([_fmt(r[c]) for c in columns])
    summary = sweep_dir / SUMMARY_FILE
    atomic_write(summary, lambda tmp: Path(tmp).write_text(buf.getvalue()))
    best = _best(rows, metric)
    fig_path = None
    if figure and rows and 1 <= len(keys) <= 2:
        if all(math.isnan(_number(r[metric])) for r in rows):
            log.warning("sweep report: no job has a value for %s; no figure", metric)
        else:
            fig_path = sweep_dir / f"summary_{metric}.png"
            _plot(fig_path, rows, keys, metric, best)
    elif figure and rows:
        log.info("sweep report: %d swept keys, so no figure (one or two make a line or a heat map)",
                 len(keys))
    return Report(summary=summary, figure=fig_path, keys=keys, rows=rows, metric=metric, best=best)


def _plot(path: Path, rows, keys, metric, best) -> None:
    """``summary_<metric>.png``: a line over one swept key, a heat map over two."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    label = METRICS[metric][0]
    counts = {st: sum(r["status"] == st for r in rows) for st in ("failed", "incomplete")}
    note = ", ".join([f"{len(rows)} jobs", *(f"{n} {st}" for st, n in counts.items() if n)])
    if len(keys) == 1:
        n = len(_axis(rows, keys[0]))
        fig = Figure(figsize=(max(4.0, 0.6 * n + 2.0) + 1.8, 3.2), dpi=100)
        _line(fig.add_subplot(), rows, keys[0], metric, f"{label} ({note})", best)
    else:
        ys, xs = (_axis(rows, k) for k in keys)
        fig = Figure(figsize=(1.6 + 0.75 * len(xs) + 1.2, 1.3 + 0.5 * len(ys)), dpi=100)
        _heat_map(fig, rows, keys, metric, f"{label} ({note})", best)
    FigureCanvasAgg(fig)
    fig.tight_layout()
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))


def _line(ax, rows, key, metric, title, best=None) -> None:
    """The metric over one swept key: completed jobs as a line (broken where a value is
    missing), the best one ringed in red; a value of ``key`` whose jobs all failed (or are
    incomplete) as a hatched red band across the plot, labelled, with no point."""
    import numpy as np
    from matplotlib.patches import Patch

    xs = _axis(rows, key)
    vals = np.array([_mean([_number(r[metric]) for r in rows if str(r[key]) == x
                            and r["status"] == "completed"]) for x in xs])
    numeric = all(not math.isnan(_number(x)) for x in xs)
    pos = np.array([_number(x) for x in xs]) if numeric else np.arange(len(xs), dtype=float)
    handles = ax.plot(pos, vals, "o-", label="completed jobs (mean)")
    if best is not None:
        i = xs.index(str(best[key]))
        handles += ax.plot(pos[i], vals[i], "o", ms=11, mfc="none", mec="tab:red", mew=1.5,
                           label=f"best: {key}={best[key]}")
    half = 0.3 * (np.diff(np.sort(pos)).min() if len(pos) > 1 else 1.0)
    states, failed = set(), []
    for i, x in enumerate(xs):
        status = {r["status"] for r in rows if str(r[key]) == x}
        if "completed" in status:
            continue
        states |= status
        ax.axvspan(pos[i] - half, pos[i] + half, fc="tab:red", alpha=0.12, hatch="///",
                   ec="tab:red", lw=0)
        ax.annotate(f"{'/'.join(sorted(status))}: no value", (pos[i], 0.5),
                    xycoords=("data", "axes fraction"), rotation=90, ha="center", va="center",
                    fontsize=8, color="tab:red")
        failed.append(i)
    if states:
        handles.append(Patch(fc="tab:red", alpha=0.12, hatch="///", ec="tab:red", lw=0,
                             label=f"{'/'.join(sorted(states))} jobs"))
    ax.set_xticks(pos, xs)
    for i in failed:
        ax.get_xticklabels()[i].set_color("tab:red")
    ax.set_xlim(pos.min() - 2 * half, pos.max() + 2 * half)
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False)
    ax.set_xlabel(key)
    ax.set_ylabel(METRICS[metric][0])
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)


def _no_value(rows) -> str:
    """Why a cell of jobs has no value: the statuses of its jobs ("failed", "incomplete") when
    none completed; "" when one did (or there are none)."""
    status = {r["status"] for r in rows}
    return "" if not rows or "completed" in status else "/".join(sorted(status))


def _grid(rows, keys, metric):
    """The metric's mean per (y, x) cell over completed jobs, and why a cell has no value."""
    import numpy as np

    (ykey, xkey), (ys, xs) = keys, [_axis(rows, k) for k in keys]
    grid = np.full((len(ys), len(xs)), np.nan)
    why = np.full(grid.shape, "", dtype=object)
    for i, y in enumerate(ys):
        for j, x in enumerate(xs):
            cell = [r for r in rows if str(r[ykey]) == y and str(r[xkey]) == x]
            grid[i, j] = _mean([_number(r[metric]) for r in cell if r["status"] == "completed"])
            why[i, j] = _no_value(cell)
    return ys, xs, grid, why


def _heat_map(fig, rows, keys, metric, title, best) -> None:
    """The metric over two swept keys: one cell per pair of values with its value written in it,
    cells without a completed job grey and marked "failed" or "incomplete", the best cell
    outlined in red."""
    import matplotlib
    import numpy as np
    from matplotlib.patches import Rectangle

    (ykey, xkey), (ys, xs, grid, why) = keys, _grid(rows, keys, metric)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="0.88")
    im = ax.imshow(np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=cmap)
    fig.colorbar(im, ax=ax, label=METRICS[metric][0])
    finite = grid[np.isfinite(grid)]
    mid = (finite.min() + finite.max()) / 2 if finite.size else 0.0
    for (i, j), value in np.ndenumerate(grid):
        if why[i, j]:
            ax.text(j, i, why[i, j], ha="center", va="center", fontsize=7, color="0.35")
        elif np.isfinite(value):
            ax.text(j, i, _short(value), ha="center", va="center", fontsize=7,
                    color="white" if value < mid else "black")
    if best is not None:
        i, j = ys.index(str(best[ykey])), xs.index(str(best[xkey]))
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=2, ec="tab:red"))
        title += f"\nbest (red): {ykey}={best[ykey]}, {xkey}={best[xkey]}"
    ax.set_xticks(range(len(xs)), xs)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlabel(xkey)
    ax.set_ylabel(ykey)
    ax.set_title(title, fontsize=9)


def _table(report: Report) -> str:
    """The metric as a text table over the two swept keys (or a column for one)."""
    rows, keys, metric = report.rows, report.keys, report.metric

    def cell(rs):
        if not rs or _no_value(rs):
            return _no_value(rs)
        value = _mean([_number(r[metric]) for r in rs])
        return "-" if math.isnan(value) else _short(value)

    if len(keys) == 1:
        (key,) = keys
        lines = [[key, metric]] + [[x, cell([r for r in rows if str(r[key]) == x])]
                                   for x in _axis(rows, key)]
    elif len(keys) == 2:
        ykey, xkey = keys
        xs = _axis(rows, xkey)
        lines = [[f"{ykey} \\ {xkey}", *xs]]
        for y in _axis(rows, ykey):
            lines.append([y, *(cell([r for r in rows if str(r[ykey]) == y and str(r[xkey]) == x])
                               for x in xs)])
    else:
        return ""
    widths = [max(len(line[c]) for line in lines) for c in range(len(lines[0]))]
    return "\n".join("  ".join(v.rjust(w) for v, w in zip(line, widths)) for line in lines)


def _print_report(report: Report, file=None) -> None:
    file = sys.stdout if file is None else file
    n, failed = len(report.rows), report.failed
    n_incomplete = sum(r["status"] == "incomplete" for r in failed)
    print(f"topomap: sweep of {n} jobs, {n - len(failed)} completed, "
          f"{len(failed) - n_incomplete} failed" +
          (f", {n_incomplete} incomplete" if n_incomplete else ""), file=file)
    table = _table(report)
    if table:
        print(f"{METRICS[report.metric][0]}:\n{table}", file=file)
    if report.best is not None:
        setting = " ".join(f"{k}={report.best[k]}" for k in report.keys)
        print(f"topomap: best {report.metric}: {_number(report.best[report.metric]):.4g} "
              f"(job {report.best['job']}: {setting})", file=file)
    for r in failed[:5]:
        print(f"topomap: job {r['job']} {r['status']}: {r['error']}", file=file)
    if len(failed) > 5:
        print(f"topomap: ... and {len(failed) - 5} more (see {report.summary.name})", file=file)
    print(f"topomap: report in {report.summary}" +
          (f" and {report.figure.name}" if report.figure else ""), file=file)


class SweepReport(Callback):
    """Hydra callback: write the sweep report when a multirun ends.

    Parameters (``hydra.callbacks.sweep_report.<name>=...``)
    ---------------------------------------------------------
    metric : str
        Summary column shown in the figure and the printed table (default ``ari``, the final ARI);
        one of :data:`METRICS`.
    figure : bool
        Write ``summary_<metric>.png``.
    strict : bool
        Exit with status 1 after writing the report if any job failed (default: failed jobs are
        rows of the report and the command succeeds).
    """

    def __init__(self, metric: str = "ari", figure: bool = True, strict: bool = False):
        if metric not in METRICS:
            raise ValueError(f"hydra.callbacks.sweep_report.metric={metric!r} is not a summary "
                             f"column; choose one of {', '.join(METRICS)}")
        self.metric, self.figure, self.strict = metric, bool(figure), bool(strict)

    def on_multirun_end(self, config, **kwargs) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        report = write_report(sweep_dir, metric=self.metric, figure=self.figure,
                              multirun_cfg=config)
        _print_report(report)
        if report.failed:
            log.warning("%d of %d jobs did not complete; their errors are in %s",
                        len(report.failed), len(report.rows), report.summary)
            if self.strict:
                sys.exit(f"topomap: error: {len(report.failed)} of {len(report.rows)} jobs "
                         f"did not complete; see {report.summary}")


def main(argv=None) -> int:
    """``python -m topomap.app.sweep SWEEP_DIR [--metric M] [--no-figure]``: rebuild a sweep report."""
    parser = argparse.ArgumentParser(prog="python -m topomap.app.sweep", description=main.__doc__)
    parser.add_argument("sweep_dir", type=Path)
    parser.add_argument("--metric", default="ari", choices=list(METRICS))
    parser.add_argument("--no-figure", dest="figure", action="store_false")
    args = parser.parse_args(argv)
    if not args.sweep_dir.is_dir():
        parser.error(f"{args.sweep_dir} is not a folder")
    report = write_report(args.sweep_dir, metric=args.metric, figure=args.figure)
    if not report.rows:
        print(f"topomap: error: no job folders (holding .hydra/) under {args.sweep_dir}",
              file=sys.stderr)
        return 1
    _print_report(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
