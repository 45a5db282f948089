"""Logs read one at a time: a folder or a list of recordings, walked in chunks of steps.

:class:`Logs` stands for a set of recordings that together may be larger than memory: a folder
(every ``.npz``, ``.csv``, ``.csv.gz`` and ``.bag`` file and every ROS 2 bag folder in it, in name
order), a list of such paths, or a list of :class:`~topomap.core.data.trajectory.Trajectory`
objects.  Each log is one episode (or its own ``lengths``).  Nothing is read until asked:

* :meth:`Logs.survey` reads what a fit must know before the observations -- every log's steps,
  episode lengths, observation width, actions and GDS -- without the observations of an
  ``.npz`` log (their array header only);
* :meth:`Logs.rows` gives the steps ``[start, stop)`` of one log as float64 observations,
  actions and GDS ids.  The observations of an ``.npz`` log written without compression (as
  :func:`~topomap.core.data.trajectory.save_trajectory` writes large ones) are mapped from the
  file, so that a chunk costs its own rows only; any other log is read whole, one log at a time.

Action and GDS names are made consistent across logs: a log with ``action_names`` has its ids
renumbered to the names' order of first appearance over the logs (the same for ``gds_names``).
Every problem is a one-line ValueError naming the file.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .trajectory import Trajectory, load_trajectory

__all__ = ["Logs", "LogInfo", "log_paths", "LOG_SUFFIXES", "CHUNK_STEPS"]

#: the file names a folder's logs end in (ROS 2 bags are folders holding a metadata.yaml)
LOG_SUFFIXES = (".npz", ".csv", ".csv.gz", ".bag")
#: steps per chunk: 2**20 steps of 15 features are 126 MB of float64 observations
CHUNK_STEPS = 1 << 20


def _is_log(path: Path) -> bool:
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.name.lower().endswith(LOG_SUFFIXES)


def log_paths(source) -> list[Path]:
    """The logs of ``source``: a folder (its logs in name order), one path, or a list of paths."""
    if isinstance(source, (str, Path)):
        path = Path(source)
        if path.is_dir() and not (path / "metadata.yaml").is_file():
            found = sorted((p for p in path.iterdir() if _is_log(p)), key=lambda p: p.name)
            if not found:
                raise ValueError(f"log folder {path} holds no logs (files ending in "
                                 f"{', '.join(LOG_SUFFIXES)} or ROS 2 bag folders)")
            return found
        if not path.exists():
            raise ValueError(f"log {path} does not exist")
        return [path]
    try:
        paths = [Path(p) for p in source]
    except TypeError:
        kinds = sorted({type(p).__name__ for p in source})
        raise ValueError(f"logs must be paths or Trajectory objects (not mixed), got "
                         f"{', '.join(kinds)}") from None
    if not paths:
        raise ValueError("the list of logs is empty")
    for p in paths:
        if not p.exists():
            raise ValueError(f"log {p} does not exist")
    return paths


@dataclass
class LogInfo:
    """What :meth:`Logs.survey` reads of one log: its steps, episode lengths, observation
    width, actions (ids as the log numbers them) and GDS ids."""

    name: str
    steps: int
    lengths: np.ndarray
    n_features: int
    max_action: int
    n_plain: int
    gds_ids: np.ndarray
    action_names: list | None
    gds_names: list | None


def _npz_member(path: Path, name: str):
    """``(offset, shape, dtype, fortran)`` of the array ``name`` stored uncompressed in the
    ``.npz`` file ``path``, or None (compressed, missing or unreadable)."""
    try:
        with zipfile.ZipFile(path) as z:
            info = z.getinfo(f"{name}.npy")
            if info.compress_type != zipfile.ZIP_STORED:
                return None
            with z.open(info) as fh:
                version = np.lib.format.read_magic(fh)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                shape, fortran, dtype = read(fh)
                header = fh.tell()
        with open(path, "rb") as raw:  # the member's data start: past its local file header
            raw.seek(info.header_offset + 26)
            n, m = np.frombuffer(raw.read(4), dtype="<u2")
        return info.header_offset + 30 + int(n) + int(m) + header, shape, dtype, fortran
    except (KeyError, OSError, ValueError, zipfile.BadZipFile):
        return None


class Logs:
    """A set of logs read one at a time (see the module docstring).

    Parameters
    ----------
    source : path, or an iterable of paths or of Trajectory
        A folder of logs, one log, or several in the order to learn them (trajectories given
        are held as they are: a folder or paths keep only one log in memory at a time).
    rosbag : dict, optional
        The arguments of :func:`topomap.read_rosbag` (topics, ...) for the bags among the logs.
    chunk_steps : int
        The steps of a chunk (:meth:`chunks`).
    """

    def __init__(self, source, *, rosbag: dict | None = None, chunk_steps: int = CHUNK_STEPS):
        items = None if isinstance(source, (str, Path)) else list(source)
        if items and all(isinstance(t, Trajectory) for t in items):
            self.paths, self._given = [None] * len(items), items
        else:
            self.paths, self._given = log_paths(source if items is None else items), None
        self.rosbag = dict(rosbag or {})
        self.chunk_steps = int(chunk_steps)
        self._cache: tuple[int, Trajectory] | None = None
        self._remap: dict[int, tuple] = {}

    def __len__(self) -> int:
        return len(self.paths)

    def name(self, i: int) -> str:
        return f"trajectory {i}" if self.paths[i] is None else str(self.paths[i])

    def __getstate__(self):  # what a worker receives: no log read so far
        return dict(vars(self), _cache=None)

    # ------------------------------------------------------------------ whole logs
    def load(self, i: int) -> Trajectory:
        """Log ``i`` as a :class:`Trajectory` (read once and kept until another is read)."""
        if self._cache is not None and self._cache[0] == i:
            return self._cache[1]
        if self._given is not None:
            traj = self._given[i]
        else:
            path = self.paths[i]
            is_bag = path.is_dir() or path.suffix.lower() == ".bag"
            if is_bag:
                from .rosbag import read_rosbag
                if not {"observation_topic", "action_topic"} <= set(self.rosbag):
                    raise ValueError(f"log {path} is a ROS bag: give the bags' observation_topic "
                                     "and action_topic (rosbag=dict(...))")
                traj = read_rosbag(path, **self.rosbag)
            else:
                traj = load_trajectory(path)
        self._cache = (i, traj)
        return traj

    def survey(self, i: int) -> LogInfo:
        """What a fit needs of log ``i`` before its observations (see :class:`LogInfo`)."""
        path = self.paths[i]
        if path is not None and path.suffix.lower() == ".npz":
            member = _npz_member(path, "observations")
            if member is not None and len(member[1]) == 2:
                return self._survey_npz(i, path, member[1])
        traj = self.load(i)
        return _info(self.name(i), traj.observations.shape, traj.actions, traj.gds, traj.lengths,
                     traj.action_names, traj.gds_names)

    def _survey_npz(self, i, path, shape) -> LogInfo:
        try:
            with np.load(path, allow_pickle=False) as data:
                small = {k: data[k] for k in data.files if k != "observations"}
        except Exception as exc:  # noqa: BLE001 -- any unreadable file: one line naming it
            raise ValueError(f"trajectory file {path} is not a valid .npz file: "
                             f"{' '.join(str(exc).split())}") from None
        if "actions" not in small:
            raise ValueError(f"trajectory file {path} lacks the array(s) actions")
        # checked as a Trajectory would be, with a one-column stand-in for the observations
        stand_in = np.zeros((shape[0], 1))
        try:
            traj = Trajectory(stand_in, small["actions"], gds=small.get("gds"),
                              lengths=small.get("lengths"), action_names=small.get("action_names"),
                              gds_names=small.get("gds_names"))
        except ValueError as exc:
            raise ValueError(f"trajectory file {path}: {exc}") from None
        return _info(self.name(i), shape, traj.actions, traj.gds, traj.lengths,
                     traj.action_names, traj.gds_names)

    # ------------------------------------------------------------------ chunks
    def set_ids(self, i: int, actions: np.ndarray | None, gds: np.ndarray | None) -> None:
        """Renumber log ``i``'s action and GDS ids when read (``actions[old] = new``; None: as
        they are): names made consistent across logs by the caller."""
        self._remap[i] = (actions, gds)

    def chunks(self, i: int, steps: int) -> list[tuple[int, int]]:
        """The ``(start, stop)`` of the chunks of log ``i`` (of ``steps`` steps)."""
        return [(a, min(a + self.chunk_steps, steps)) for a in range(0, steps, self.chunk_steps)]

    def rows(self, i: int, start: int, stop: int):
        """``(X (n, D) float64, actions (n,) int64, gds (n,) int64)`` of the steps
        ``[start, stop)`` of log ``i`` (ids renumbered by :meth:`set_ids`)."""
        path = self.paths[i]
        member = None
        if path is not None and path.suffix.lower() == ".npz" and self._cache_index() != i:
            member = _npz_member(path, "observations")
        if member is not None and len(member[1]) == 2:
            offset, shape, dtype, fortran = member
            X = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape,
                          order="F" if fortran else "C")
            X = np.array(X[start:stop], dtype=np.float64)
            u, g = self._small(i, path)
        else:
            traj = self.load(i)
            X = np.asarray(traj.observations[start:stop], dtype=np.float64)
            u = traj.actions
            g = traj.gds if traj.gds is not None else np.full(u.size, -1, dtype=np.int64)
        if not np.all(np.isfinite(X)):
            raise ValueError(f"log {self.name(i)}: observations contain NaN or inf")
        u, g = u[start:stop], g[start:stop]
        acts, ids = self._remap.get(i, (None, None))
        if acts is not None:
            u = acts[u]
        if ids is not None:
            g = np.where(g >= 0, ids[np.maximum(g, 0)], -1)
        return X, u, g

    def plain_rows(self, i: int, picks: np.ndarray):
        """The float64 observations of log ``i``'s non-GDS rows at the sorted positions
        ``picks`` (among those rows), read from the file alone where its observations are
        stored without compression; None otherwise (read the chunks)."""
        path = self.paths[i]
        member = None if path is None or path.suffix.lower() != ".npz" else _npz_member(
            path, "observations")
        if member is None or len(member[1]) != 2 or self._remap.get(i, (None, None))[1] is not None:
            return None
        offset, shape, dtype, fortran = member
        _, g = self._small(i, path)
        rows = np.flatnonzero(g < 0)[picks]
        X = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape,
                      order="F" if fortran else "C")
        out = np.array(X[rows], dtype=np.float64)
        if not np.all(np.isfinite(out)):
            raise ValueError(f"log {self.name(i)}: observations contain NaN or inf")
        return out

    def _cache_index(self):
        return None if self._cache is None else self._cache[0]

    def _small(self, i: int, path: Path):
        """Log ``i``'s actions and GDS ids (kept while its chunks are read)."""
        kept = getattr(self, "_small_cache", None)
        if kept is not None and kept[0] == i:
            return kept[1], kept[2]
        with np.load(path, allow_pickle=False) as data:
            u = np.asarray(data["actions"]).astype(np.int64)
            g = (np.asarray(data["gds"]).astype(np.int64) if "gds" in data.files
                 else np.full(u.size, -1, dtype=np.int64))
        self._small_cache = (i, u, g)
        return u, g


def _info(name, shape, actions, gds, lengths, action_names, gds_names) -> LogInfo:
    T = int(shape[0])
    plain = T if gds is None else int(np.count_nonzero(gds < 0))
    ids = np.empty(0, dtype=np.int64) if gds is None else np.unique(gds[gds >= 0])
    return LogInfo(name, T, np.array([T]) if lengths is None else np.asarray(lengths),
                   int(shape[1]), int(actions.max()), plain, ids, action_names, gds_names)
