"""What a run checks once its parts are built and its data is read, beyond the config's checks:
the cluster counts a told size leaves room for, enough steps per K-means symbol, and a told
number of states the split did not reach."""

from __future__ import annotations

import logging

from ...core.split.stopping import TargetStates
from ..compose.registry import Parts

log = logging.getLogger("topomap")

__all__ = ["check_room_for_clusters", "check_cluster_count", "report_missed_target",
           "STEPS_PER_SYMBOL"]


def check_room_for_clusters(cfg: dict, parts: Parts) -> None:
    """Say, before any data or BIC, when a told ``stop.n_states`` narrows the cluster counts a
    policy choosing from the data searches (``clusters=bic``: ``min_ns`` .. ``max_ns``, plus the
    world's GDS): :class:`~topomap.MapLearner` searches only the counts it leaves room for.  (A
    told size below ``min_ns`` plus the GDS is refused by the learner's own checks, before
    this.)"""
    most = getattr(parts.clusters, "max_ns", None)
    least = getattr(parts.clusters, "min_ns", None)
    stop = parts.stop
    if most is None or least is None or not isinstance(stop, TargetStates):
        return
    n_gds = int(getattr(parts.env, "n_gds", 0) or 0)
    if least + n_gds <= stop.n_states < most + n_gds:
        log.info("clusters=%s searches %d to %d clusters: stop.n_states=%d leaves room for no "
                 "more%s", cfg["clusters"]["component"], least, stop.n_states - n_gds,
                 stop.n_states, f" beside the {n_gds} GDS" if n_gds else "")


#: fewer steps than this per K-means symbol, on average, and a run warns (see
#: :func:`check_cluster_count`)
STEPS_PER_SYMBOL = 10


def check_cluster_count(ns: int | None, traj) -> None:
    """Refuse ``clusters.ns`` above half the steps K-means clusters (the steps at no GDS): most
    symbols would hold a single step, whose transitions cannot be estimated; warn below
    :data:`STEPS_PER_SYMBOL` steps per symbol on average, where the symbols' observation models
    and transition counts are poorly estimated.  ``ns`` None: the count is chosen from the data
    (``clusters=bic``), nothing to check."""
    if ns is None:
        return
    n = int((traj.gds < 0).sum()) if traj.gds is not None else len(traj)
    if 2 * ns > n:
        raise ValueError(f"clusters.ns={ns} is more than half of the {n} steps to cluster: most "
                         f"symbols would hold a single step, whose transitions cannot be "
                         f"estimated; give at most clusters.ns={n // 2}, or more steps")
    if ns * STEPS_PER_SYMBOL > n:
        log.warning("clusters.ns=%d leaves %.1f steps per symbol on average (%d steps to "
                    "cluster): below %d, the symbols' observation models and transitions are "
                    "poorly estimated; lower clusters.ns or give more steps", ns, n / ns, n,
                    STEPS_PER_SYMBOL)


def report_missed_target(learner) -> None:
    """Warn when the split stopped short of the told number of states, saying why."""
    rule = learner.stop
    told = rule.n_states if isinstance(rule, TargetStates) else None
    made = learner.map_split_.n_states
    if told is not None and made < told:
        log.warning("stop.n_states=%d not reached: the split stopped at %d states (%s)", told,
                    made, learner.stop_reason_)
