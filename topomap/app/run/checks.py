"""What a run checks once its parts are built and its data is read, beyond the config's checks:
the cluster counts a told size leaves room for, enough steps per K-means symbol, and a told
number of states the split did not reach."""

from __future__ import annotations

import logging
import os

from ...core.split.stopping import TargetStates
from ..compose.registry import Parts

log = logging.getLogger("topomap")

__all__ = ["check_before_data", "check_room_for_clusters", "check_cluster_count",
           "check_state_count", "report_missed_target", "available_memory", "STEPS_PER_SYMBOL"]


def check_before_data(cfg: dict, parts: Parts) -> None:
    """What a run can check before it has data: the run's ``seed``, ``output.min_prob``, and
    for a simulated walk the memory its steps need and the number of states they can hold
    (:func:`check_walk_memory`, :func:`check_state_count`)."""
    seed = cfg.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed={seed} must be a non-negative integer")
    min_prob = (cfg.get("output") or {}).get("min_prob", 0.8)
    if not 0 <= min_prob < 1:
        raise ValueError(f"output.min_prob={min_prob} must be a probability in [0, 1): arcs "
                         "are drawn where P(x'|x,u) > output.min_prob")
    data = parts.data
    if getattr(data, "simulates", False) and parts.env is not None:
        walk = data.steps(parts.env)
        check_walk_memory(parts, walk, walk + data.heldout_steps_in(parts.env))
        check_state_count(parts.stop, walk)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux's ``MemAvailable``), None if not
    known."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def observation_size(env) -> int | None:
    """Features per step of the world ``env``: its ``n_features`` where it says it without
    walking (the arena), else those of a two-step probe walk; None when the probe's own
    checks refuse it (a sensor judges the whole walk, which the run then senses)."""
    import numpy as np

    from ...core.checks import ParameterError
    from ...worlds.explorers import RandomExplorer

    size = getattr(env, "n_features", None)
    if size is not None:
        return int(size)
    try:
        probe = env.simulate(2, RandomExplorer(), np.random.default_rng(0))
    except ParameterError:
        return None
    return int(probe.observations.shape[1])


def check_walk_memory(parts: Parts, walk: int, steps: int) -> None:
    """Refuse a simulated walk whose observations alone would not fit in the memory available,
    saying how much it needs (:func:`observation_size` gives the size of a step)."""
    free = available_memory()
    width = None if free is None else observation_size(parts.env)
    if width is None:
        return
    per_step = 8 * (width + 5)  # observations, position, ids
    need = steps * per_step
    if need > free:
        gib = 2 ** 30
        raise ValueError(
            f"data.n_steps={walk} needs at least {need / gib:.0f} GiB for the "
            f"walk alone ({steps} steps, held-out walk included, of {width} features) and "
            f"{free / gib:.0f} GiB of memory is available; give at most "
            f"data.n_steps={max(1, free // per_step // 2)} (with data.heldout_steps=0 no "
            "held-out walk is simulated)")


def check_state_count(stop, n_steps: int) -> None:
    """Refuse a told number of states above half the steps (``stop.n_states``): most states
    would hold a single step, whose transitions cannot be estimated, and the split would run
    for long to no use."""
    if isinstance(stop, TargetStates) and 2 * stop.n_states > n_steps:
        raise ValueError(f"stop.n_states={stop.n_states} is more than half of the {n_steps} "
                         "steps: most states would hold a single step, whose transitions "
                         f"cannot be estimated; give at most stop.n_states={n_steps // 2}, or "
                         "more steps")


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
