"""The learner's parameters made into the components of a fit -- the cluster-count policy, the
observation metric, the split criterion, the stopping rule and the refinement -- with every
error naming the learner's own parameter (:func:`naming`)."""

from __future__ import annotations

import copy
import functools
import inspect
import warnings
from contextlib import contextmanager

import numpy as np
from sklearn.base import BaseEstimator, clone

from .checks import ParameterError, check_count
from .map.observations import log_density_chunks
from .phase1.ambiguity import symbol_ambiguity
from .phase1.clustering import FixedClusters, make_metric
from .phase1.heading import MODES as HEADING_MODES
from .refine.methods import REFINEMENTS, CloneFit
from .size import AutoStates
from .split.criteria import CRITERIA
from .split.stopping import TargetStates

__all__ = ["make_components", "make_refinement", "fit_refinement", "refinement_label", "naming",
           "within_told_size", "fold_renamed", "set_params", "RENAMED", "phase1_symbols"]

#: the learner's own parameter behind a parameter of a component it makes itself
#: (``FixedClusters(n_clusters)``, ``TargetStates(n_states)``)
_MADE_FROM = {("clusters", "ns"): "n_clusters", ("stop", "n_states"): "n_states"}
#: the learner's parameters renamed in 0.3 (accepted until 0.4): their new names and the new
#: names' defaults
RENAMED = {"criterion": ("split", "entropy"), "stopping": ("stop", None)}


@contextmanager
def naming(learner, arg: str, **own: str):
    """Name the parameter of a :class:`ParameterError` raised inside as ``learner``'s:
    ``<arg>.<param>`` for a parameter of the component passed as ``arg`` (``clusters.ns``),
    the learner's own parameter when the learner made the component from it
    (``n_clusters``), and ``own[param]`` for a setting passed on under another name
    (``method`` is ``phase1``)."""
    given = getattr(learner, arg)
    try:
        yield
    except ParameterError as err:
        if err.param in own:
            name = own[err.param]
        elif given is None:
            name = _MADE_FROM.get((arg, err.param), err.param)
        else:
            name = f"{arg}.{err.param}"
        raise err.renamed(name) from err.__cause__


def fold_renamed(old: dict, split, stop, stacklevel: int):
    """The learner's ``(split, stop)`` given as ``split`` and ``stop``, with the values given
    under their names of before 0.3 (``old``: ``criterion``, ``stopping``) in their place, a
    ``FutureWarning`` for each (``stacklevel`` counted from the caller); a
    :class:`ParameterError` when the new name is given too, a ``TypeError`` for any other
    name."""
    out = {"split": split, "stop": stop}
    for name, value in old.items():
        if name not in RENAMED:
            raise TypeError(f"MapLearner got an unexpected keyword argument {name!r}")
        new, default = RENAMED[name]
        warnings.warn(f"MapLearner's {name}= was renamed {new}= in 0.3 and goes in 0.4; pass "
                      f"{new}= instead", FutureWarning, stacklevel=stacklevel + 1)
        given = out.get(new, default)
        if given is not default and given != default:
            raise ParameterError(name, f"is the deprecated name of {new}: give {new} only")
        out[new] = value
    return out["split"], out["stop"]


def set_params(learner, **params):
    """:class:`~topomap.MapLearner`'s ``set_params``: scikit-learn's, ``criterion`` and
    ``stopping`` (the names of ``split`` and ``stop`` before 0.3) accepted until 0.4 with a
    ``FutureWarning``."""
    old = {k: params.pop(k) for k in RENAMED if k in params}
    if old:
        params["split"], params["stop"] = fold_renamed(
            old, params.get("split", learner.split), params.get("stop", learner.stop), 2)
    return BaseEstimator.set_params(learner, **params)


def make_components(learner):
    """``(clusters, metric, criterion, stopping)`` of a fit by ``learner`` (its ``clusters``,
    ``metric``, ``split`` and ``stop``), its other settings checked; a stopping rule may keep
    state during a fit (e.g. its limit), so a fit works on a copy and the parameter itself is
    never changed."""
    with naming(learner, "clusters"):
        clusters = (learner.clusters if learner.clusters is not None
                    else FixedClusters(learner.n_clusters))
    if learner.stop is not None:
        stopping = copy.deepcopy(learner.stop)
    else:
        stopping = (AutoStates() if learner.n_states == "auto"
                    else TargetStates(learner.n_states))
    criterion = learner.split
    if isinstance(criterion, str):
        if criterion not in CRITERIA:
            raise ParameterError("split", f"{criterion!r} is unknown; choose one of "
                                          f"{', '.join(sorted(CRITERIA))}")
        criterion = CRITERIA[criterion]()
    if learner.refined_size not in ("told", "free"):
        raise ParameterError("refined_size",
                             f"must be 'told' or 'free', got {learner.refined_size!r}")
    if learner.heading not in HEADING_MODES:
        raise ParameterError("heading", f"must be one of {', '.join(HEADING_MODES)}, got "
                                        f"{learner.heading!r}")
    if learner.covariance_type not in ("diag", "full"):
        raise ParameterError("covariance_type",
                             f"must be 'diag' or 'full', got {learner.covariance_type!r}")
    if not (isinstance(learner.reg_covar, (int, float)) and learner.reg_covar > 0):
        raise ParameterError("reg_covar", f"must be a positive number, got {learner.reg_covar!r}")
    check_count(learner.n_init, "n_init")
    check_count(learner.sample_size, "sample_size", allow_none=True)
    check_count(learner.window, "window")
    check_count(learner.refit_every, "refit_every")
    return clusters, make_metric(learner.metric), criterion, stopping


def make_refinement(refine):
    """The refinement a fit uses for the learner's ``refine`` (None: the paper's method alone): a
    new built-in for a name, else a clone of the object (``sklearn.base.clone``; a deep copy of
    an object that is not a scikit-learn estimator), so fitting it never changes ``refine``."""
    if isinstance(refine, str):
        if refine == "none":  # the config's option name; in Python "no refinement" is None
            warnings.warn('refine="none" is refine=None in Python; the string goes in 0.4',
                          FutureWarning, stacklevel=3)
            return None
        if refine not in REFINEMENTS:
            raise ParameterError("refine", f"{refine!r} is unknown; choose None or one of "
                                           f"{', '.join(sorted(REFINEMENTS))}")
        return REFINEMENTS[refine]()
    if refine is not None and not callable(getattr(refine, "fit", None)):
        raise ParameterError("refine", f"{refine!r} has no fit(sequence, split_state_symbol, "
                                       "random_state) method")
    return None if refine is None else clone(refine, safe=False)


def fit_refinement(refinement, seq, split_state_symbol, random_state: int,
                   init=None, split_labels=None, ambiguity=None, observed=None) -> CloneFit:
    """Fit ``refinement`` and return what it learned as a :class:`CloneFit`.

    A refinement's ``fit`` returns the refinement, its ``labels_``, ``state_symbol_`` and
    ``info_`` set (``info_`` optional).  A ``fit`` that returns a ``CloneFit`` itself (the
    contract before 0.3) is still accepted, with a ``FutureWarning``, until 0.4.  ``init`` (a
    labelling to start from, :meth:`~topomap.core.refine.rounds.CloneRefinement.fit`) is given
    only when not None, so a refinement whose ``fit`` does not take it still works without;
    ``split_labels`` (the split state of every step), ``ambiguity`` (:func:`symbol_hint`) and
    ``observed`` (:func:`observation_hint`) only to a refinement whose ``fit`` takes them."""
    extra = {} if init is None else {"init": init}
    for name, value in (("split_labels", split_labels), ("ambiguity", ambiguity),
                        ("observed", observed)):
        if value is not None and name in inspect.signature(refinement.fit).parameters:
            extra[name] = value
    out = refinement.fit(seq, split_state_symbol, random_state, **extra)
    if isinstance(out, CloneFit):
        warnings.warn(f"{type(refinement).__name__}.fit returned a CloneFit; since 0.3 a "
                      "refinement's fit returns self with labels_, state_symbol_ and info_ set "
                      "(a CloneFit is refused from 0.4)", FutureWarning, stacklevel=3)
        return out
    return CloneFit(out.labels_, out.state_symbol_, dict(getattr(out, "info_", {})))


def _settings(refinement):
    """A built-in refinement's checked settings (:mod:`topomap.core.refine.settings`), None for
    a refinement without ``settings()``."""
    settings = getattr(refinement, "settings", None)
    return settings() if callable(settings) else None


def symbol_hint(learner, data, refinement):
    """The ``ambiguity`` a refinement's ``fit`` is given: the share of steps whose symbol phase 1
    may have misread (:func:`~topomap.core.phase1.ambiguity.symbol_ambiguity` under the phase-1
    map's models of the symbols, seeded by ``random_state``), kept as the learner's
    ``symbol_ambiguity_``; None (not computed) unless the refinement uses it
    (``growth.first="auto"`` and a ``fit`` taking ``ambiguity``)."""
    growth = getattr(_settings(refinement), "growth", None)
    if growth is None or growth.first != "auto" or \
            "ambiguity" not in inspect.signature(refinement.fit).parameters:
        return None
    labels, rows = phase1_symbols(learner)
    m = learner.map_phase1_
    learner.symbol_ambiguity_ = symbol_ambiguity(data.X, labels, m.means[rows],
                                                 m.covariances[rows], learner.random_state)
    return learner.symbol_ambiguity_


def phase1_symbols(learner):
    """``(labels, rows)``: every step's K-means symbol (GDS steps ``ns + g``) and the phase-1
    map's state of every symbol, whose observation model is the symbol's: the phase-1 labels
    and states themselves, unless phase 1's states are (symbol, heading) pairs
    (:mod:`~topomap.core.phase1.heading`)."""
    headed = getattr(learner, "_headed", None)
    if headed is None:
        return learner.labels_phase1_, slice(0, learner.n_clusters_)
    return headed.emitted(learner.labels_phase1_), headed.symbol_rows()


def observation_hint(learner, data, refinement, steps=None):
    """The ``observed`` a refinement's ``fit`` is given: None unless its soft rounds take each
    step's evidence from its observation (``reading.temperature`` > 0) and its ``fit`` takes
    ``observed``; else a function returning the (steps, n_symbols) log-densities of the first
    ``steps`` observations (None: all) under the phase-1 map's models of the symbols, computed
    when it is first called (when a soft round runs) and kept for a second call (the soft
    rounds run again after a first hard round cut short is finished)."""
    reading = getattr(_settings(refinement), "reading", None)
    if reading is None or "observed" not in inspect.signature(refinement.fit).parameters or \
            reading.temperature == 0:
        return None
    (_, rows), m = phase1_symbols(learner), learner.map_phase1_
    X = data.X if steps is None else data.X[:steps]
    headed = getattr(learner, "_headed", None)

    @functools.cache
    def loglik():
        chunks = log_density_chunks(np.asarray(X, dtype=np.float64), m.means[rows],
                                    m.covariances[rows])
        out = np.concatenate([logp for _, logp in chunks])
        return out if headed is None else headed.observed(out)
    return loglik


def refinement_hints(learner, data, refinement, steps=None) -> dict:
    """What a refinement's ``fit`` is given beside the symbols (:func:`fit_refinement`):
    ``ambiguity`` (:func:`symbol_hint`) and ``observed`` (:func:`observation_hint`, of the first
    ``steps`` steps)."""
    return {"ambiguity": symbol_hint(learner, data, refinement),
            "observed": observation_hint(learner, data, refinement, steps)}


def refinement_label(refinement) -> str:
    """What map.json stores as ``info["refine"]``: the refinement's :meth:`provenance` when it
    has one (the built-ins), else its ``repr``."""
    provenance = getattr(refinement, "provenance", None)
    return provenance() if callable(provenance) else repr(refinement)


def within_told_size(clusters, stopping, n_gds: int):
    """A cluster-count policy that searches a range (``min_ns`` .. ``max_ns``, as
    :class:`~topomap.core.phase1.clustering.BICClusters`) searched only up to the counts a told
    number of states leaves room for (``n_states`` minus the GDS states): a larger count could
    not be split to that size.  The policy itself is not changed (its repr, kept in the map, is
    the one given)."""
    if not isinstance(stopping, TargetStates):
        return clusters
    low, high = getattr(clusters, "min_ns", None), getattr(clusters, "max_ns", None)
    room = stopping.n_states - n_gds
    if low is None or high is None or not low <= room < high:
        return clusters
    searched = copy.copy(clusters)
    searched.max_ns = room
    return searched
