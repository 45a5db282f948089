"""The robot mode's metric map as a file: ``robot_map.npz`` (numpy's npz, no pickle), written
beside ``map.json`` by a run learned with ``learner.motion.mode=robot``, so that a walk can be
placed on it later by its own odometry (:func:`~topomap.core.motion.robot.place_walk`)."""

from __future__ import annotations

from dataclasses import MISSING, fields
from pathlib import Path

import numpy as np

from ..data.atomic import atomic_write
from .robot import RobotMap

__all__ = ["save_robot_map", "load_robot_map"]

#: the file's format version (an integer; a file of another version is refused)
FORMAT = 1


def save_robot_map(model: RobotMap, path) -> Path:
    """Write ``model`` to ``path`` (npz: one array per field but those that are None,
    ``format``), atomically."""
    arrays = {f.name: np.asarray(getattr(model, f.name)) for f in fields(RobotMap)
              if getattr(model, f.name) is not None}

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, format=np.int64(FORMAT), **arrays)
    return atomic_write(path, write)


def load_robot_map(path) -> RobotMap:
    """The :class:`~topomap.core.motion.robot.RobotMap` in ``path`` (written by
    :func:`save_robot_map`); a missing field, a wrong shape or another format is one
    ``ValueError`` naming the file and the field."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except (OSError, ValueError) as err:
        raise ValueError(f"{path}: not a robot map file ({err})") from None
    if int(data.get("format", -1)) != FORMAT:
        raise ValueError(f"{path}: format {data.get('format')} is not {FORMAT}")
    missing = [f.name for f in fields(RobotMap)
               if f.name not in data and f.default is MISSING]
    if missing:
        raise ValueError(f"{path}: {missing[0]} is missing")
    # a field with a default (``evidence``) may be absent: the map then weighs every beam fully
    model = RobotMap(**{f.name: (float(data[f.name]) if data[f.name].ndim == 0
                                 else data[f.name]) for f in fields(RobotMap) if f.name in data})
    _check(model, path)
    return model


def _check(model: RobotMap, path) -> None:
    """Refuse a robot map whose arrays do not fit together, naming the field."""
    n = model.n_cells
    shapes = {"centres": model.centres.shape == (n, 2), "scans": model.scans.ndim == 2
              and model.scans.shape[0] == n, "log_prior": model.log_prior.shape == (n,),
              "place": model.place.shape == (n,),
              "successor_ptr": model.successor_ptr.shape == (n + 1,)}
    for name, ok in shapes.items():
        if not ok:
            raise ValueError(f"{path}: {name} has shape {getattr(model, name).shape} for "
                             f"{n} cells")
    if not 0 < model.evidence <= 1:
        raise ValueError(f"{path}: evidence {model.evidence} is not in (0, 1]")
    B = model.scans.shape[1]
    if model.beam_order is not None and not np.array_equal(np.sort(model.beam_order),
                                                           np.arange(B)):
        raise ValueError(f"{path}: beam_order is not an order of the scans' {B} beams")
    if model.successor_idx.size and (model.successor_idx.min() < 0
                                     or model.successor_idx.max() >= n):
        raise ValueError(f"{path}: successor_idx names a cell outside 0..{n - 1}")
