"""Figures of a sweep: one summary column over the swept values (matplotlib, Agg backend, PNG).

A line over one swept key (:func:`plot_sweep_line`), a heat map over two
(:func:`plot_sweep_heat_map`), or a scatter of the jobs when their values do not make a grid (a
search such as Optuna's picks its own, :func:`plot_sweep_scatter`); :func:`write_sweep_figure` writes ``summary_<metric>.png``.  As
for the run figures (:mod:`topomap.app.plots`), every ``plot_*`` function draws on the Axes (or
Figure) it is given and returns it, and the style is theirs: the palette's first colour for the
values, its red for the best job and for values no job completed, the same font sizes, PNG files
written by :func:`~topomap.app.plots.save_figure`.  A value's label is its summary column's
(:data:`topomap.app.results.METRICS`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plots.style import LEGEND_SIZE, PALETTE, TITLE_SIZE, pyplot, save_figure
from ..results import METRICS
from .columns import axis_values, cell_value, no_value, number, short

__all__ = ["write_sweep_figure", "plot_sweep_line", "plot_sweep_heat_map", "plot_sweep_scatter",
           "is_grid"]

#: the colour of the values, and of the best job and of the values that no job completed
VALUE, ALERT = PALETTE[0], PALETTE[3]


def write_sweep_figure(path: Path, rows, keys, metric: str, best=None) -> None:
    """``summary_<metric>.png``: ``metric`` over one swept key (a line) or two (a heat map, or a
    scatter of the jobs when their values do not make a grid, see :func:`is_grid`);
    ``rows`` are the summary's, ``best`` the best job's row (ringed or outlined)."""
    plt = pyplot()
    counts = {st: sum(r["status"] == st for r in rows)
              for st in ("failed", "interrupted", "incomplete", "not started")}
    note = ", ".join([f"{len(rows)} jobs", *(f"{n} {st}" for st, n in counts.items() if n)])
    title = f"{METRICS[metric].label} ({note})"
    if len(keys) == 1:
        n = len(axis_values(rows, keys[0]))
        fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * n + 2.0), 3.2))
        plot_sweep_line(ax, rows, keys[0], metric, title, best)
    elif not is_grid(rows, keys):
        fig = plt.figure(figsize=(6.4, 4.6))
        plot_sweep_scatter(fig, rows, keys, metric, title, best)
    else:
        ys, xs = (axis_values(rows, k) for k in keys)
        fig = plt.figure(figsize=(1.6 + 0.75 * len(xs) + 1.2, 1.3 + 0.5 * len(ys)))
        plot_sweep_heat_map(fig, rows, keys, metric, title, best)
    save_figure(fig, path)


def plot_sweep_line(ax, rows, key, metric, title, best=None):
    """``metric`` over one swept ``key``: the mean of the completed jobs of each value as a line
    (broken where a value is missing), the best job ringed in red; a value whose jobs all failed
    (or are incomplete) as a hatched red band across the plot, labelled, with a red tick and no
    point.  Returns ``ax``."""
    xs = axis_values(rows, key)
    vals = np.array([cell_value([r for r in rows if str(r[key]) == x], metric) for x in xs])
    numeric = all(not np.isnan(number(x)) for x in xs)
    pos = np.array([number(x) for x in xs]) if numeric else np.arange(len(xs), dtype=float)
    handles = ax.plot(pos, vals, "o-", color=VALUE, ms=4, label="completed jobs (mean)")
    if best is not None:
        i = xs.index(str(best[key]))
        handles += ax.plot(pos[i], vals[i], "o", ms=11, mfc="none", mec=ALERT, mew=1.5,
                           label=f"best: {key}={best[key]}")
    half = 0.3 * (np.diff(np.sort(pos)).min() if len(pos) > 1 else 1.0)
    handles += _no_value_bands(ax, rows, key, xs, pos, half)
    ax.set_xlim(pos.min() - 2 * half, pos.max() + 2 * half)
    ax.legend(handles=handles, fontsize=LEGEND_SIZE, loc="upper left", bbox_to_anchor=(1.01, 1.0),
              frameon=False)
    ax.set_xlabel(key)
    ax.set_ylabel(METRICS[metric].label)
    ax.set_title(title, fontsize=TITLE_SIZE)
    ax.grid(alpha=0.3)
    return ax


def _no_value_bands(ax, rows, key, xs, pos, half) -> list:
    """Mark the values ``xs`` (at ``pos``) of ``key`` that no job completed: a hatched red band
    ``2 * half`` wide saying why, and a red tick label.  Sets the ticks; returns the legend's
    handle for the bands ([] when every value has a completed job)."""
    from matplotlib.patches import Patch

    band = dict(fc=ALERT, alpha=0.12, hatch="///", ec=ALERT, lw=0)
    states, missing = set(), []
    for i, x in enumerate(xs):
        why = no_value([r for r in rows if str(r[key]) == x])
        if not why:
            continue
        states |= set(why.split("/"))
        ax.axvspan(pos[i] - half, pos[i] + half, **band)
        ax.annotate(f"{why}: no value", (pos[i], 0.5), xycoords=("data", "axes fraction"),
                    rotation=90, ha="center", va="center", fontsize=LEGEND_SIZE, color=ALERT)
        missing.append(i)
    ax.set_xticks(pos, xs)
    for i in missing:
        ax.get_xticklabels()[i].set_color(ALERT)
    return [Patch(**band, label=f"{'/'.join(sorted(states))} jobs")] if states else []


def _grid(rows, keys, metric):
    """``metric``'s mean per (y, x) cell over completed jobs, and why a cell has no value."""
    (ykey, xkey), (ys, xs) = keys, [axis_values(rows, k) for k in keys]
    grid = np.full((len(ys), len(xs)), np.nan)
    why = np.full(grid.shape, "", dtype=object)
    for i, y in enumerate(ys):
        for j, x in enumerate(xs):
            cell = [r for r in rows if str(r[ykey]) == y and str(r[xkey]) == x]
            grid[i, j] = cell_value(cell, metric)
            why[i, j] = no_value(cell)
    return ys, xs, grid, why


def plot_sweep_heat_map(fig, rows, keys, metric, title, best=None):
    """``metric`` over two swept ``keys`` (y, x) on a new Axes of ``fig``: one cell per pair of
    values with its value written in it, cells without a completed job grey and marked "failed"
    or "incomplete", the best cell outlined in red.  Returns the Axes."""
    import matplotlib
    from matplotlib.patches import Rectangle

    (ykey, xkey), (ys, xs, grid, why) = keys, _grid(rows, keys, metric)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="0.88")
    im = ax.imshow(np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=cmap)
    fig.colorbar(im, ax=ax, label=METRICS[metric].label)
    finite = grid[np.isfinite(grid)]
    mid = (finite.min() + finite.max()) / 2 if finite.size else 0.0
    for (i, j), value in np.ndenumerate(grid):
        if why[i, j]:
            ax.text(j, i, why[i, j], ha="center", va="center", fontsize=LEGEND_SIZE, color="0.35")
        elif np.isfinite(value):
            ax.text(j, i, short(value), ha="center", va="center", fontsize=LEGEND_SIZE,
                    color="white" if value < mid else "black")
    if best is not None:
        i, j = ys.index(str(best[ykey])), xs.index(str(best[xkey]))
        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=2, ec=ALERT))
        title += f"\nbest (red): {ykey}={best[ykey]}, {xkey}={best[xkey]}"
    ax.set_xticks(range(len(xs)), xs)
    ax.set_yticks(range(len(ys)), ys)
    ax.set_xlabel(xkey)
    ax.set_ylabel(ykey)
    ax.set_title(title, fontsize=TITLE_SIZE)
    return ax


def is_grid(rows, keys) -> bool:
    """Whether the jobs' values of two swept ``keys`` make a grid: a job for at least half the
    pairs of values (a grid sweep has one for every pair; a search picks a few scattered ones)."""
    pairs = {tuple(str(r[k]) for k in keys) for r in rows}
    cells = np.prod([len(axis_values(rows, k)) for k in keys])
    return 2 * len(pairs) >= cells


def plot_sweep_scatter(fig, rows, keys, metric, title, best=None):
    """``metric`` over two swept ``keys`` (y, x) when the jobs do not make a grid: one point per
    completed job at its values, coloured by ``metric``, numbered by job, and a red cross for each
    job that did not complete; the best job ringed in red.  Returns the Axes."""
    (ykey, xkey) = keys
    ax = fig.add_subplot()
    done = [r for r in rows if r["status"] == "completed" and np.isfinite(number(r[metric]))]
    lost = [r for r in rows if r not in done]

    def xy(rs):
        return (np.array([number(r[xkey]) for r in rs]), np.array([number(r[ykey]) for r in rs]))

    handles = []
    if done:
        x, y = xy(done)
        pts = ax.scatter(x, y, c=[number(r[metric]) for r in done], cmap="viridis", s=36,
                         edgecolors="0.3", lw=0.5, zorder=3, label="completed job (number)")
        fig.colorbar(pts, ax=ax, label=METRICS[metric].label)
        handles.append(pts)
        for r, xi, yi in zip(done, x, y):
            ax.annotate(str(r["job"]), (xi, yi), xytext=(3, 3), textcoords="offset points",
                        fontsize=6, color="0.3")
    if lost:
        x, y = xy(lost)
        handles.append(ax.scatter(x, y, marker="x", color=ALERT, s=28, lw=1.2, zorder=3,
                                  label="failed or incomplete job"))
    if best is not None:
        handles += ax.plot(number(best[xkey]), number(best[ykey]), "o", ms=13, mfc="none",
                           mec=ALERT, mew=1.5, zorder=4,
                           label=f"best: {ykey}={best[ykey]}, {xkey}={best[xkey]}")
    ax.legend(handles=handles, fontsize=LEGEND_SIZE, loc="upper center",
              bbox_to_anchor=(0.5, -0.14), frameon=False, ncol=2)
    ax.set_xlabel(xkey)
    ax.set_ylabel(ykey)
    ax.set_title(title, fontsize=TITLE_SIZE)
    ax.grid(alpha=0.3)
    return ax
