"""Trajectories: what a robot saw and did, step by step, and the files that hold them.

A :class:`Trajectory` is the learner's input: ``T`` observation vectors, the action taken at each
step, optionally the globally distinctive state (GDS) recognised at each step and the robot's own
odometry, and, for simulated or annotated data, the ground truth (place id and position).  Several
episodes may be stored back to back; ``lengths`` gives their sizes and no transition is counted
across an episode boundary.

Two file formats are read and written (``docs/file-formats.md`` describes them in full):

``.npz``
    arrays ``observations`` (T, D) float, ``actions`` (T,) int and optionally ``gds`` (T,) int,
    ``places`` (T,) int, ``positions`` (T, 2 or 3) float, ``odometry`` (T, 3) float, ``lengths``
    (E,) int, ``action_names`` and ``gds_names`` (string arrays).  Loaded with
    ``allow_pickle=False``.
``.csv``
    a header row ``o0,...,o{D-1},action[,gds][,place][,x,y[,z]][,odom_x,odom_y,odom_theta]
    [,episode]`` and one row per step;
    actions given by name (``north``) get ids in order of first appearance, the names kept.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from ..stats import episode_masks
from .atomic import atomic_write
from .csv_file import read_csv
from .odometry import ODOMETRY_COLUMNS, check_odometry
from .positions import POSITION_COLUMNS, check_positions

__all__ = ["Trajectory", "load_trajectory", "save_trajectory", "check_sequences",
           "as_float_observations"]


def _as_array(values, name: str) -> np.ndarray:
    """``np.asarray(values)``, or a ValueError naming ``name`` when the nested lists are ragged."""
    try:
        return np.asarray(values)
    except (ValueError, TypeError):
        text = " ".join(repr(values).split())
        raise ValueError(f"{name} must be a rectangular array (nested lists of equal lengths), "
                         f"got {text if len(text) <= 60 else text[:57] + '...'}") from None


#: the largest magnitude an id, count or length may have (it must fit an int64 exactly)
_INT_LIMIT = 2**53


def _as_int_array(values, name: str, length: int | None = None) -> np.ndarray:
    """Return ``values`` as a 1-D int64 array, or raise a ValueError naming ``name``."""
    arr = _as_array(values, name)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {arr.shape}")
    if length is not None and arr.shape[0] != length:
        raise ValueError(
            f"{name} has {arr.shape[0]} entries but observations has {length} rows; "
            "they must have the same length"
        )
    if arr.dtype.kind == "b":
        raise ValueError(f"{name} must hold integers, got booleans")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must hold integers, found NaN or inf")
        if not np.all(arr == np.round(arr)):
            bad = int(np.flatnonzero(arr != np.round(arr))[0])
            raise ValueError(f"{name} must hold integers, found {arr[bad]!r} at index {bad}")
    elif arr.dtype.kind not in "iu":
        raise ValueError(f"{name} must hold integers, got values of type {arr.dtype}")
    wide = arr.astype(np.float64) if arr.dtype.kind == "f" else arr  # float16 cannot hold 2**53
    if wide.size and (wide.max() > _INT_LIMIT or wide.min() < -_INT_LIMIT):
        big = (wide.max() if wide.max() > _INT_LIMIT else wide.min()).item()
        raise ValueError(f"{name} holds {big!r}, beyond the supported range of +-2**53")
    return arr if arr.dtype == np.int64 else arr.astype(np.int64)


def as_float_observations(observations, keep_float32: bool = False) -> np.ndarray:
    """``observations`` as a float64 array, copied only when it is not one already: a contiguous
    float64 array is used as it is (at T = 10^7, D = 15 a copy would be 1.2 GB).
    ``keep_float32``: a contiguous float32 array is used as it is too (half the memory; what
    :meth:`~topomap.core.learner.MapLearner.fit` takes), any other input becomes float64."""
    X = _as_array(observations, "observations")
    if X.dtype.kind not in "fiub":
        raise ValueError(f"observations must be numbers, got values of type {X.dtype}")
    contiguous = X.flags.c_contiguous or X.flags.f_contiguous
    kept = (np.float64, np.float32) if keep_float32 else (np.float64,)
    return X if X.dtype in kept and contiguous else X.astype(np.float64)


_BLOCK_ROWS = 1 << 16


def _check_values(X: np.ndarray) -> None:
    """A ValueError naming the rows that hold NaN or inf (how many, the first), or else the
    first value so large that the squares the learner sums over the observations (variances,
    K-means distances, summed over T x D values) overflow their float type: every ``|x|`` must
    stay below ``sqrt(max float / (T D)) / 2`` (about 7e148 at T D = 1e8 in float64, 9e14 in
    float32, where K-means computes its distances in float32).  One pass, block by block: each
    block's sum screens it for NaN and inf (an overflowing sum is re-checked row by row), its
    largest ``|x|`` is read while it is in the cache (no (T, D) temporary)."""
    limit = 0.5 * np.sqrt(np.finfo(X.dtype).max / max(X.size, 1))
    bad, big = [], None
    for start in range(0, X.shape[0], _BLOCK_ROWS):
        block = X[start:start + _BLOCK_ROWS]
        if not np.isfinite(block.sum()):
            rows = np.flatnonzero(~np.all(np.isfinite(block), axis=1))
            if rows.size:
                bad.append(rows + start)
                continue
        if not bad and big is None and max(block.max(), -block.min()) >= limit:
            big = start
    if bad:
        rows = np.concatenate(bad)
        raise ValueError(
            f"observations contain NaN or inf in {rows.size} row(s), first at step {int(rows[0])}")
    if big is not None:
        block = X[big:big + _BLOCK_ROWS]
        step, column = np.unravel_index(np.argmax(np.abs(block)), block.shape)
        raise ValueError(
            f"observations hold {block[step, column]:.3g} (step {big + int(step)}, column "
            f"{int(column)}), too large: the variances and distances the learner sums over these "
            f"{X.shape[0]} x {X.shape[1]} values would overflow {X.dtype} (|x| must stay below "
            f"{limit:.2g}); rescale the observations (e.g. to SI units)")


def check_sequences(observations, actions, gds=None, lengths=None, *, min_length: int = 3,
                    keep_float32: bool = False):
    """Validate learner input and return it as arrays ``(X, u, gds, lengths)``.

    Every problem is reported as a :class:`ValueError` whose message names the argument.
    ``gds`` defaults to all ``-1`` (no GDS) and ``lengths`` to one episode of length ``T``.
    ``X`` is the caller's array when that is contiguous float64 already (not a copy), or
    contiguous float32 with ``keep_float32`` (:func:`as_float_observations`).
    """
    X = as_float_observations(observations, keep_float32)
    if X.ndim == 1:
        raise ValueError(
            f"observations must be a 2-D array (T, D), got a 1-D array of shape {X.shape}; "
            "reshape it with observations.reshape(-1, 1) if it holds a single feature, or "
            "observations.reshape(1, -1) if it is a single step"
        )
    if X.ndim != 2:
        raise ValueError(f"observations must be a 2-D array (T, D), got shape {X.shape}")
    T = X.shape[0]
    if T < min_length:
        raise ValueError(f"observations has {T} steps; at least {min_length} are needed")
    if X.shape[1] == 0:
        raise ValueError("observations has 0 columns; at least one feature is needed")
    _check_values(X)
    u = _as_int_array(actions, "actions", T)
    if u.min() < 0:
        raise ValueError(f"actions must be >= 0, found {int(u.min())} at step {int(np.argmin(u))}")
    if gds is None:
        g = np.broadcast_to(np.int64(-1), (T,))  # read-only, no (T,) array
    else:
        g = _as_int_array(gds, "gds", T)
        if g.min() < -1:
            raise ValueError(
                f"gds ids must be -1 (no GDS) or >= 0, found {int(g.min())} at step {int(np.argmin(g))}"
            )
    if lengths is None:
        L = np.array([T], dtype=np.int64)
    else:
        L = _as_int_array(lengths, "lengths")
        if L.size == 0 or np.any(L <= 0):
            raise ValueError("lengths must be a non-empty list of positive episode lengths")
        if int(L.sum()) != T:
            raise ValueError(f"lengths sum to {int(L.sum())} but observations has {T} steps")
    return X, u, g, L


@dataclass
class FitData:
    """The validated input of one fit (:func:`check_fit_data`)."""

    X: np.ndarray
    u: np.ndarray
    gds: np.ndarray
    lengths: np.ndarray
    n_actions: int
    action_names: list | None
    gds_names: list | None

    @property
    def masks(self):
        return episode_masks(self.X.shape[0], self.lengths)


def check_fit_data(observations, actions, gds, lengths, n_actions, action_names,
                   gds_names) -> FitData:
    """:func:`check_sequences` (float32 observations kept as they are), and the number of
    actions and the names checked against it."""
    X, u, g, L = check_sequences(observations, actions, gds, lengths, keep_float32=True)
    A = int(u.max()) + 1 if n_actions is None else int(n_actions)
    if action_names is not None and n_actions is None:
        A = max(A, len(action_names))
    if u.max() >= A:
        raise ValueError(f"actions use id {int(u.max())} but n_actions is {A}")
    if action_names is not None and len(action_names) != A:
        raise ValueError(f"action_names has {len(action_names)} names but n_actions is {A}")
    if gds_names is not None and g.max() >= len(gds_names):
        raise ValueError(f"gds id {int(g.max())} is out of range: only {len(gds_names)} "
                         "gds_names are given")
    return FitData(X, u, g, L, A, action_names, gds_names)


def _as_names(values, name: str) -> list[str]:
    """A list of names from a sequence (a 1-D array, list or tuple), or a ValueError naming
    ``name``."""
    if isinstance(values, (str, bytes)):
        raise ValueError(f"{name} must be a list of names, got the single string {values!r}")
    arr = _as_array(values, name)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a one-dimensional list of names, got shape {arr.shape}")
    return [str(v) for v in arr.tolist()]


@dataclass
class Trajectory:
    """One or more episodes of observations and actions, with optional labels and ground truth.

    Attributes
    ----------
    observations : (T, D) float array
        The observation of every step.
    actions : (T,) int array
        The action taken at every step, values in ``[0, n_actions)``.
    gds : (T,) int array or None
        GDS id recognised at each step, ``-1`` for none.
    places : (T,) int array or None
        Ground-truth place id of each step.
    positions : (T, 2) or (T, 3) float array or None
        Ground-truth position of each step (metres: x, y and optionally z), used only to score a
        map.
    lengths : (E,) int array or None
        Episode lengths (None: a single episode).
    action_names, gds_names : list of str or None
        The names of the actions and of the GDS ids.
    meta : dict
        Where the steps came from (a world's or a bag's description); not saved in files.
    odometry : (T, 3) float array or None
        The robot's own dead reckoning at each step: x, y (metres) and heading (radians) in its
        odometry frame.  It drifts: input to learning, never the score
        (:mod:`~topomap.core.data.odometry`; a move of more than ``MAX_ODOMETRY_STEP`` metres
        between two steps of an episode is refused).
    """

    observations: np.ndarray
    actions: np.ndarray
    gds: np.ndarray | None = None
    places: np.ndarray | None = None
    positions: np.ndarray | None = None
    lengths: np.ndarray | None = None
    action_names: list[str] | None = None
    gds_names: list[str] | None = None
    meta: dict = field(default_factory=dict)
    odometry: np.ndarray | None = None

    def __post_init__(self):
        X, u, g, L = check_sequences(
            self.observations, self.actions, self.gds, self.lengths, min_length=1
        )
        T = X.shape[0]
        self.observations, self.actions = X, u
        self.gds = None if self.gds is None else g
        self.lengths = None if self.lengths is None else L
        if self.places is not None:
            self.places = _as_int_array(self.places, "places", T)
        if self.positions is not None:
            self.positions = check_positions(self.positions, T)
        if self.odometry is not None:
            self.odometry = check_odometry(self.odometry, T, self.lengths)
        if self.action_names is not None:
            self.action_names = _as_names(self.action_names, "action_names")
            if u.max() >= len(self.action_names):
                raise ValueError(
                    f"actions use id {int(u.max())} but only {len(self.action_names)} "
                    "action_names are given"
                )
        if self.gds_names is not None:
            self.gds_names = _as_names(self.gds_names, "gds_names")
            if g.max() >= len(self.gds_names):
                raise ValueError(
                    f"gds uses id {int(g.max())} but only {len(self.gds_names)} gds_names are given"
                )

    def __len__(self) -> int:
        return int(self.observations.shape[0])

    @property
    def n_actions(self) -> int:
        """Number of actions: ``len(action_names)`` if known, else ``max(actions) + 1``."""
        if self.action_names is not None:
            return len(self.action_names)
        return int(self.actions.max()) + 1


_REQUIRED = ("observations", "actions")
_OPTIONAL = ("gds", "places", "positions", "odometry", "lengths", "action_names", "gds_names")


def _checked(traj: Trajectory, path: Path) -> Trajectory:
    """A validated copy of ``traj``, whose fields may have been changed since it was made."""
    try:
        return Trajectory(**{f.name: getattr(traj, f.name) for f in fields(traj)})
    except ValueError as exc:
        raise ValueError(f"cannot write trajectory file {path}: {exc}") from None


#: ``.npz`` files of trajectories with more observation values than this are not compressed
COMPRESS_LIMIT = 10**7


def save_trajectory(traj: Trajectory, path, *, compress: bool | None = None) -> Path:
    """Write ``traj`` to ``path`` (``.npz`` or ``.csv``); the file appears only when complete.

    ``compress`` (``.npz``): None compresses up to :data:`COMPRESS_LIMIT` observation values
    (80 MB), where it is quick and pays off (MiniGrid's 0/1 views shrink 40-fold); beyond that
    compression costs seconds per 100 MB and saves little on continuous sensor data.

    The trajectory is validated again first, so that no file is written that would not load.
    """
    path = Path(path)
    traj = _checked(traj, path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        arrays = {"observations": traj.observations, "actions": traj.actions}
        for key in _OPTIONAL:
            value = getattr(traj, key)
            if value is not None:
                arrays[key] = np.asarray(value, dtype=str) if key.endswith("names") else value

        if compress is None:  # compression costs seconds per 100 MB and saves little on sensors
            compress = traj.observations.size <= COMPRESS_LIMIT
        save = np.savez_compressed if compress else np.savez

        def write(tmp):
            with open(tmp, "wb") as fh:
                save(fh, **arrays)

    elif suffix == ".csv":
        D = traj.observations.shape[1]
        header = [f"o{i}" for i in range(D)] + ["action"]
        cols = [traj.observations, traj.actions[:, None]]
        if traj.gds is not None:
            header.append("gds")
            cols.append(traj.gds[:, None])
        if traj.places is not None:
            header.append("place")
            cols.append(traj.places[:, None])
        if traj.positions is not None:
            header += POSITION_COLUMNS[:traj.positions.shape[1]]
            cols.append(traj.positions)
        if traj.odometry is not None:
            header += ODOMETRY_COLUMNS
            cols.append(traj.odometry)
        if traj.lengths is not None:
            header.append("episode")
            cols.append(np.repeat(np.arange(traj.lengths.size), traj.lengths)[:, None])
        int_cols = {"action", "gds", "place", "episode"}

        def write(tmp):
            table = np.hstack([np.asarray(c, dtype=np.float64) for c in cols])
            with open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(header)
                for row in table.tolist():
                    w.writerow([int(v) if h in int_cols else repr(v) for h, v in zip(header, row)])

    else:
        raise ValueError(f"trajectory file {path} must end in .npz or .csv, not {suffix!r}")
    atomic_write(path, write)
    return path


def _load_npz(path: Path) -> Trajectory:
    try:
        with np.load(path, allow_pickle=False) as data:
            contents = {k: data[k] for k in data.files}
    except Exception as exc:  # zipfile.BadZipFile, zlib.error, EOFError, pickled objects, ...
        raise ValueError(f"trajectory file {path} is not a valid .npz file (arrays without "
                         f"pickled objects): {' '.join(str(exc).split())}") from None
    missing = [k for k in _REQUIRED if k not in contents]
    if missing:
        raise ValueError(f"trajectory file {path} lacks the array(s) {', '.join(missing)}")
    unknown = sorted(set(contents) - set(_REQUIRED) - set(_OPTIONAL))
    if unknown:
        raise ValueError(f"trajectory file {path} has unknown array(s) {', '.join(unknown)}")
    kwargs = {k: contents[k] for k in _REQUIRED + _OPTIONAL if k in contents}
    try:
        return Trajectory(**kwargs)
    except ValueError as exc:
        raise ValueError(f"trajectory file {path}: {exc}") from None


def _episode_lengths(episode) -> np.ndarray:
    """Episode lengths from a CSV's ``episode`` column (ids that never decrease)."""
    ep = _as_int_array(episode, "episode")
    if np.any(np.diff(ep) < 0):
        raise ValueError("episode ids must not decrease")
    change = np.flatnonzero(np.diff(ep) != 0)
    return np.diff(np.concatenate([[0], change + 1, [ep.size]]))


def load_trajectory(path) -> Trajectory:
    """Read a trajectory from a ``.npz``, ``.csv`` or ``.csv.gz`` file, validating every field."""
    path = Path(path)
    if not path.is_file():
        where = "" if path.is_absolute() else f" (relative to {Path.cwd()})"
        raise ValueError(f"trajectory file {path} does not exist{where}")
    suffix = ".csv" if path.name.lower().endswith(".csv.gz") else path.suffix.lower()
    if suffix == ".npz":
        return _load_npz(path)
    if suffix == ".csv":
        fields = read_csv(path)
        try:
            if "episode" in fields:
                fields["lengths"] = _episode_lengths(fields.pop("episode"))
            return Trajectory(**fields)
        except ValueError as exc:
            raise ValueError(f"trajectory file {path}: {exc}") from None
    raise ValueError(f"trajectory file {path} must end in .npz, .csv or .csv.gz, not {suffix!r}")
