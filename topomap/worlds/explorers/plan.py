"""The plan policy: the action of highest planned novelty under a belief over the map's states
(``explorer=active explorer.route=plan``)."""

from __future__ import annotations

import numpy as np

from ...core.checks import ParameterError, check_count
from .base import MapExplorer, View, check_mask, pick

__all__ = ["PlanExplorer", "novelty_values"]

#: the last steps kept (view and action) to track the belief again on a new map; the steps it
#: is tracked over
KEPT_STEPS, REFILTERED_STEPS = 64, 32


def novelty_values(counts, opened, transitions, gamma: float, horizon: int) -> np.ndarray:
    """``(S, A)`` worth of every (state, action): its novelty plus the discounted best worth of
    where it leads, after ``horizon`` rounds of value iteration.

    ``counts`` (S, A): times each action was taken from each state; an action taken ``n`` times
    is worth ``1 / sqrt(n + 1)``.  ``opened`` (S, A) bool: actions seen executable in each state.
    ``transitions`` (S, A, S): ``P(x'|x,u)``.  An action is open where it was seen executable or
    taken; in a state where no action was seen executable, an action never taken from it in ``A``
    visits or more counts as not executable.  Actions not open are worth 0 (the mask of the
    current step tells what can be done there).
    """
    visits = counts.sum(1, keepdims=True)
    seen = opened.any(1, keepdims=True)
    allowed = (counts > 0) | opened | (~seen & (visits < counts.shape[1]))
    bonus = 1.0 / np.sqrt(counts + 1.0)
    q = np.where(allowed, bonus, -np.inf)
    for _ in range(horizon):
        v = np.max(q, axis=1)
        v = np.where(np.isfinite(v), v, 0.0)
        q = np.where(allowed, bonus + gamma * (transitions @ v), -np.inf)
    return np.where(np.isfinite(q), q, 0.0)


class PlanExplorer(MapExplorer):
    """Take the executable action of highest planned novelty under the belief over the map's
    states.

    The state is the map's own state, tracked as a belief from what the robot saw (the map's
    ``P(x'|x,u)`` and ``P(o|x)``; ``P(u|x)`` is no evidence, as the explorer chose the actions
    itself).  The worth of every (state, action) is :func:`novelty_values` over the map's action
    counts plus the actions taken from the likely state since the map arrived, planned once per
    step; the executable action of highest worth under the belief is taken (ties at random), or
    with probability ``epsilon`` a random one.  On a new map the belief is tracked again over the
    last :data:`REFILTERED_STEPS` steps.

    Measured (``benchmarks/bench_online.py``): slower than a random walk on gridrooms -- on the
    early maps its belief is often wrong, and it then goes back and forth where it thinks a novel
    action is.

    Parameters
    ----------
    update_every : int
        Steps between two updates of the map.
    gamma : float
        Discount of the value iteration, in (0, 1).
    horizon : int
        Rounds of value iteration.
    epsilon : float
        Share of random actions, in [0, 1].
    """

    def __init__(self, update_every: int = 250, gamma: float = 0.9, horizon: int = 30,
                 epsilon: float = 0.0):
        super().__init__(update_every, epsilon)
        if not (isinstance(gamma, (int, float)) and 0 < gamma < 1):
            raise ParameterError("gamma", f"must lie in (0, 1), got {gamma!r}")
        self.gamma = float(gamma)
        self.horizon = check_count(horizon, "horizon")
        self._map = None           # the map learned so far
        self._trans = None         # (S, A, S) its P(x'|x,u)
        self._tried = None         # (S, A) actions taken from the likely state since the map
        self._open = None          # (S, A) actions seen executable in the likely state since
        self._value = None         # (S, A) novelty_values of the above (None: not planned yet)
        self._belief = None        # (S,) belief over the map's states at the current step
        self._last = None          # the action taken at the step before
        self._recent = []          # (view, action) of the last KEPT_STEPS steps

    def update(self, learner) -> None:
        """Take the map the learner has now, and track the belief on it again."""
        m = learner.map_
        self._map, self._trans = m, m.transition_probs
        self._tried = np.zeros((m.n_states, m.n_actions))
        self._open = np.zeros((m.n_states, m.n_actions), dtype=bool)
        self._value = None
        belief, prev = None, None
        for view, a in self._recent[-REFILTERED_STEPS:]:
            belief = self._step(belief, prev, view)
            prev = a
        self._belief = belief

    def see(self, view: View) -> None:
        """Take the view of the current step; move the belief on to it."""
        super().see(view)
        if self._map is not None:
            self._belief = self._step(self._belief, self._last, view)

    def _step(self, belief, action, view: View):
        """The belief after ``action`` and then ``view``."""
        m = self._map
        try:
            alone = m.step_belief(None, 0, view.observation, view.gds)
        except ValueError:  # a GDS the map does not know yet
            alone = m.step_belief(None, 0, view.observation, None)
        if belief is None or action is None or action >= m.n_actions:
            return alone
        post = (belief @ self._trans[:, action, :]) * (alone / np.maximum(m.state_probs, 1e-12))
        total = post.sum()
        return post / total if total > 0 else alone

    def choose(self, executable, rng: np.random.Generator) -> int:
        """The executable action of highest worth under the belief (see the class docstring)."""
        mask = check_mask(executable)
        idx = np.flatnonzero(mask)
        planned = (self._map is not None and self._belief is not None
                   and self._map.n_actions >= mask.size)
        if planned:
            self._open_here(mask)
        if not planned or rng.random() < self.epsilon:
            a = pick(idx, rng)
        else:
            q = self._belief @ self._planned()[:, :mask.size]
            a = pick(idx[np.isclose(q[idx], q[idx].max(), rtol=0, atol=1e-12)], rng)
        if planned:
            self._tried[int(np.argmax(self._belief)), a] += 1
            self._value = None
        if self._view is not None:
            self._recent.append((self._view, a))
            del self._recent[:-KEPT_STEPS]
        self._last = a
        return a

    def _open_here(self, mask: np.ndarray) -> None:
        """What can be done here is what can be done in the likely state: record the mask."""
        s = int(np.argmax(self._belief))
        here = self._open[s, :mask.size]
        if (mask & ~here).any():
            self._open[s, :mask.size] = here | mask
            self._value = None

    def _planned(self) -> np.ndarray:
        """The worth of every (state, action), planned again if anything changed since."""
        if self._value is None:
            self._value = novelty_values(self._map.action_counts + self._tried, self._open,
                                         self._trans, self.gamma, self.horizon)
        return self._value

    def __repr__(self) -> str:
        return (f"PlanExplorer(update_every={self.update_every}, gamma={self.gamma}, "
                f"horizon={self.horizon}, epsilon={self.epsilon})")
