"""Exploration policies: how the simulated robot picks its next action.

An explorer has one method, ``choose(executable, rng) -> int``, which receives the boolean mask of
the actions that can be started at the current place and returns the index of one of them.

Two optional methods let an explorer use what a real robot has, and nothing more:

* ``see(view)`` -- called by the world before every ``choose`` with a :class:`View`: the step's
  observation, the executable actions and the GDS recognised there.  A view has no place: the
  true place never reaches an explorer.
* ``update(learner)`` -- called while mapping as the robot explores (``data.curve_every``, or
  an explorer with this method) after every ``partial_fit`` of the run's
  :class:`~topomap.MapLearner`: the map learned so far is ``learner.map_``.

:class:`RandomExplorer` is the paper's; :class:`ActiveExplorer` goes where the map is least known.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.checks import ParameterError, check_count

__all__ = ["View", "RandomExplorer", "ActiveExplorer", "show"]


class View(NamedTuple):
    """What the robot has at a step: its observation (as the sensor gives it), the boolean mask
    of the actions it can start, the GDS it recognises there (-1: none) and the step index."""

    observation: np.ndarray
    executable: np.ndarray
    gds: int
    t: int


def show(explorer, observation, executable, gds: int, t: int) -> None:
    """Hand an explorer that has ``see`` the step's :class:`View` (the worlds call this)."""
    see = getattr(explorer, "see", None)
    if see is not None:
        see(View(np.array(observation, dtype=np.float64), np.array(executable, dtype=bool),
                 int(gds), int(t)))


def _check_mask(executable) -> np.ndarray:
    mask = np.asarray(executable)
    if mask.ndim != 1 or mask.dtype.kind != "b":
        raise ValueError(f"executable must be a 1-D boolean mask, got {mask.dtype} array of shape {mask.shape}")
    if not mask.any():
        raise ValueError("executable marks no action as executable; cannot choose one")
    return mask


class RandomExplorer:
    """Pick uniformly at random among the executable actions (the paper's exploration)."""

    def choose(self, executable, rng: np.random.Generator) -> int:
        """Return the index of an executable action, drawn uniformly with ``rng``.

        Parameters
        ----------
        executable : (n_actions,) bool array
        rng : numpy.random.Generator

        Raises
        ------
        ValueError
            If no action is executable.
        """
        idx = np.flatnonzero(_check_mask(executable))
        return int(idx[rng.integers(idx.size)])

    def __repr__(self) -> str:
        return "RandomExplorer()"


class ActiveExplorer:
    """Go where the map is least known: count-based novelty on (state, action) pairs.

    Two routes (``route``), both using only what the robot has -- its views, the actions it took
    and the map learned so far (``update(learner)``); both walk at random until a map exists:

    * ``"history"`` (default): the state is the robot's recent past read through the map's
      symbols: the symbols of the last ``context`` views, the actions between them and the symbol
      of the current view (a GDS counts as its own symbol).  Each step it takes the executable
      action it has taken least often from that state (ties at random).  No belief is tracked, so
      no belief can be wrong; the counts stay valid from one map to the next (the symbols of a
      map learned while exploring are fixed after its first pass).
    * ``"plan"``: the state is the map's own state, tracked as a belief from what it saw
      (``P(x'|x,u)`` and ``P(o|x)`` of the map; ``P(u|x)`` is no evidence, as the explorer chose
      the actions itself).  An action tried ``n`` times from a state is worth
      ``1 / sqrt(n + 1)``; ``horizon`` rounds of value iteration over the map's ``P(x'|x,u)`` with
      discount ``gamma`` carry that worth back to the states that lead there, and the executable
      action of highest value under the belief is taken (ties at random).

    With probability ``epsilon`` a random action is taken instead.  Needs the map: the run maps
    while exploring, every ``update_every`` steps (:meth:`topomap.MapLearner.partial_fit`).
    Measured (``benchmarks/bench_online.py``): ``"history"`` reaches a given ARI in fewer steps
    than a random walk on gridrooms; ``"plan"`` in more -- on the early maps its belief is often
    wrong, and it then goes back and forth where it thinks a novel action is.

    Parameters
    ----------
    update_every : int
        Steps between two updates of the map.
    route : {"history", "plan"}
        What a state is (see above).
    context : int
        ``"history"``: the past views that make a state, besides the current one.
    gamma : float
        ``"plan"``: discount of the value iteration, in (0, 1).
    horizon : int
        ``"plan"``: rounds of value iteration.
    epsilon : float
        Share of random actions, in [0, 1].
    """

    ROUTES = ("history", "plan")

    def __init__(self, update_every: int = 250, route: str = "history", context: int = 3,
                 gamma: float = 0.9, horizon: int = 30, epsilon: float = 0.0):
        self.update_every = check_count(update_every, "update_every")
        if route not in self.ROUTES:
            raise ParameterError("route", f"must be one of {', '.join(self.ROUTES)}, got {route!r}")
        self.route = route
        if not (isinstance(context, int) and not isinstance(context, bool) and context >= 0):
            raise ParameterError("context", f"must be a non-negative integer, got {context!r}")
        self.context = context
        if not (isinstance(gamma, (int, float)) and 0 < gamma < 1):
            raise ParameterError("gamma", f"must lie in (0, 1), got {gamma!r}")
        self.gamma = float(gamma)
        self.horizon = check_count(horizon, "horizon")
        if not (isinstance(epsilon, (int, float)) and 0 <= epsilon <= 1):
            raise ParameterError("epsilon", f"must lie in [0, 1], got {epsilon!r}")
        self.epsilon = float(epsilon)
        self._map = None
        self._belief = None
        self._view = None
        self._last = None          # the action taken at the step before
        self._recent = []          # (view, action) of the last steps, to re-filter on a new map
        self._symbols = None       # (K, D) observation mean of every symbol, fixed at the first map
        self._past = []            # "history": symbols and actions of the last steps
        self._counts = {}          # "history": times each action was taken from each state

    # ---------------------------------------------------------------- what the robot has
    def update(self, learner) -> None:
        """Take the map the learner has now."""
        m = learner.map_
        self._map = m
        if self._symbols is None:
            plain = m.state_symbol >= 0
            order = np.unique(m.state_symbol[plain], return_index=True)[1]
            self._symbols = m.means[plain][order]
        if self.route == "history":
            return
        self._trans = m.transition_probs
        self._tried = np.zeros((m.n_states, m.n_actions))
        self._executable = np.zeros((m.n_states, m.n_actions), dtype=bool)  # masks seen
        self._value = self._plan()
        belief, prev = None, None
        for view, a in self._recent[-32:]:
            belief = self._step(belief, prev, view)
            prev = a
        self._belief = belief

    def see(self, view: View) -> None:
        self._view = view
        if self._map is not None and self.route == "plan":
            self._belief = self._step(self._belief, self._last, view)

    def _symbol(self, view: View) -> int:
        """The view's symbol: its GDS (as ``-1 - gds``), else the nearest symbol mean."""
        if view.gds >= 0:
            return -1 - int(view.gds)
        d = ((self._symbols - view.observation[None, :]) ** 2).sum(1)
        return int(np.argmin(d))

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
        mask = _check_mask(executable)
        idx = np.flatnonzero(mask)
        if self.route == "history":
            a = self._choose_history(idx, rng)
        else:
            a = self._choose_plan(mask, idx, rng)
        if self._view is not None and self.route == "plan":
            self._recent.append((self._view, a))
            del self._recent[:-64]
        self._last = a
        return a

    def _choose_history(self, idx, rng) -> int:
        if self._symbols is None or self._view is None:
            return int(idx[rng.integers(idx.size)])
        sym = self._symbol(self._view)
        state = (*self._past[len(self._past) - 2 * self.context:], sym) if self.context else (sym,)
        if rng.random() < self.epsilon:
            a = int(idx[rng.integers(idx.size)])
        else:
            tried = np.array([self._counts.get((state, int(b)), 0) for b in idx])
            least = idx[tried == tried.min()]
            a = int(least[rng.integers(least.size)])
        self._counts[(state, a)] = self._counts.get((state, a), 0) + 1
        self._past += [sym, a]
        del self._past[:-2 * max(self.context, 1)]
        return a

    def _choose_plan(self, mask, idx, rng) -> int:
        planned = (self._map is not None and self._belief is not None
                   and self._value.shape[1] >= mask.size)
        if planned:  # what can be done here, now seen, is what can be done in the likely state
            s = int(np.argmax(self._belief))
            seen = self._executable[s, :mask.size]
            if (mask & ~seen).any():
                seen |= mask
                self._value = self._plan()
        if not planned or rng.random() < self.epsilon:
            a = int(idx[rng.integers(idx.size)])
        else:
            q = self._belief @ self._value[:, :mask.size]
            best = idx[np.isclose(q[idx], q[idx].max(), rtol=0, atol=1e-12)]
            a = int(best[rng.integers(best.size)])
        if planned and a < self._tried.shape[1]:
            self._tried[int(np.argmax(self._belief)), a] += 1
            self._value = self._plan()
        return a

    # ---------------------------------------------------------------- planning
    def _plan(self) -> np.ndarray:
        """(S, A) values: the novelty of every (state, action) plus the discounted best value of
        where it leads, over ``horizon`` rounds."""
        m = self._map
        n = m.action_counts + self._tried
        visits = n.sum(1, keepdims=True)
        # an action is open where it was seen executable or taken; in a state whose actions were
        # not seen, an action never taken from it in A visits or more is taken as not executable
        seen = self._executable.any(1, keepdims=True)
        allowed = (n > 0) | self._executable | (~seen & (visits < m.n_actions))
        bonus = 1.0 / np.sqrt(n + 1.0)
        q = np.where(allowed, bonus, -np.inf)
        for _ in range(self.horizon):
            v = np.max(q, axis=1)
            v = np.where(np.isfinite(v), v, 0.0)
            q = np.where(allowed, bonus + self.gamma * (self._trans @ v), -np.inf)
        return np.where(np.isfinite(q), q, 0.0)  # the mask tells what is executable here

    def __repr__(self) -> str:
        if self.route == "history":
            return (f"ActiveExplorer(update_every={self.update_every}, route='history', "
                    f"context={self.context}, epsilon={self.epsilon})")
        return (f"ActiveExplorer(update_every={self.update_every}, route='plan', "
                f"gamma={self.gamma}, horizon={self.horizon}, epsilon={self.epsilon})")
