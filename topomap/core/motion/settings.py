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


@dataclass(frozen=True)
class MotionSettings:
    """How :meth:`topomap.MapLearner.fit` maps a log recorded at 10-50 Hz (docs/continuous.md).

    ``mode``: ``"auto"`` recognises such a log (:func:`is_continuous`: ``min_steps`` steps or
    more, no GDS, every phase-1 symbol entered twice on average, runs of one symbol ``min_run``
    steps long on average, or odometry given) and cuts its places from views and odometry learned from the data;
    ``"discrete"`` never does (the paper's map, refined as ``refine`` says); ``"continuous"``
    always does.  A continuous log gets no ``refine``: its places replace the refinement.

    ``gates``: a step joins a copy of its view cluster within ``gate`` cell extents of its reckoned
    position (:func:`topomap.core.motion.odometry.odometric_positions`); each gate gives one
    position estimate, and all of them enter the K-means that cuts the places, so that no single
    gate decides (a tight gate splits an open room by drift, a wide one joins alike rooms).
    ``weight``: the positions' weight beside the view in that K-means (the view in units of one
    view cluster's extent, the positions in cell extents;
    :func:`topomap.core.motion.places.place_features`).  ``loose_weight``: their weight instead
    where the odometry closes loops loosely -- walks that return to a view cluster keep more
    than ``loose_return`` of a random walk's displacement in its weaker direction
    (:func:`topomap.core.motion.places.position_weight`): at 0.5 a view one cluster's extent
    off counts as a position two cell extents off, so drift of a cell or so inside a room
    leaves a step with its view (with boundary-vector cells, whose odometry keeps 0.26-0.33,
    places cut at weight 1 smeared inside rooms and placed a new walk worse than the views;
    docs/benchmarks.md); where the places cut so give way to the view clusters in the held-out
    check, those cut at ``weight`` are checked in turn.  ``pull``: how far a step's reckoned
    position moves towards the copy it joins.  ``max_return``: odometry is used only where walks
    that come back to a view cluster keep at most this share of a random walk's displacement
    (:func:`topomap.core.motion.odometry.action_vectors`); turn / forward commands fail it and
    the places are then the view clusters alone.

    ``holdout``: the share of the log, at its end, that the held-out check decodes
    (:mod:`topomap.core.motion.check`): the places and the view clusters (K-means on the views,
    as many clusters as places) are learned on the rest and decode it; a held-out step is
    misplaced when its decoded state stands more than ``far`` cell extents from the odometric
    position the filter carries on (counted over the held-out steps that joined a copy made
    before them).  ``folds`` such parts are held out, one after another from
    the end (the second learns from the steps before the last two, and decodes the first of
    them), and the places are kept only when their misplaced share over the folds' held-out
    steps with a reference (each counted once) is below the view clusters', at most ``margin`` times it and at least ``min_gain`` below it (two
    shares of a hundredth or so are a handful of runs of one view either way), or when most of
    the last ``votes`` parts (the third learning from the first quarter alone), each on its
    own, give the places a share at least ``min_gain`` below the view clusters' (``votes=0``:
    no vote).  ``confidence`` > 0 also asks the pooled share to beat the view clusters' by that
    many times its own sampling noise (:func:`topomap.core.motion.check.gain_noise`: the spread
    of the gain over stretches of ``block_runs`` mean runs of one view cluster, since
    neighbouring steps are not independent draws); the check records gain and noise either way
    (off by default: on ``topomap experiment=arena_two_rooms`` a bar of 1 gives up places at
    half the views' error, docs/benchmarks.md).  Else the map's states are the view clusters;
    they are also, unchecked, where the middle gate's filter kept no more than ``min_copies``
    copies per view cluster (:func:`topomap.core.motion.check.tells_apart`: the odometry told
    no sighting of a view from another, and the places could only follow its drift).
    They are also, unchecked, where fewer than ``min_purity`` of the steps lie in their place's
    view cluster (:func:`topomap.core.motion.check.view_purity`: the places cut across the views,
    the odometry alone deciding where a step belongs; with boundary-vector cells on
    ``three_rooms`` and ``pillars`` such places were as often worse than the views as better;
    0: never).
    ``holdout=0`` (or a held-out part under 100 steps) keeps the places unchecked.

    ``n_init``: the k-means++ starts of the view clusters (scikit-learn's ``KMeans`` on every
    row, :func:`~topomap.core.phase1.clustering.view_clusters`).  A map that falls back to
    them gives every state one variance, pooled over the states and the features, times
    ``fallback_variance``: its Viterbi decoding then ranks states by the distance of a view to
    their means, as the nearest centre does, and at 0.01 (a tenth of a cluster's spread) that
    ranking outweighs the transitions but where two centres are all but equally near (at 1 the
    transitions move steps off their nearest centre, up to 2 % farther off on a held-out walk).
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
