"""Walks drawn from a learned map: the states, actions and observations its tables generate.

:meth:`~topomap.core.map.model.TopologicalMap.sample` calls :func:`sample`.  A walk uses the map's
own tables, unsmoothed (inference mixes in ``smoothing``; a walk needs no protection from
unseen moves): the first state from the state frequencies (:attr:`state_probs
<topomap.core.map.model.TopologicalMap.state_probs>`), each action from ``P(u|x)``, a policy or
the actions given, the next state from ``P(x'|x,u)`` (a pair ``(x, u)`` never seen has a uniform
row, as everywhere in the map) and each observation from the state's Gaussian.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..checks import check_count

__all__ = ["sample", "executable_actions"]


def executable_actions(m) -> list[np.ndarray]:
    """For every state of the map ``m``, the actions it has seen lead somewhere from that state
    (a transition counted), or every action where it has seen none."""
    seen = m.transition_counts.sum(axis=2) > 0
    every = np.arange(m.n_actions)
    return [every[row] if row.any() else every for row in seen]


def sample(m, n_samples, actions=None, random_state=None, currstate=None):
    """``(X, actions, states)``: a walk of ``n_samples`` steps on the map ``m``.

    ``actions`` None draws each step's action from ``P(u|x)``; an array of ``n_samples`` action
    ids is followed as given; a callable ``policy(state, executable)`` is asked for each step's
    action with the step's state and its :func:`executable_actions` (an array of ids) and must
    return one of them (a policy that draws at random keeps its own seeded generator).  Every
    step has an action, the last one included (the map counts ``P(u|x)`` at every step).
    ``random_state`` seeds the draws (an int, None for fresh entropy, or a
    ``numpy.random.Generator``); ``currstate`` fixes the first state.  GDS states emit their GDS's
    observations; ``m.state_gds[states]`` gives the GDS labels of the walk.
    """
    n = check_count(n_samples, "n_samples")
    try:
        rng = np.random.default_rng(random_state)
    except (TypeError, ValueError):
        raise ValueError("random_state must be an int, None or a numpy Generator, got "
                         f"{random_state!r}") from None
    start = -1 if currstate is None else _checked_state(m, currstate)
    given = None if callable(actions) else _given_actions(m, actions, n)
    S = m.n_states
    init = m.state_probs if m.state_counts.sum() > 0 else np.full(S, 1.0 / S)
    cdf_init = np.cumsum(init)
    cdf_trans = np.cumsum(m.transition_probs, axis=2)
    draws = rng.random((n, 2))  # column 0: the state, column 1: the action
    states, acts = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    if given is None:
        _policy_walk(m, actions, start, cdf_init, cdf_trans, draws, states, acts)
    else:
        _walk(start, cdf_init, np.cumsum(m.action_probs, axis=1), cdf_trans, given, draws,
              states, acts)
    return _observations(m, states, rng), acts, states


def _checked_state(m, state) -> int:
    if not (isinstance(state, (int, np.integer)) and 0 <= state < m.n_states):
        raise ValueError(f"currstate must be a state of this map (0..{m.n_states - 1}), "
                         f"got {state!r}")
    return int(state)


def _given_actions(m, actions, n: int) -> np.ndarray:
    """The actions to follow (an empty array: draw them), checked against ``m`` and ``n``."""
    if actions is None:
        return np.empty(0, dtype=np.int64)
    u = np.asarray(actions)
    if u.dtype.kind not in "iu" or u.shape != (n,):
        raise ValueError(f"actions must be None, a policy or {n} action ids (n_samples), got "
                         f"{u.dtype} of shape {u.shape}")
    if u.min() < 0 or u.max() >= m.n_actions:
        bad = int(u.min()) if u.min() < 0 else int(u.max())
        raise ValueError(f"actions use id {bad} but the map knows actions 0..{m.n_actions - 1}")
    return u.astype(np.int64)


@njit(cache=True)
def _draw(cdf, r):
    """The first index whose cumulative probability exceeds ``r`` (in [0, 1)) of the total:
    an index drawn with probability proportional to its step of ``cdf``."""
    x = r * cdf[-1]
    lo, hi = 0, cdf.size - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] > x:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True)
def _walk(start, cdf_init, cdf_act, cdf_trans, given, draws, states, acts):
    """The states and actions of a walk whose actions are drawn from ``P(u|x)`` (``given``
    empty) or given."""
    x = start if start >= 0 else _draw(cdf_init, draws[0, 0])
    for t in range(states.size):
        if t > 0:
            x = _draw(cdf_trans[x, acts[t - 1]], draws[t, 0])
        states[t] = x
        acts[t] = given[t] if given.size > 0 else _draw(cdf_act[x], draws[t, 1])


def _policy_walk(m, policy, start, cdf_init, cdf_trans, draws, states, acts) -> None:
    """:func:`_walk` asking ``policy`` for every action."""
    executable = executable_actions(m)
    x = start if start >= 0 else int(_draw(cdf_init, draws[0, 0]))
    for t in range(states.size):
        if t > 0:
            x = int(_draw(cdf_trans[x, acts[t - 1]], draws[t, 0]))
        states[t] = x
        a = policy(x, executable[x].copy())
        if not (isinstance(a, (int, np.integer)) and a in executable[x]):
            raise ValueError(f"the policy chose action {a!r} in state {x}, whose executable "
                             f"actions are {executable[x].tolist()}")
        acts[t] = a


def _observations(m, states, rng) -> np.ndarray:
    """One observation of every step, drawn from its state's Gaussian."""
    z = rng.standard_normal((states.size, m.n_features))
    if m.covariance_type == "diag":
        return m.means[states] + z * np.sqrt(m.covariances[states])
    X = np.empty_like(z)
    for s in np.unique(states):
        rows = states == s
        X[rows] = m.means[s] + z[rows] @ np.linalg.cholesky(m.covariances[s]).T
    return X
