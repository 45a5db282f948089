"""Recorded paths: a rat's (shipped with ratinabox) or the user's own, resampled at the sensor rate.

Two recorded rat paths ship with ratinabox (its ``data/`` folder):

``sargolini``
    Sargolini et al. (2006), "Conjunctive representation of position, direction, and velocity in
    entorhinal cortex", Science 312(5774), doi 10.1126/science.1125572: 600 s at 50 Hz in a
    1 x 1 m box.
``tanni``
    Tanni, de Cothi & Barry (2022), "State transitions in the statistically stable place cell
    population correspond to rate of perceptual change", Current Biology 32(16),
    doi 10.1016/j.cub.2022.06.046: 7,323 s at 30 Hz in a 3.5 x 2.5 m box.

A user's path is a ``.npz`` with arrays ``t`` (seconds) and ``pos`` (metres, (N, 2)) --
ratinabox's own layout -- or ``times`` and ``positions``; or a ``.csv`` with the header ``t,x,y``.

A path is resampled every ``dt`` seconds with ratinabox's ``Agent.import_trajectory`` (a cubic
spline through the samples, evaluated at all times at once: no per-step update).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from ...core.checks import ParameterError
from .layouts import Layout, open_box
from .kinematics import isolated_global_rng

__all__ = ["DATASETS", "RecordedPath", "load_path", "bad_path"]

#: the recorded paths that ship with ratinabox, and the box each was recorded in
DATASETS = {"sargolini": (1.0, 1.0), "tanni": (3.5, 2.5)}


def _dataset_file(name: str) -> Path:
    import ratinabox

    return Path(ratinabox.__file__).resolve().parent / "data" / f"{name}.npz"


def bad_path(source, problem: str) -> ParameterError:
    """The error of a bad recorded path: ``path=<source>: <problem>``, naming the parameter."""
    return ParameterError("path", f"={source}: {problem}")


def _read_npz(path: Path) -> tuple:
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except Exception as exc:  # not a zip, pickled objects, truncated
        raise bad_path(path, f"not a valid .npz file: {' '.join(str(exc).split())}") from None
    for t_key, p_key in (("t", "pos"), ("times", "positions")):
        if t_key in arrays and p_key in arrays:
            return arrays[t_key], arrays[p_key]
    raise bad_path(path, f"needs the arrays t and pos (or times and positions), has "
                         f"{', '.join(sorted(arrays)) or 'none'}")


def _read_csv(path: Path) -> tuple:
    try:
        with open(path) as fh:
            header = [h.strip() for h in fh.readline().split(",")]
        table = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise bad_path(path, f"could not be read as CSV: {' '.join(str(exc).split())}") from None
    if header != ["t", "x", "y"]:
        raise bad_path(path, f"must have the header t,x,y, got {','.join(header)}")
    return table[:, 0], table[:, 1:3]


def _checked(times, positions, source: str) -> tuple[np.ndarray, np.ndarray]:
    """Times strictly increasing and finite, positions (N, 2) finite, N >= 4."""
    t = np.asarray(times, dtype=np.float64)
    t = t.reshape(-1) if t.ndim > 1 and t.size == max(t.shape) else t  # a column: (N, 1)
    P = np.asarray(positions, dtype=np.float64)
    if t.ndim != 1:
        raise bad_path(source, f"the times must be one array of N seconds, got shape {t.shape}")
    if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] != t.size:
        raise bad_path(source, f"the positions must have shape ({t.size}, 2) to match the "
                               f"{t.size} times, got {P.shape}")
    if t.size < 4:
        raise bad_path(source, f"has {t.size} samples; at least 4 are needed")
    if not (np.isfinite(t).all() and np.isfinite(P).all()):
        raise bad_path(source, "times and positions must be finite (no NaN or inf)")
    if np.any(np.diff(t) <= 0):
        bad = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise bad_path(source, f"times must increase, but sample {bad} is not later than the "
                               "one before")
    return t - t[0], P


class RecordedPath:
    """A recorded path, ready to be resampled every ``dt`` seconds.

    Parameters
    ----------
    source : str
        ``"sargolini"``, ``"tanni"`` or a ``.npz`` / ``.csv`` file (see the module docstring).
    """

    def __init__(self, source: str):
        from .checks import require_ratinabox

        require_ratinabox()
        self.source = str(source)
        if self.source in DATASETS:
            t, P = _read_npz(_dataset_file(self.source))
        else:
            path = Path(self.source)
            if path.suffix.lower() not in (".npz", ".csv"):
                raise bad_path(self.source, f"is neither a recorded path of ratinabox "
                                            f"({', '.join(DATASETS)}) nor a .npz or .csv file")
            if not path.is_file():
                raise bad_path(path, "does not exist")
            t, P = _read_npz(path) if path.suffix.lower() == ".npz" else _read_csv(path)
        self.times, self.positions = _checked(t, P, self.source)
        self._spline = None

    @property
    def duration(self) -> float:
        """Seconds from the first sample to the last."""
        return float(self.times[-1])

    def layout(self) -> Layout | None:
        """The box a shipped recording was made in (None for a user's path)."""
        if self.source not in DATASETS:
            return None
        return open_box(*DATASETS[self.source], name=f"{self.source}_box")

    def resample(self, start: float, dt: float, n_samples: int) -> np.ndarray:
        """Positions at ``start, start + dt, ...`` (``n_samples`` of them, seconds from the first
        sample), through ratinabox's cubic-spline import."""
        if self._spline is None:
            from ratinabox.Agent import Agent
            from ratinabox.Environment import Environment

            x0, y0 = self.positions.min(axis=0) - 1.0  # a host for the spline, never walked
            x1, y1 = self.positions.max(axis=0) + 1.0
            env = Environment(params={"boundary": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]})
            with isolated_global_rng(0), contextlib.redirect_stdout(io.StringIO()):
                agent = Agent(env)  # (it draws a start point; it prints what it imported)
                agent.import_trajectory(times=self.times, positions=self.positions)
            self._spline = agent.pos_interp
        return np.asarray(self._spline(start + dt * np.arange(n_samples)), dtype=np.float64)

    def n_steps(self, start: float, dt: float) -> int:
        """How many steps of ``dt`` seconds the path holds after ``start`` seconds."""
        return max(int(np.floor((self.duration - start) / dt + 1e-9)), 0)


def load_path(source: str) -> RecordedPath:
    """:class:`RecordedPath` of ``source``."""
    return RecordedPath(source)
