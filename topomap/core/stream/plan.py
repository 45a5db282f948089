"""The survey of a streamed fit: what the logs hold before any observation is read (steps,
episodes, width, actions, GDS) and the names made consistent across them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.logs import LogInfo

__all__ = ["Plan", "make_plan", "survey_job"]


def survey_job(logs, i: int) -> LogInfo:
    return logs.survey(i)


@dataclass
class Plan:
    """Every log's :class:`~topomap.core.data.logs.LogInfo` and what follows for the fit."""

    infos: list
    n_actions: int
    action_names: list | None
    gds_names: list | None
    gds_ids: np.ndarray

    @property
    def steps(self) -> np.ndarray:
        return np.array([info.steps for info in self.infos], dtype=np.int64)

    @property
    def lengths(self) -> np.ndarray:
        return np.concatenate([info.lengths for info in self.infos]).astype(np.int64)

    @property
    def n_plain(self) -> np.ndarray:
        return np.array([info.n_plain for info in self.infos], dtype=np.int64)

    @property
    def n_features(self) -> int:
        return self.infos[0].n_features


def _names(infos, field: str, given, logs):
    """Names consistent over the logs: ``(names, {log: old id -> new id})``.  ``given`` fixes
    them; otherwise the logs' own, in order of first appearance (every log must have names if
    one has)."""
    own = [getattr(info, field) for info in infos]
    if given is None and all(n is None for n in own):
        return None, {}
    names = list(given) if given is not None else []
    remap = {}
    for i, log_names in enumerate(own):
        if log_names is None:
            if given is None:
                raise ValueError(f"log {logs.name(i)} has no {field} while log "
                                 f"{logs.name(own.index(next(n for n in own if n)))} has them")
            continue
        if given is None:
            names += [n for n in log_names if n not in names]
        unknown = [n for n in log_names if n not in names]
        if unknown:
            raise ValueError(f"log {logs.name(i)}: {field} {unknown[0]!r} is not one of the "
                             f"{field} given")
        remap[i] = np.array([names.index(n) for n in log_names], dtype=np.int64)
    return names, remap


def make_plan(logs, infos, n_actions, action_names, gds_names) -> Plan:
    """Check the logs against each other (one observation width), make their names
    consistent (:meth:`~topomap.core.data.logs.Logs.set_ids`) and size the actions."""
    first = infos[0]
    for i, info in enumerate(infos):
        if info.n_features != first.n_features:
            raise ValueError(f"log {logs.name(i)} has observations of {info.n_features} "
                             f"features, log {logs.name(0)} of {first.n_features}")
    acts, act_map = _names(infos, "action_names", action_names, logs)
    gnames, gds_map = _names(infos, "gds_names", gds_names, logs)
    for i in set(act_map) | set(gds_map):
        logs.set_ids(i, act_map.get(i), gds_map.get(i))
    top = max(int(act_map[i][:info.max_action + 1].max()) if i in act_map else info.max_action
              for i, info in enumerate(infos))
    A = top + 1 if n_actions is None else int(n_actions)
    if acts is not None:
        A = max(A, len(acts)) if n_actions is None else A
        if len(acts) != A:
            raise ValueError(f"action_names has {len(acts)} names but n_actions is {A}")
    if top >= A:
        raise ValueError(f"actions use id {top} but n_actions is {A}")
    ids = [gds_map[i][info.gds_ids] if i in gds_map else info.gds_ids
           for i, info in enumerate(infos)]
    gds_ids = np.unique(np.concatenate(ids)) if ids else np.empty(0, dtype=np.int64)
    if gnames is not None and gds_ids.size and gds_ids.max() >= len(gnames):
        raise ValueError(f"gds id {int(gds_ids.max())} is out of range: only {len(gnames)} "
                         "gds_names are given")
    return Plan(infos, A, acts, gnames, gds_ids.astype(np.int64))


def read_logs(source, *, rosbag: dict | None = None):
    """Every log of ``source`` (a folder or a list, as :class:`~topomap.core.data.logs.Logs`
    takes) read into one :class:`~topomap.Trajectory` in memory, each log an episode (or its
    own ``lengths``), names made consistent; places and positions kept when every log has
    them.  What ``topomap data=file data.path=<folder>`` learns from."""
    from ..data.logs import Logs
    from ..data.trajectory import Trajectory

    logs = Logs(source, rosbag=rosbag)
    plan = make_plan(logs, [logs.survey(i) for i in range(len(logs))], None, None, None)
    parts = [logs.rows(i, 0, info.steps) + (logs.load(i),) for i, info in enumerate(plan.infos)]
    places = [p[3].places for p in parts]
    positions = [p[3].positions for p in parts]
    shapes = {q.shape[1] for q in positions if q is not None}
    return Trajectory(
        np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
        gds=np.concatenate([p[2] for p in parts]) if plan.gds_ids.size else None,
        places=None if any(q is None for q in places) else np.concatenate(places),
        positions=(np.concatenate(positions) if all(q is not None for q in positions)
                   and len(shapes) == 1 else None),
        lengths=plan.lengths if len(parts) > 1 or len(plan.lengths) > 1 else None,
        action_names=plan.action_names, gds_names=plan.gds_names,
        meta={"logs": [logs.name(i) for i in range(len(logs))]})
