"""Motion in the arena: what a path's samples say about the moves, and ratinabox's random motion.

A path is sampled every ``dt`` seconds: ``T + 1`` positions give ``T`` steps, step ``t`` being
the move from sample ``t`` to sample ``t + 1``.  :class:`Motion` derives from the positions alone,
the same way for random motion and for recorded paths, what the sensors and the action rules use:

* ``velocity[t] = (p[t+1] - p[t]) / dt`` (m/s), and ``speed`` its length;
* ``heading[t]``: the direction the robot faces at sample ``t``, that of its last move (of the
  first move at ``t = 0``); a move shorter than 1 micrometre keeps the heading it had;
* ``rotational_velocity[t] = wrap(heading[t+1] - heading[t]) / dt`` (rad/s, anticlockwise
  positive): the turn made during step ``t``, as a differential-drive robot is commanded.

Random motion is ratinabox's ``Agent`` (its motion model fitted to rats, Sargolini et al. 2006,
see George et al. 2024, eLife, doi 10.7554/eLife.85274).  ratinabox draws from numpy's global
random state: :func:`isolated_global_rng` seeds it for the call and puts the caller's state back,
so the same seed gives the same path byte for byte and two worlds never disturb each other.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

__all__ = ["Motion", "isolated_global_rng", "random_motion", "MOTION_PARAMETERS"]

#: the ratinabox ``Agent`` parameters the arena passes on (its random-motion model)
MOTION_PARAMETERS = ("speed_mean", "speed_coherence_time", "rotational_velocity_std",
                     "rotational_velocity_coherence_time", "thigmotaxis", "wall_repel_distance",
                     "wall_repel_strength")
#: moves shorter than this (metres) keep the heading
_STILL = 1e-6


@contextlib.contextmanager
def isolated_global_rng(seed: int):
    """Seed numpy's global random state with ``seed`` for the block, then restore the caller's."""
    saved = np.random.get_state()
    np.random.seed(int(seed) % 2**32)
    try:
        yield
    finally:
        np.random.set_state(saved)


def _headings(positions: np.ndarray) -> np.ndarray:
    """The heading at every sample: the direction of the last move longer than :data:`_STILL`."""
    moves = np.diff(positions, axis=0)
    angles = np.arctan2(moves[:, 1], moves[:, 0])
    moving = np.hypot(moves[:, 0], moves[:, 1]) > _STILL
    if not moving.any():
        return np.zeros(positions.shape[0])
    last = np.maximum.accumulate(np.where(moving, np.arange(moves.shape[0]), -1))
    last = np.where(last < 0, np.flatnonzero(moving)[0], last)
    return np.concatenate([[angles[last[0]]], angles[last]])


@dataclass(frozen=True)
class Motion:
    """The ``T`` steps of a path sampled every ``dt`` seconds (see the module docstring).

    Attributes
    ----------
    times : (T,) float -- seconds at each step's start
    positions : (T, 2) float -- metres, where each step starts
    velocity : (T, 2) float -- m/s over each step
    heading : (T,) float -- radians, anticlockwise from east, faced at each step's start
    rotational_velocity : (T,) float -- rad/s turned during each step
    dt : float
    """

    times: np.ndarray
    positions: np.ndarray
    velocity: np.ndarray
    heading: np.ndarray
    rotational_velocity: np.ndarray
    dt: float

    @classmethod
    def from_samples(cls, positions, dt: float, t0: float = 0.0) -> "Motion":
        """The steps of ``T + 1`` positions sampled every ``dt`` seconds from ``t0``."""
        P = np.asarray(positions, dtype=np.float64)
        T = P.shape[0] - 1
        heading = _headings(P)
        turn = np.angle(np.exp(1j * np.diff(heading)))
        return cls(times=t0 + dt * np.arange(T), positions=P[:-1], velocity=np.diff(P, axis=0) / dt,
                   heading=heading[:-1], rotational_velocity=turn / dt, dt=float(dt))

    @property
    def speed(self) -> np.ndarray:
        """(T,) m/s."""
        return np.hypot(self.velocity[:, 0], self.velocity[:, 1])

    def __len__(self) -> int:
        return int(self.positions.shape[0])


def random_motion(environment, n_steps: int, dt: float, params: dict, seed: int) -> np.ndarray:
    """``n_steps + 1`` positions of ratinabox's random motion in ``environment``.

    A new ``Agent`` with ``params`` (and ``dt``) starts at a random point and takes ``n_steps``
    ``update()`` calls, all under :func:`isolated_global_rng` with ``seed``; it leaves the
    environment afterwards.
    """
    from ratinabox.Agent import Agent

    with isolated_global_rng(seed):
        agent = Agent(environment, params={**params, "dt": float(dt)})
        try:
            start = np.array(agent.pos, dtype=np.float64)
            for _ in range(n_steps):
                agent.update()
            path = np.asarray(agent.history["pos"], dtype=np.float64)
        finally:
            environment.remove_agent(agent)
    return np.concatenate([start[None], path])
