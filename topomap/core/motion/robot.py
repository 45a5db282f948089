"""The robot route: a metric map of cells from headings closed by loops, places on it, and a
held-out walk placed by its own odometry (``MotionSettings(mode="robot")``; docs/robot-logs.md).

Learning from one walk of egocentric range scans ``X`` (T, B: a ring of ``B`` beams, beam 0
straight ahead, anticlockwise) and wheel odometry (T, 3) (:func:`learn_robot`):

1. every step's heading from :func:`~topomap.core.motion.scans.scan_headings` (the odometry's
   turns calibrated against the scans' turns, closed by scan-matched loop closures), and
   positions dead-reckoned along it with the odometry's travel (:func:`~.reckoning.reckon`);
2. ``CELLS`` cells by K-means on the squares the walk entered (:func:`cells`), each cell's mean
   scan turned into the map frame, one pooled variance, each cell's successors between
   keyframes and the cells within ``REACH`` spacings of it (:func:`successors`);
3. ``n_places`` places by K-means on the positions; each cell belongs to the place most of its
   steps are in.

Placing a walk (:func:`place_walk`): its keyframes' moves from its own odometry, a Viterbi over
(cell, heading bin) (:mod:`topomap.core.motion.robot_decode`), each step the place of its
keyframe's cell; a keyframe's scan likelihood is weighted by the evidence it holds
(:func:`evidence_weight`).  Measured (``benchmarks/notes/robots.md``, 2026-12-03): 1.11-1.25x
the error of K-means on the true positions on three furnished 1 m plans, 1.22x on an office
plan held out from development; it fails on point-symmetric plans (the walk and its point
reflection look alike) and where a new walk goes onto floor a 30-minute walk never covered.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from sklearn.cluster import KMeans

from ..stats import label_means
from . import scans as S
from .reckoning import forward_moves, keyframes, reckon
from .robot_decode import emission, heading_kernel, viterbi

__all__ = ["RobotMap", "learn_robot", "place_walk", "cells", "successors", "CELLS",
           "SQUARES_PER_CELL", "KEYFRAME_SPACING", "REACH", "MOVE_SD", "HEADING_SD_BINS", "JUMP",
           "PLACE_STARTS", "EVIDENCE_LAGS", "evidence_weight"]

#: cells of the metric map (cells): 0.07-0.1 m apart on the 1 m plans, about a third of a
#: place; the research route's value, 1.16-1.38x ideal there (not tuned further)
CELLS = 256
#: grid squares per cell spacing (squares): cells are cut on the squares a quarter of a cell wide
#: that the walk entered, each once -- K-means on the steps made the room visited longer finer,
#: and pulled a whole held-out walk into the wrong alike room (robot_alike seed 1: 1.32 m against
#: 0.105 m)
SQUARES_PER_CELL = 4
#: a keyframe every this much of the cells' spacing travelled (share)
KEYFRAME_SPACING = 0.5
#: the sd of where a move lands around a successor cell (share of the cells' spacing)
MOVE_SD = 0.5
#: the sd of a keyframe's heading about the odometry's turn (heading bins of 2 pi / B rad)
HEADING_SD_BINS = 0.5
#: a cell's successors include every cell within this many cell spacings (spacings): a new walk
#: steps between neighbouring cells the training walk never stepped between at consecutive
#: keyframes -- 10-19 % of a held-out walk's keyframe moves on the 1 m plans and
#: ``robot_office`` at a third of its size; the decoder, held to the walked successors, lost
#: ``robot_office`` seed 1's held-out walk (1.59 m off against 0.08 m with a reach of 2;
#: 1.5: 0.09 m, but seed 2 0.49 m against 0.14 m; 3: no better, twice the successors)
REACH = 2.0
#: a jump anywhere (probability a keyframe): none -- at 1e-4 a held-out stay of 4,900 steps in
#: one of two identical rooms drifted to the other (0.72 m against 0.096 m without)
JUMP = 1e-300
#: k-means++ starts of the cells and the places (starts)
PLACE_STARTS = 2
#: keyframes: the residuals' correlation across keyframes is summed over this many lags (their
#: correlation falls from 0.3-0.6 at one keyframe to 0.03-0.11 at eight on the 1 m plans and
#: ``robot_office`` at a third of its size)
EVIDENCE_LAGS = 8


@dataclass(frozen=True)
class RobotMap:
    """The metric map a walk is placed on: ``centres`` (N, 2) [m] of the cells in the map frame,
    ``scans`` (N, B) their mean scans turned into the map frame [m], ``variance`` [m^2] of a
    beam about them, each cell's successors in CSR (``successor_ptr`` (N + 1,),
    ``successor_idx``), ``spacing`` [m] the median distance of a cell to its nearest,
    ``log_prior`` (N,) the share of training steps in each cell (log), ``place`` (N,) the
    place of each cell, ``evidence`` the weight of a keyframe's scan likelihood
    (:func:`evidence_weight`; 1: every beam of every keyframe independent) and ``beam_order``
    (B,) the column order that numbers a walk's beams as the map reads them (beam 0 ahead,
    anticlockwise; None: as they come, :mod:`~topomap.core.motion.beams`)."""

    centres: np.ndarray
    scans: np.ndarray
    variance: float
    successor_ptr: np.ndarray
    successor_idx: np.ndarray
    spacing: float
    log_prior: np.ndarray
    place: np.ndarray
    evidence: float = 1.0
    beam_order: np.ndarray | None = None

    @property
    def n_cells(self) -> int:
        return len(self.centres)


def cells(xy, n: int, random_state) -> tuple[np.ndarray, np.ndarray]:
    """``(labels (T,), centres (N, 2))``: at most ``n`` K-means cells on the grid squares
    ``SQUARES_PER_CELL`` to a cell spacing that the positions ``xy`` (T, 2) [m] entered, each
    square once (cells as dense where the walk went once as where it went often); only cells
    holding a step are kept, numbered in order."""
    xy = np.asarray(xy, dtype=np.float64)
    extent = np.maximum(xy.max(0) - xy.min(0), 1e-9)
    side = np.sqrt(np.prod(extent) / n) / SQUARES_PER_CELL
    squares = np.unique(np.round(xy / side), axis=0) * side
    km = KMeans(min(n, len(squares)), n_init=PLACE_STARTS, random_state=random_state).fit(squares)
    labels = km.predict(xy)
    used, labels = np.unique(labels, return_inverse=True)
    return labels, km.cluster_centers_[used]


def successors(cells_kf, n: int, centres=None,
               reach: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(ptr, idx)`` of each of ``n`` cells' successors: the cells the keyframes'
    ``cells_kf`` step to from it, itself included, and the cells whose ``centres`` (n, 2) [m]
    lie within ``reach`` [m] of its own."""
    A = np.eye(n, dtype=bool)
    A[cells_kf[:-1], cells_kf[1:]] = True
    if centres is not None and reach > 0:
        for i, near in enumerate(cKDTree(centres).query_ball_point(centres, reach)):
            A[i, near] = True
    return np.r_[0, np.cumsum(A.sum(1))].astype(np.int64), np.nonzero(A)[1].astype(np.int64)


def evidence_weight(residuals) -> float:
    """The weight (0-1] of a keyframe's scan likelihood, ``log N(x; m, var I)`` of its ``B``
    beams taken as independent: ``residuals`` (K, B) [m] are the training walk's keyframe scans
    less their cells' mean scans, in walk order.  Beams and keyframes are not independent (a
    pose off its cell's centre moves every beam at once; keyframes half a cell apart see the
    same off-centre): the weight is the beams' effective number, the participation ratio
    ``tr(C)^2 / tr(C^2)`` of the residuals' covariance ``C`` (``B`` for independent beams of
    one variance, 1 for one shared error), over ``B``, times the keyframes' effective share
    ``1 / (1 + 2 sum_l rho_l)``, ``rho_l`` the residuals' correlation ``l`` keyframes apart
    (lags 1 to :data:`EVIDENCE_LAGS`, each at least 0).  Measured on the benchmark's robot:
    0.04-0.1."""
    R = np.asarray(residuals, dtype=np.float64)
    K, B = R.shape
    if K < 2:
        return 1.0
    C = np.cov(R.T)
    ratio = np.trace(C) ** 2 / max(float(np.sum(C * C)), 1e-300) / B
    power = float((R * R).sum(1).mean())
    rho = [max(float((R[:-lag] * R[lag:]).sum(1).mean()) / max(power, 1e-300), 0.0)
           for lag in range(1, min(EVIDENCE_LAGS, K - 1) + 1)]
    return float(min(1.0, ratio / (1 + 2 * sum(rho))))


def learn_robot(X, odometry, n_places: int, random_state=0, n_cells: int = CELLS,
                odometry_turns: bool = True,
                headings=None) -> tuple[RobotMap, np.ndarray, np.ndarray]:
    """``(map, places (T,), poses (T, 3))`` from one walk: scans ``X`` (T, B) in the robot's frame
    and its wheel ``odometry`` (T, 3); ``poses`` the reckoned x [m], y [m], heading [rad].
    ``odometry_turns=False``: the headings from the scans' turns alone (odometry whose heading
    is no measurement, e.g. :func:`~.reckoning.command_poses`); ``headings`` (T,) [rad]: the
    steps' headings solved already (:func:`~.scans.scan_headings`; None: solved here)."""
    odometry = np.asarray(odometry, dtype=np.float64)
    if headings is None:
        headings = S.scan_headings(X, odometry[:, 2] if odometry_turns else None)
    P = reckon(forward_moves(odometry), np.asarray(headings, dtype=np.float64))
    cell, cent = cells(P[:, :2], n_cells, random_state)
    N = len(cent)
    R = S.rotate_scans(S.despike(X), P[:, 2])
    M = label_means(cell, R, N)
    var = float(((R - M[cell]) ** 2).mean())
    gaps = np.linalg.norm(cent[:, None] - cent[None], axis=2) + np.diag(np.full(N, np.inf))
    spacing = float(np.median(gaps.min(1))) if N > 1 else 1.0
    kf = keyframes(P, spacing * KEYFRAME_SPACING)
    ptr, idx = successors(cell[kf], N, cent, spacing * REACH)
    n_places = min(n_places, len(np.unique(P[:, :2], axis=0)))
    places = KMeans(n_places, n_init=PLACE_STARTS, random_state=random_state).fit(
        P[:, :2]).labels_
    votes = np.zeros((N, n_places))
    np.add.at(votes, (cell, places), 1)
    prior = np.log(np.bincount(cell, minlength=N) / len(cell))
    model = RobotMap(cent, M, var, ptr, idx, spacing, prior, votes.argmax(1),
                     evidence_weight(R[kf] - M[cell[kf]]))
    return model, places, P


def place_walk(model: RobotMap, X, odometry, jump: float = JUMP) -> tuple[np.ndarray, np.ndarray]:
    """``(places (T,), cells (T,))`` of one walk: scans ``X`` (T, B) and its own ``odometry``
    (T, 3), placed keyframe by keyframe (the module docstring; ``jump`` the probability of a
    jump anywhere a keyframe); each step takes its keyframe's cell."""
    O = np.asarray(odometry, dtype=np.float64)
    kf = keyframes(O, model.spacing * KEYFRAME_SPACING)
    E = emission(S.despike(X)[kf], model.scans, model.variance / model.evidence)
    path, _ = viterbi(E, forward_moves(O[kf]), model.centres, model.successor_ptr,
                      model.successor_idx, model.spacing * MOVE_SD,
                      heading_kernel(HEADING_SD_BINS), model.log_prior, np.log(jump))
    step_cells = path[np.searchsorted(kf, np.arange(len(O)), "right") - 1]
    return model.place[step_cells], step_cells
