"""The learner's parameters made into the components of a fit -- the cluster-count policy, the
observation metric, the split criterion, the stopping rule and the refinement -- with every
error naming the learner's own parameter (:func:`naming`)."""

from __future__ import annotations

import copy
from contextlib import contextmanager

from .checks import ParameterError, check_count
from .phase1.clustering import FixedClusters, make_metric
from .refine.methods import REFINEMENTS
from .size import AutoStates
from .split.criteria import CRITERIA
from .split.stopping import TargetStates

__all__ = ["make_components", "make_refinement", "naming", "within_told_size"]

#: the learner's own parameter behind a parameter of a component it makes itself
#: (``FixedClusters(n_clusters)``, ``TargetStates(n_states)``)
_MADE_FROM = {("clusters", "ns"): "n_clusters", ("stopping", "n_states"): "n_states"}


@contextmanager
def naming(learner, arg: str, **own: str):
    """Name the parameter of a :class:`ParameterError` raised inside as ``learner``'s:
    ``<arg>.<param>`` for a parameter of the component passed as ``arg`` (``clusters.ns``),
    the learner's own parameter when the learner made the component from it
    (``n_clusters``), and ``own[param]`` for a setting passed on under another name
    (``method`` is ``phase1``)."""
    try:
        yield
    except ParameterError as err:
        if err.param in own:
            name = own[err.param]
        elif getattr(learner, arg) is None:
            name = _MADE_FROM.get((arg, err.param), err.param)
        else:
            name = f"{arg}.{err.param}"
        raise err.renamed(name) from err.__cause__


def make_components(learner):
    """``(clusters, metric, criterion, stopping)`` of a fit by ``learner``, its other settings
    checked; a stopping rule may keep state during a fit (e.g. its limit), so a fit works on a
    copy and the parameter itself is never changed."""
    with naming(learner, "clusters"):
        clusters = (learner.clusters if learner.clusters is not None
                    else FixedClusters(learner.n_clusters))
    if learner.stopping is not None:
        stopping = copy.deepcopy(learner.stopping)
    else:
        stopping = (AutoStates() if learner.n_states == "auto"
                    else TargetStates(learner.n_states))
    criterion = learner.criterion
    if isinstance(criterion, str):
        if criterion not in CRITERIA:
            raise ParameterError("criterion", f"{criterion!r} is unknown; choose one of "
                                              f"{', '.join(sorted(CRITERIA))}")
        criterion = CRITERIA[criterion]()
    if learner.refined_size not in ("told", "free"):
        raise ParameterError("refined_size",
                             f"must be 'told' or 'free', got {learner.refined_size!r}")
    if learner.covariance_type not in ("diag", "full"):
        raise ParameterError("covariance_type",
                             f"must be 'diag' or 'full', got {learner.covariance_type!r}")
    if not (isinstance(learner.reg_covar, (int, float)) and learner.reg_covar > 0):
        raise ParameterError("reg_covar", f"must be a positive number, got {learner.reg_covar!r}")
    check_count(learner.n_init, "n_init")
    check_count(learner.sample_size, "sample_size", allow_none=True)
    learner._online_settings()
    return clusters, make_metric(learner.metric), criterion, stopping


def make_refinement(refine):
    """The refinement object of the learner's ``refine`` (None: the paper's method alone)."""
    if isinstance(refine, str):
        if refine == "none":
            return None
        if refine not in REFINEMENTS:
            raise ParameterError("refine", f"{refine!r} is unknown; choose one of none, "
                                           f"{', '.join(sorted(REFINEMENTS))}")
        return REFINEMENTS[refine]()
    if refine is not None and not callable(getattr(refine, "fit", None)):
        raise ParameterError("refine", f"{refine!r} has no fit(sequence, split_state_symbol, "
                                       "random_state) method")
    return refine


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
