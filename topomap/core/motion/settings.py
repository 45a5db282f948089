"""How a log recorded at 10-50 Hz is recognised and mapped: :class:`MotionSettings`, the
``motion`` parameter of :class:`topomap.MapLearner` (``learner.motion.<key>`` in the config), and
:func:`mean_run`, the statistic that recognises such a log."""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from ..checks import ParameterError, check_count

__all__ = ["MODES", "MotionSettings", "motion_settings", "mean_run", "is_continuous"]

#: what ``MotionSettings.mode`` (or ``motion`` given as a string) accepts
MODES = ("auto", "discrete", "continuous")
#: what ``MotionSettings.check`` accepts
CHECKS = ("folds", "crossfit")


@dataclass(frozen=True)
class MotionSettings:
    """How :meth:`topomap.MapLearner.fit` maps a log recorded at 10-50 Hz (docs/continuous.md;
    the measured reason for each default is in benchmarks/notes/continuous.md).  Distances are in
    cell extents: the spread of the reckoned positions over which one view cluster is seen.

    ``mode``: ``"auto"`` recognises such a log (:func:`is_continuous`; a log given odometry always
    is) and cuts its places from
    views and odometry learned from the data; ``"discrete"`` never does (the paper's map, refined
    as ``refine`` says); ``"continuous"`` always does.  A continuous log gets no ``refine``.
    ``min_steps`` (steps) and ``min_run`` (steps, the mean run of one phase-1 symbol): the least a
    log needs to be recognised.

    ``gates`` (cell extents): a step joins a copy of its view cluster within each gate of its
    reckoned position (:func:`topomap.core.motion.odometry.odometric_positions`), one position
    estimate per gate.  ``pull`` (a share, 0-1): how far a joining step's position moves towards
    the copy.  ``max_return`` (a share of a random walk's displacement): odometry is used only
    where walks that come back to a view cluster keep at most this much
    (:func:`topomap.core.motion.odometry.action_vectors`); else the places are the view clusters.
    ``weight``: the positions' weight beside the view in the K-means that cuts the places
    (:func:`topomap.core.motion.places.place_features`); ``loose_weight`` their weight where walks
    that return keep more than ``loose_return`` of a random walk's displacement
    (:func:`topomap.core.motion.places.position_weight`).

    The held-out check (:mod:`topomap.core.motion.check`): ``holdout`` (a share of the log; 0, or
    a part under 100 steps: no check) is held out at the end, ``folds`` such parts one after
    another; a held-out step is misplaced when its decoded state stands more than ``far`` cell
    extents from its odometric position.  The places are kept when their misplaced share is at most ``margin`` times the
    view clusters' and at least ``min_gain`` below it, or when most of the last ``votes`` parts
    (0: no vote) find it ``min_gain`` below; ``confidence`` (0: off) also asks the gain to be that
    many times its noise over stretches of ``block_runs`` mean runs of one view
    (:func:`topomap.core.motion.check.gain_noise`).  The view clusters are the map's states,
    unchecked, where the check's filter kept no more than ``min_copies`` copies per view cluster
    (:func:`topomap.core.motion.check.tells_apart`) or fewer than ``min_purity`` of the steps lie
    in their place's view cluster (:func:`topomap.core.motion.check.view_purity`; 0: never).

    ``check``: ``"folds"`` (the rule above) or ``"crossfit"`` -- one rule instead: the places
    are cut again on the log before its last ``holdout`` share, from those steps' own positions,
    and kept where they place the held-out steps nearer the held-out part's own pose graph than
    the view clusters do (:mod:`topomap.core.motion.crossfit`; ``gates``' middle one and
    ``pull`` make both pose graphs, no other setting of the check is read).

    ``n_init``: the k-means++ starts of the view clusters (scikit-learn's ``KMeans`` on every
    row).  A map of view clusters gives every state one variance, pooled over the states and the
    features, times ``fallback_variance``, so that its decoding ranks states by the distance of
    a view to their means.
    """

    mode: str = "auto"
    min_run: float = 1.6
    min_steps: int = 1000
    gates: tuple[float, ...] = (2.5, 3.0, 3.5)
    weight: float = 1.0
    pull: float = 0.2
    max_return: float = 0.35
    holdout: float = 0.25
    margin: float = 0.9
    far: float = 2.0
    n_init: int = 4
    folds: int = 2
    fallback_variance: float = 0.01
    min_gain: float = 0.02
    votes: int = 3
    min_copies: float = 1.0
    confidence: float = 0.0
    block_runs: float = 50.0
    min_purity: float = 0.2
    loose_return: float = 0.26
    loose_weight: float = 0.5
    check: str = "folds"


def motion_settings(value) -> MotionSettings:
    """``value`` -- a mode name, a :class:`MotionSettings`, or a mapping of some of its fields
    (the config's ``learner.motion``) -- as checked settings; a :class:`ParameterError` names
    ``motion`` or ``motion.<field>``."""
    names = [f.name for f in fields(MotionSettings)]
    if isinstance(value, str):
        value = {"mode": value}
    if isinstance(value, Mapping):
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise ParameterError(f"motion.{unknown[0]}", "is not a motion setting; the settings "
                                                        "are " + ", ".join(names))
        value = MotionSettings(**{k: (tuple(v) if k == "gates" and not isinstance(v, str)
                                      and hasattr(v, "__iter__") else v)
                                  for k, v in value.items()})
    if not isinstance(value, MotionSettings):
        raise ParameterError("motion", f"must be one of {', '.join(MODES)}, a MotionSettings "
                                       f"or a mapping of its fields, got {value!r}")
    if value.mode not in MODES:
        raise ParameterError("motion.mode", f"must be one of {', '.join(MODES)}, "
                                            f"got {value.mode!r}")
    if value.check not in CHECKS:
        raise ParameterError("motion.check", f"must be one of {', '.join(CHECKS)}, "
                                             f"got {value.check!r}")
    check_count(value.min_steps, "motion.min_steps")
    check_count(value.n_init, "motion.n_init")
    check_count(value.folds, "motion.folds")
    check_count(value.votes, "motion.votes", minimum=0)
    gates = value.gates
    if not isinstance(gates, tuple) or not gates or not all(_positive(g) for g in gates):
        raise ParameterError("motion.gates", f"must be a non-empty list of positive numbers, "
                                             f"got {gates!r}")
    for name in ("min_run", "weight", "loose_weight", "pull", "max_return", "far", "min_copies",
                 "block_runs"):
        if not _positive(getattr(value, name)):
            raise ParameterError(f"motion.{name}", f"must be a positive number, "
                                                   f"got {getattr(value, name)!r}")
    for name in ("holdout", "min_gain", "min_purity", "loose_return"):
        v = getattr(value, name)
        if not (isinstance(v, numbers.Real) and not isinstance(v, bool) and 0 <= v < 1):
            raise ParameterError(f"motion.{name}", f"must be a number in [0, 1), got {v!r}")
    for name in ("margin", "fallback_variance"):
        v = getattr(value, name)
        if not _positive(v) or v > 1:
            raise ParameterError(f"motion.{name}", f"must be a number in (0, 1], got {v!r}")
    c = value.confidence
    if not (isinstance(c, numbers.Real) and not isinstance(c, bool) and np.isfinite(c) and c >= 0):
        raise ParameterError("motion.confidence", f"must be a number >= 0, got {c!r}")
    if value.pull > 1:
        raise ParameterError("motion.pull", f"must be at most 1, got {value.pull!r}")
    return value


def _positive(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and np.isfinite(v) and v > 0


def mean_run(symbols, lengths) -> float:
    """Mean number of consecutive steps with one symbol (runs end at episode boundaries)."""
    symbols = np.asarray(symbols)
    if symbols.size == 0:
        return 0.0
    change = np.ones(symbols.size, dtype=bool)
    change[1:] = symbols[1:] != symbols[:-1]
    change[np.cumsum(lengths)[:-1]] = True
    return float(symbols.size / np.count_nonzero(change))


def is_continuous(settings: MotionSettings, symbols, lengths, gds,
                  odometry: bool = False) -> bool:
    """Whether a log whose phase-1 symbols are ``symbols`` is continuous under ``settings``:
    ``mode="continuous"``, or ``mode="auto"`` and ``min_steps`` steps or more, no GDS step, two
    symbols or more, each entered twice on average, and runs of ``min_run`` steps or more on
    average (1.0-1.3 in every discrete world topomap ships; compass walkers 13-16 at 10 Hz; a
    robot's egocentric scans 2.0-5.0 at 10 Hz, as they turn with it) -- or, ``odometry`` given,
    whatever its runs: a log with odometry is a robot's, continuous motion."""
    if settings.mode != "auto":
        return settings.mode == "continuous"
    symbols = np.asarray(symbols)
    if symbols.size < settings.min_steps:
        return False
    run = max(mean_run(symbols, lengths), settings.min_run if odometry else 0.0)
    if run < settings.min_run or not np.all(np.asarray(gds) < 0):
        return False  # a discrete world: decided without sorting its symbols
    n_symbols = np.unique(symbols).size
    return bool(n_symbols >= 2 and symbols.size / run >= 2 * n_symbols)
