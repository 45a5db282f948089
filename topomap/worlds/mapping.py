"""Mapping while exploring: a simulated walk whose map is learned as the steps arrive.

:func:`map_while_exploring` walks a world with an explorer wrapped so that every
``update_every`` steps the steps seen are handed to :meth:`topomap.MapLearner.partial_fit`, and
an explorer with ``update(learner)`` gets the map learned so far.  What the explorer sees is what
is recorded: the world's observation passed through the sensor noise model, one step at a time.
The labels of every step after every update are kept, so the map's quality against the steps
taken can be measured afterwards against the world's places (which the explorer never sees).

ARI on the steps taken so far flatters an explorer that stays in a small part of the world (few
places, easily told apart), so a ``judge`` may also score the map at every update on a walk it
never learned from: :func:`heldout_judge` decodes a random walk through the whole world with the
map learned so far and returns its ARI against that walk's places.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from sklearn.metrics import adjusted_rand_score

from ..core.checks import ParameterError, check_count
from .explorers import View

__all__ = ["MappingWalk", "map_while_exploring", "quality_curve", "heldout_judge"]


class MappingWalk:
    """An explorer that feeds a learner while it walks (see the module docstring)."""

    def __init__(self, explorer, learner, noise, rng_noise, update_every: int,
                 n_actions: int | None, judge=None):
        self.explorer, self.learner, self.noise, self.rng = explorer, learner, noise, rng_noise
        self.update_every, self.n_actions, self.judge = int(update_every), n_actions, judge
        self.obs, self.gds, self.actions = [], [], []
        self._done = 0
        self.checkpoints = []   # (steps, labels, states, seconds of partial_fit, judge's scores)

    def see(self, view: View) -> None:
        seen = self.noise.apply(view.observation[None, :], self.rng)[0]
        self.obs.append(seen)
        self.gds.append(view.gds)
        if hasattr(self.explorer, "see"):
            self.explorer.see(view._replace(observation=seen))

    def choose(self, executable, rng) -> int:
        a = self.explorer.choose(executable, rng)
        self.actions.append(int(a))
        if len(self.actions) - self._done >= self.update_every:
            self.flush()
        return a

    def flush(self) -> None:
        """``partial_fit`` the steps since the last update; hand the map to the explorer."""
        lo, hi = self._done, len(self.actions)
        if hi == lo:
            return
        t0 = time.perf_counter()
        self.learner.partial_fit(np.asarray(self.obs[lo:hi]), np.asarray(self.actions[lo:hi]),
                                 np.asarray(self.gds[lo:hi]), n_actions=self.n_actions)
        seconds = time.perf_counter() - t0
        self._done = hi
        scores = {} if self.judge is None else self.judge(self.learner.map_)
        self.checkpoints.append((hi, self.learner.labels_.copy(), self.learner.map_.n_states,
                                 seconds, scores))
        if hasattr(self.explorer, "update"):
            self.explorer.update(self.learner)


def map_while_exploring(world, n_steps: int, explorer, learner, noise, rng_sim, rng_noise,
                        update_every: int | None = None, judge=None):
    """Walk ``world`` for ``n_steps`` steps, learning the map every ``update_every`` steps (None:
    the explorer's own ``update_every``).

    Returns ``(trajectory, walk)``: the trajectory holds the observations as the explorer saw them
    (noise applied), ``walk`` the :class:`MappingWalk` with its checkpoints.
    """
    if update_every is None:
        update_every = getattr(explorer, "update_every", None)
        if update_every is None:
            raise ParameterError("update_every", "is needed: the explorer has no update_every")
    update_every = check_count(update_every, "update_every")
    walk = MappingWalk(explorer, learner, noise, rng_noise, update_every,
                       getattr(world, "n_actions", None), judge)
    traj = world.simulate(n_steps, walk, rng_sim)
    traj.observations = np.asarray(walk.obs, dtype=np.float64).reshape(traj.observations.shape)
    return traj, walk


def quality_curve(walk: MappingWalk, places) -> list[dict]:
    """After every update: the steps taken, the ARI of the online map's labels of those steps
    against their true ``places``, the judge's scores, the map's states and the seconds
    ``partial_fit`` took."""
    places = np.asarray(places)
    return [{"steps": int(n), "ari": float(adjusted_rand_score(places[:n], labels)), **scores,
             "n_states": int(s), "seconds": float(sec)}
            for n, labels, s, sec, scores in walk.checkpoints]


def heldout_judge(trajectory):
    """A judge scoring a map on ``trajectory`` (a walk it never learned from, with places):
    ``{"heldout_ari": ARI of the map's Viterbi states of that walk against its places}``.

    The map is judged as a model of the world, ``P(o|x)`` and ``P(x'|x,u)``: its ``P(u|x)``
    records how the explorer chose, not the world, so the judge decodes with ``P(u|x)`` uniform.
    """
    places = np.asarray(trajectory.places)

    def judge(m) -> dict:
        m = replace(m, action_counts=np.ones_like(m.action_counts))
        try:
            states = m.predict(trajectory.observations, trajectory.actions, gds=trajectory.gds,
                               lengths=trajectory.lengths)
        except ValueError:  # a GDS of the walk the map has not met yet: judge without GDS
            states = m.predict(trajectory.observations, trajectory.actions,
                               lengths=trajectory.lengths)
        return {"heldout_ari": float(adjusted_rand_score(places, states))}

    return judge
