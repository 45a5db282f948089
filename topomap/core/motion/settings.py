"""How a log recorded at 10-50 Hz is recognised and mapped: :class:`MotionSettings`, the
``motion`` parameter of :class:`topomap.MapLearner` (``learner.motion.<key>`` in the config),
and :func:`mean_run`, the statistic that recognises such a log.

======================  =========================  ==========================================
object                  config key                 what it sets
======================  =========================  ==========================================
:class:`MotionSettings` ``learner.motion``         which logs are continuous (``mode``,
                                                   ``min_run``, ``min_steps``), and the two
                                                   groups below
:class:`PlaceSettings`  ``learner.motion.places``  how the places are cut from views and
                                                   odometry, and the view clusters beside them
:class:`CheckSettings`  ``learner.motion.check``   the held-out check that keeps the places or
                                                   gives them up for the view clusters
======================  =========================  ==========================================

Distances are in cell extents: the spread of the reckoned positions over which one view
cluster is seen.  Why each default is what it is: ``benchmarks/notes/continuous.md`` (its
sections "How each setting of the continuous path was chosen" and "``MotionSettings``: the
calibration notes of its docstring").  The flat names of before 0.3 (``holdout``, ``check``
for the rule) still work until 0.4 with a ``FutureWarning``
(:mod:`topomap.core.motion.renamed`).
"""

from __future__ import annotations

import functools
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from ..checks import ParameterError, check_count, checked_group
from .renamed import fold_motion

__all__ = ["MODES", "RULES", "PlaceSettings", "CheckSettings", "MotionSettings",
           "motion_settings", "mean_run", "is_continuous"]

#: what ``MotionSettings.mode`` (or ``motion`` given as a string) accepts
MODES = ("auto", "discrete", "continuous", "robot")
#: what ``CheckSettings.rule`` accepts
RULES = ("bootstrap", "coverage", "crossfit", "folds")


@dataclass(frozen=True)
class PlaceSettings:
    """``motion.places``: how the places are cut from views and odometry (docs/continuous.md)."""

    gates: tuple[float, ...] = (2.5, 3.0, 3.5)
    """A step joins a copy of its view cluster within each gate of its reckoned position, one
    position estimate per gate, all of them in the K-means (cell extents; one gate alone: a
    tight one splits an open room by drift, a wide one joins alike rooms)."""
    weight: float = 1.0
    """The positions' weight beside the view in the K-means that cuts the places (view cluster
    extents per cell extent; :func:`~topomap.core.motion.places.place_features`)."""
    pull: float = 0.2
    """How far a joining step's reckoned position moves towards its copy (share, 0-1)."""
    max_return: float = 0.35
    """Odometry is used only where walks returning to a view cluster keep at most this much of a
    random walk's displacement (share; compass commands 0.17-0.27, turn / forward 0.42-0.82)."""
    loose_return: float = 0.26
    """Returns keeping more than this (share) make the odometry loose: ``loose_weight`` then
    (boundary-vector cells keep 0.20-0.37, the range finder 0.11-0.25 at 10 Hz)."""
    loose_weight: float = 0.5
    """The positions' weight where the odometry is loose (as ``weight``; at 0.5 a cell or so of
    drift inside a room leaves a step with its view, alike rooms stay apart)."""
    n_init: int = 4
    """k-means++ starts of the view clusters (starts; scikit-learn's ``KMeans``, as the
    yardstick *K-means on the views* runs it)."""
    fallback_variance: float = 0.01
    """A map of view clusters gives every state one variance, pooled, times this (share, (0, 1];
    at 1 its decoding placed walks up to 2 % farther off than the nearest centre)."""
    graph_gate: float = 6.0
    """The held-out check also weighs places whose positions are one pose graph over the log,
    its loop closures the copies at this gate (cell extents; 0: no such places): where they
    place its held-out part nearer than the filter's places by over two standard errors, they
    stand in for them (:func:`~topomap.core.motion.places.graph_places`; on Tanni's rat path in
    its room with two pillars 0.088-0.100 m against the filter's 0.111-0.154 m)."""


@dataclass(frozen=True)
class CheckSettings:
    """``motion.check``: the held-out check between places and view clusters
    (:mod:`topomap.core.motion.check`; docs/continuous.md)."""

    rule: str = "coverage"
    """``"bootstrap"``: the places cut again before the last ``holdout``, kept unless the view
    clusters place it nearer its own pose graph by over two bootstrap standard errors (no field
    below but ``holdout``); ``"coverage"``: the same, but where an earlier part of as many steps
    lies mostly in places the rest of the log seldom visits, that part held out instead and the
    places kept only where no farther off (:mod:`~topomap.core.motion.coverage`), and where the
    last part keeps them within two standard errors, the part before it held out too, the places
    given up by the same bar (over 1 % above the views on 0 of 30 walks, ``bootstrap`` on 3;
    4 of 126 with the sensor settings of benchmarks/notes/continuous.md, "50 Hz");
    ``"crossfit"``: kept where nearer at all;
    ``"folds"``: the fields below."""
    holdout: float = 0.25
    """The share of the log held out at its end (share; 0, or a part under 100 steps: no check)."""
    margin: float = 0.9
    """The places are kept at most this many times the views' misplaced share (ratio, (0, 1])..."""
    far: float = 2.0
    """... a held-out step misplaced when its state stands farther off its position (cell
    extents)."""
    folds: int = 2
    """Held-out parts, one after another from the end, pooled (parts)."""
    min_gain: float = 0.02
    """... and at least this below the views' share (share; a hundredth is a handful of runs)."""
    votes: int = 3
    """Or kept when most of the last this many parts, each alone, find that gain (parts; 0:
    no vote; a third part averaged in kept losing places on Tanni's rat path)."""
    min_copies: float = 1.0
    """The view clusters, unchecked, where the middle gate kept no more copies per view cluster
    (copies per view cluster; the odometry told no sighting apart; every rule: at 50 Hz such
    places lost to the views on 6 of 24 walks, by up to 33 %)."""
    confidence: float = 0.0
    """The pooled gain must also be this many times its noise (standard errors; 0: off -- a bar
    of 1 gave up ``arena_two_rooms``' places at half the views' error)..."""
    block_runs: float = 50.0
    """... measured over stretches of this many mean runs of one view (runs)."""
    min_purity: float = 0.2
    """The view clusters, unchecked, where fewer of the steps lie in their place's view cluster
    (share; 0: never; such places lost as often as they won, 0.14-0.16 on boundary cells)."""


@dataclass(frozen=True)
class MotionSettings:
    """How :meth:`topomap.MapLearner.fit` maps a log recorded at 10-50 Hz (docs/continuous.md):
    whether a log is one, and two groups, :class:`PlaceSettings` and :class:`CheckSettings`
    (each a settings object or a mapping of some of its fields)."""

    mode: str = "auto"
    """``"auto"``: places where :func:`is_continuous` says (a log given odometry always is);
    ``"discrete"``: never (the paper's map, refined as ``refine`` says); ``"continuous"``:
    always; ``"robot"``: a robot's egocentric range scans and wheel odometry, mapped by the robot
    route (:mod:`topomap.core.motion.robot`; ``predict`` then needs the walk's odometry).  A
    continuous log gets no ``refine``."""
    min_run: float = 1.6
    """The least mean run of one phase-1 symbol of such a log (steps; discrete worlds run
    1.0-1.3, compass walkers 13-16 and a robot's own-frame scans 2.0-5.0 at 10 Hz)."""
    min_steps: int = 1000
    """The least steps of such a log (steps)."""
    scan_odometry: bool = True
    """Whether ``mode="auto"`` gives a robot's log of egocentric range scans and turn commands
    WITHOUT odometry the robot route, its odometry read from the scans
    (:mod:`topomap.core.motion.robot_scans`), behind the guards of a log with odometry (where
    one fails: the view clusters, the same map as with it off); off: such a log gets the view
    clusters without trying (measured: ``docs/robot-logs.md``)."""
    places: PlaceSettings = PlaceSettings()
    """How the places are cut (``motion.places``)."""
    check: CheckSettings = CheckSettings()
    """The held-out check (``motion.check``)."""

    def __post_init__(self):
        for name, cls in (("places", PlaceSettings), ("check", CheckSettings)):
            value = getattr(self, name)
            if isinstance(value, Mapping) and set(value) <= {f.name for f in fields(cls)}:
                object.__setattr__(self, name, cls(**_listed(value)))


def _taking_old_names(init):
    """``MotionSettings.__init__`` taking the flat names of before 0.3 too, with a warning."""

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        init(self, *args, **fold_motion(kwargs, stacklevel=2))

    return __init__


MotionSettings.__init__ = _taking_old_names(MotionSettings.__init__)


def _listed(value: Mapping) -> dict:
    """A mapping of settings with ``gates`` (a list, say) as a tuple."""
    gates = value.get("gates")
    if gates is not None and not isinstance(gates, (str, tuple)) and hasattr(gates, "__iter__"):
        return {**value, "gates": tuple(gates)}
    return dict(value)


def _real(ok, what: str):
    def check(value, key):
        if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
                and np.isfinite(value) and ok(value)):
            raise ParameterError(key, f"must be {what}, got {value!r}")
    return check


def _count(minimum: int = 1):
    return lambda value, key: check_count(value, key, minimum=minimum)


def _gates(value, key):
    if not isinstance(value, tuple) or not value or not all(_positive(g) for g in value):
        raise ParameterError(key, f"must be a non-empty list of positive numbers, got {value!r}")


_POSITIVE = _real(lambda v: v > 0, "a positive number")


def _pull(value, key):
    _POSITIVE(value, key)
    if value > 1:
        raise ParameterError(key, f"must be at most 1, got {value!r}")


def _choice(options):
    def check(value, key):
        if value not in options:
            raise ParameterError(key, f"must be one of {', '.join(options)}, got {value!r}")
    return check


_SHARE = _real(lambda v: 0 <= v < 1, "a number in [0, 1)")
_UNIT = _real(lambda v: 0 < v <= 1, "a number in (0, 1]")

#: what every field of a group must be
CHECKS = {
    PlaceSettings: {"gates": _gates, "weight": _POSITIVE, "pull": _pull,
                    "max_return": _POSITIVE, "loose_return": _SHARE, "loose_weight": _POSITIVE,
                    "n_init": _count(), "fallback_variance": _UNIT,
                    "graph_gate": _real(lambda v: v >= 0, "a number >= 0")},
    CheckSettings: {"rule": _choice(RULES), "holdout": _SHARE, "margin": _UNIT,
                    "far": _POSITIVE, "folds": _count(), "min_gain": _SHARE,
                    "votes": _count(0), "min_copies": _POSITIVE,
                    "confidence": _real(lambda v: v >= 0, "a number >= 0"),
                    "block_runs": _POSITIVE, "min_purity": _SHARE},
}
#: the groups of :class:`MotionSettings` and their classes
GROUPS = {"places": PlaceSettings, "check": CheckSettings}


def _group(cls, value, key: str):
    """``value`` -- a ``cls`` or a mapping of some of its fields -- as checked settings; a
    :class:`ParameterError` names ``<key>.<field>``."""
    return checked_group(cls, value, key, CHECKS[cls], _listed)


def motion_settings(value, stacklevel: int = 2) -> MotionSettings:
    """``value`` -- a mode name, a :class:`MotionSettings`, or a mapping of some of its fields
    (the config's ``learner.motion``; a group a mapping of some of its own) -- as checked
    settings; a :class:`ParameterError` names ``motion`` or ``motion.<group>.<field>``.  The
    names of before 0.3 are moved to their groups with a ``FutureWarning``
    (:func:`~topomap.core.motion.renamed.fold_motion`)."""
    if isinstance(value, str):
        value = {"mode": value}
    if isinstance(value, Mapping):
        value = fold_motion(value, stacklevel=stacklevel + 1)
        names = [f.name for f in fields(MotionSettings)]
        unknown = sorted(set(value) - set(names))
        if unknown:
            raise ParameterError(f"motion.{unknown[0]}", "is not a motion setting; the "
                                                         "settings are " + ", ".join(names))
        value = MotionSettings(**{k: _group(GROUPS[k], v, f"motion.{k}") if k in GROUPS else v
                                  for k, v in value.items()})
    if not isinstance(value, MotionSettings):
        raise ParameterError("motion", f"must be one of {', '.join(MODES)}, a MotionSettings "
                                       f"or a mapping of its fields, got {value!r}")
    if value.mode not in MODES:
        raise ParameterError("motion.mode", f"must be one of {', '.join(MODES)}, "
                                            f"got {value.mode!r}")
    check_count(value.min_steps, "motion.min_steps")
    if not isinstance(value.scan_odometry, (bool, np.bool_)):
        raise ParameterError("motion.scan_odometry", f"must be true or false, got "
                                                     f"{value.scan_odometry!r}")
    _POSITIVE(value.min_run, "motion.min_run")
    for name, cls in GROUPS.items():
        _group(cls, getattr(value, name), f"motion.{name}")
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
