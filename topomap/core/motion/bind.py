"""The map a continuous log's branch made, bound to the learner: what
:func:`~topomap.core.motion.learn.fit_places` and :func:`~topomap.core.motion.robot_fit.fit_robot`
both end with."""

from __future__ import annotations

import time
from dataclasses import asdict, replace

__all__ = ["bind_places"]


def bind_places(learner, m, labels, info: dict, settings, start: float) -> bool:
    """Make ``m`` (places or view clusters; ``labels`` the state of every step) ``learner``'s
    map: ``motion_info_`` is ``info``, ``entropies_`` gains the stage ``"places"``, ``map_`` keeps
    the split map's info with the motion settings (``scan_odometry`` only where off, its
    default on: a map keeps the bytes it had before the setting) and ``info``,
    ``timings_["places"]`` the seconds since ``start`` (``time.perf_counter``); the ``refine``
    callback is called; True."""
    learner.motion_info_ = info
    learner.entropies_.append(dict(m.entropies(), n_states=m.n_states, stage="places",
                                   iteration=len(learner.split_history_) + 1))
    learner.labels_ = labels
    motion = asdict(settings)
    if motion["scan_odometry"]:
        del motion["scan_odometry"]
    learner.map_ = replace(m, entropy_history=learner.entropies_, info=dict(
        learner.map_split_.info, motion=motion, motion_info=info))
    learner.timings_["places"] = time.perf_counter() - start
    learner._emit("refine", labels=labels, entropies=learner.entropies_[-1], map=learner.map_)
    return True
