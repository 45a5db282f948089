"""Numbers and nodes kept readable: points too close to tell apart are pushed apart first.

:func:`spread` keeps round things (the map's nodes) a distance apart; :func:`spread_boxes` keeps
boxes (the states' numbers, wider than they are tall, and wider for more digits) from
overlapping; :func:`write_numbers` writes the states' numbers, spread so, in bold with a white
outline.  Both work in the Axes' own units, converted from typographic points by
:func:`data_per_point`.
"""

from __future__ import annotations

import numpy as np

from .style import HALO

__all__ = ["data_per_point", "close_pairs", "spread", "spread_boxes", "write_numbers",
           "number_box"]

#: a digit's width and a number's height, as fractions of the font size (DejaVu Sans Bold)
DIGIT_WIDTH, NUMBER_HEIGHT = 0.72, 0.9


def data_per_point(ax) -> np.ndarray:
    """Data units per typographic point along x and along y (the Axes' aspect applied)."""
    ax.apply_aspect()
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    points = np.array([ax.bbox.width, ax.bbox.height]) * 72.0 / ax.figure.dpi
    return np.array([abs(x1 - x0), abs(y1 - y0)]) / np.maximum(points, 1e-9)


def close_pairs(Q, d) -> np.ndarray:
    """``(k, 2)`` indices of the points of ``Q`` closer than ``d`` along x, and than ``d`` (a
    number) or ``d[1]`` (a pair: a box) along y and in all (a sweep along x, so that thousands of
    points cost little)."""
    dx, dy = (d, d) if np.ndim(d) == 0 else d
    order = np.argsort(Q[:, 0], kind="stable")
    R = Q[order]
    found = [np.empty((0, 2), dtype=int)]
    for k in range(1, len(R)):
        i = np.flatnonzero(R[k:, 0] - R[:-k, 0] < dx)
        if not i.size:
            break
        gap = np.abs(R[i + k] - R[i])
        near = (np.hypot(*gap.T) < dx) if np.ndim(d) == 0 else (gap[:, 1] < dy)
        found.append(np.column_stack([order[i[near]], order[i[near] + k]]))
    return np.concatenate(found)


def _start(P, scale) -> np.ndarray:
    """``P`` nudged by a thousandth of ``scale`` in a different direction for each point (the
    golden angle), so that coincident points leave in fixed directions."""
    angle = np.arange(len(P)) * 2.399963
    return P + 1e-3 * np.asarray(scale) * np.column_stack([np.cos(angle), np.sin(angle)])


def spread(P, d, iters=40):
    """``P`` with points closer than ``d`` pushed apart (deterministic), so that nodes at one
    position stay readable."""
    Q = _start(np.asarray(P, dtype=float), d)
    for _ in range(iters):
        found = close_pairs(Q, d)
        if not len(found):
            break
        diff = Q[found[:, 0]] - Q[found[:, 1]]
        dist = np.hypot(*diff.T)[:, None]
        push = diff / np.maximum(dist, 1e-12) * (d - dist) / 2
        np.add.at(Q, found[:, 0], push)
        np.add.at(Q, found[:, 1], -push)
    return Q


def spread_boxes(P, size, iters=60):
    """``P`` with the boxes of ``size`` ``(width, height)`` centred on them pushed apart until no
    two overlap (deterministic): each overlapping pair moves apart along the axis on which it
    overlaps least, half the overlap each."""
    size = np.asarray(size, dtype=float)
    Q = _start(np.asarray(P, dtype=float), size)
    for _ in range(iters):
        found = close_pairs(Q, size)
        if not len(found):
            break
        diff = Q[found[:, 0]] - Q[found[:, 1]]
        overlap = size - np.abs(diff)
        axis = np.argmin(overlap / size, axis=1)  # the cheaper way out
        push = np.zeros_like(diff)
        rows = np.arange(len(found))
        sign = np.where(diff[rows, axis] >= 0, 1.0, -1.0)
        push[rows, axis] = sign * (overlap[rows, axis] / 2 + 1e-6 * size[axis])
        np.add.at(Q, found[:, 0], push)
        np.add.at(Q, found[:, 1], -push)
    return Q


def number_box(ax, states, fontsize) -> np.ndarray:
    """``(width, height)`` in data units of the widest of the numbers ``states`` at ``fontsize``
    points, with their white outline."""
    digits = max((len(str(int(s))) for s in states), default=1)
    points = np.array([DIGIT_WIDTH * digits * fontsize, NUMBER_HEIGHT * fontsize]) + HALO
    return points * data_per_point(ax)


def write_numbers(ax, P, states, fontsize):
    """Write each state's number at its point of ``P`` in bold with a white outline, the numbers'
    boxes first pushed apart so that none overlaps another (:func:`spread_boxes`)."""
    import matplotlib.patheffects as pe

    halo = [pe.withStroke(linewidth=HALO, foreground="white")]
    Q = spread_boxes(P, number_box(ax, states, fontsize)) if len(P) > 1 else P
    for s, (x, y) in zip(states, Q):
        ax.text(x, y, str(s), ha="center", va="center", fontsize=fontsize, zorder=6,
                fontweight="bold", path_effects=halo, clip_on=True)
