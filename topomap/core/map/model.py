"""The learned topological map: a POMDP-style model over discrete states.

A :class:`TopologicalMap` holds, for every state, where it came from (its K-means symbol or its
GDS id, and the state it was split from), the Gaussian observation model ``P(o|x)``, the counts
behind ``P(u|x)`` and ``P(x'|x,u)``, and the learning record (split history and the three entropies
after phase 1 and after every split).  It is estimated from labelled steps (:meth:`from_labels`),
decodes new sequences (:meth:`predict`, Viterbi; :meth:`decode`), scores them (:meth:`score`,
forward algorithm), filters them (:meth:`filter`) and gives every step's posterior
(:meth:`predict_proba`, :meth:`score_samples`, forward-backward) through
:mod:`topomap.core.map.inference`, with hmmlearn's names and return values.  It draws walks
(:meth:`sample`, :mod:`topomap.core.map.sampling`).  Its files (JSON, GraphML, networkx) are
:mod:`topomap.core.map.files`, its planning :mod:`topomap.core.map.planning`.

Observation models are *tied*: states split from the same symbol share that symbol's Gaussian, as
in the paper, where splitting refines the state set without touching ``P(o|x)``.  Hence
``H(o|x)`` is left unchanged by every split.
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from pathlib import Path

import numpy as np

from . import files, inference, planning, sampling
from .files import FORMAT_VERSION
from .observations import observation_models
from ..data.trajectory import as_float_observations
from ..stats import conditional_entropy, count_tables, episode_masks, normalise

__all__ = ["TopologicalMap", "FORMAT_VERSION"]


@dataclass(frozen=True, eq=False, repr=False)
class TopologicalMap:
    """A learned map.  Usually made by :class:`topomap.MapLearner`; see the module docstring.

    Every field is checked when the map is made (a ValueError names the JSON field at fault,
    :mod:`topomap.core.map.files`); a map never changes afterwards: ``dataclasses.replace`` makes
    a changed copy.

    Fields
    ------
    state_symbol : (S,) int -- K-means symbol of each state, -1 for GDS states
    state_gds : (S,) int -- GDS id of each state, -1 for ordinary states
    state_parent : (S,) int -- the state each state was split from, -1 for phase-1 states
    means : (S, D) float -- observation mean of each state's symbol (or GDS)
    covariances : (S, D, D) or (S, D) float -- covariance ("full") or variances ("diag")
    state_counts : (S,) int -- steps in each state
    action_counts : (S, A) int -- steps in each state taking each action
    transition_counts : (S, A, S) int -- transitions ``(x, u) -> x'`` inside episodes
    action_names, gds_names : list of str or None (keyword only, as the fields after them)
    split_history : list of dict -- the learner's splits (``MapLearner.split_history_``)
    entropy_history : list of dict -- ``H_o``, ``H_u``, ``H_x`` after phase 1 and after every
        split (``MapLearner.entropies_``; the JSON field ``entropies``)
    info : dict -- how the map was learned (parameters, stopping reason, refinement)
    """

    state_symbol: np.ndarray
    state_gds: np.ndarray
    state_parent: np.ndarray
    means: np.ndarray
    covariances: np.ndarray
    state_counts: np.ndarray
    action_counts: np.ndarray
    transition_counts: np.ndarray
    _: KW_ONLY
    action_names: list | None = None
    gds_names: list | None = None
    split_history: list = ()
    entropy_history: list = ()
    info: dict | None = None

    def __post_init__(self):
        for name, value in files.checked_fields(self).items():
            object.__setattr__(self, name, value)
        files.check_tables(self)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_labels(cls, observations, actions, labels, *, lengths=None, state_symbol, state_gds,
                    state_parent, n_actions, covariance_type="diag", reg_covar=1e-3, info=None,
                    models=None, counts=None, **fields):
        """Estimate every table from a labelled sequence (labels in ``[0, S)``); ``fields`` are
        the map's keyword fields (names, histories), ``info`` gets ``covariance_type`` first.
        ``models``: the ``(means, covariances)`` of every state when they are known already (a
        split keeps every step's symbol, so the split map's are phase 1's; else
        :meth:`state_models`); ``counts``: the ``(state_counts, action_counts,
        transition_counts)`` of the labelling when they are known already (the split's, kept
        as it goes); neither is estimated again.

        The observation model of a state is the Gaussian of all steps sharing its symbol (or its
        GDS id); ``reg_covar`` times the mean feature variance of the data is added to every
        variance so that a constant feature does not make the density degenerate.  Float32
        observations are read as they are (not copied to float64) and summed in float64.
        """
        X = as_float_observations(observations, keep_float32=True)
        u = np.asarray(actions, dtype=np.int64)
        x = np.asarray(labels, dtype=np.int64)
        T = X.shape[0]
        S = len(state_symbol)
        A = int(n_actions)
        if x.size and (x.min() < 0 or x.max() >= S):
            raise ValueError(f"labels must lie in [0, {S}) (the states of state_symbol)")
        if models is None:
            models = cls.state_models(X, x, state_symbol, state_gds, covariance_type, reg_covar)
        if counts is None:
            L = np.array([T]) if lengths is None else np.asarray(lengths)
            _, has_next = episode_masks(T, L)
            counts = count_tables(x, u, S, A, has_next)
        info = {"covariance_type": covariance_type, **(info or {})}
        return cls(state_symbol, state_gds, state_parent, *models, *counts, info=info, **fields)

    @staticmethod
    def state_models(observations, labels, state_symbol, state_gds, covariance_type="diag",
                     reg_covar=1e-3, variance=None):
        """``(means (S, D), covariances)`` of every state of a labelling, as :meth:`from_labels`
        estimates them: the Gaussian of all steps sharing the state's symbol (or GDS id).
        ``variance``: the data's feature variance when it is known already
        (:func:`~topomap.core.map.observations.observation_models`)."""
        symbol, gds = np.asarray(state_symbol), np.asarray(state_gds)
        # a "model id" per state: symbols, then GDS ids after them
        n_sym = int(symbol.max()) + 1 if (symbol >= 0).any() else 0
        model_of_state = np.where(symbol >= 0, symbol, n_sym + gds)
        M = int(model_of_state.max()) + 1
        mean_m, cov_m, _ = observation_models(observations, labels, M, covariance_type, reg_covar,
                                              lookup=model_of_state, variance=variance)
        return mean_m[model_of_state], cov_m[model_of_state]

    # ------------------------------------------------------------------ sizes and tables
    @property
    def n_states(self) -> int:
        return int(self.state_counts.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.action_counts.shape[1])

    @property
    def n_features(self) -> int:
        return int(self.means.shape[1])

    @property
    def covariance_type(self) -> str:
        return "full" if self.covariances.ndim == 3 else "diag"

    @property
    def state_probs(self) -> np.ndarray:
        """(S,) share of steps in each state."""
        return self.state_counts / max(self.state_counts.sum(), 1)

    @property
    def action_probs(self) -> np.ndarray:
        """(S, A) ``P(u|x)``; a state never seen gets a uniform row."""
        return normalise(self.action_counts)

    @property
    def transition_probs(self) -> np.ndarray:
        """(S, A, S) ``P(x'|x,u)``; an ``(x, u)`` never seen gets a uniform row."""
        return normalise(self.transition_counts)

    @property
    def marginal_transition_probs(self) -> np.ndarray:
        """(S, S) ``P(x'|x) = sum_u P(u|x) P(x'|x,u)``: the transitions with the action summed
        out, hmmlearn's ``transmat_`` of this map; a sequence without actions is decoded with
        it (``predict(observations)``)."""
        return np.einsum("xa,xay->xy", self.action_probs, self.transition_probs)

    # ------------------------------------------------------------------ entropies
    def state_entropies(self) -> np.ndarray:
        """(S,) differential entropy in bits of each state's Gaussian observation model."""
        if self.covariance_type == "diag":
            logdet = np.log2(self.covariances).sum(axis=1)
        else:
            logdet = np.linalg.slogdet(self.covariances)[1] / np.log(2)
        return 0.5 * (self.n_features * np.log2(2 * np.pi * np.e) + logdet)

    def entropies(self) -> dict:
        """``H(o|x)``, ``H(u|x)``, ``H(x'|x,u)`` in bits (``H(o|x)`` is a differential entropy)."""
        return {
            "H_o": float(self.state_probs @ self.state_entropies()),
            "H_u": conditional_entropy(self.action_counts),
            "H_x": conditional_entropy(self.transition_counts),
        }

    # ------------------------------------------------------------------ inference
    def predict(self, observations, actions=None, gds=None, lengths=None, *, smoothing=1e-6,
                prune=True) -> np.ndarray:
        """Most likely state of every step of a new sequence (Viterbi).

        Uses the Gaussian observation likelihoods, ``P(u|x)`` and ``P(x'|x,u)``; ``smoothing`` mixes
        a small uniform share into every table so unseen transitions are unlikely, not impossible.
        ``actions=None`` (observations alone, as hmmlearn's ``predict(X)``): the actions are
        summed out, so the states move by :attr:`marginal_transition_probs`
        (:func:`~topomap.core.map.inference.without_actions`); the same holds for every method
        below.
        With ``gds`` given, GDS steps are clamped to their GDS state and other steps never take
        one.  ``prune`` skips states far below a step's best (exact; see
        :mod:`topomap.core.map.inference`).  Memory does not grow with T beyond the path.
        """
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.viterbi(s)

    def score(self, observations, actions=None, gds=None, lengths=None, *, smoothing=1e-6,
              prune=True) -> float:
        """Mean log-likelihood per step (natural log, forward algorithm) of a new sequence.

        Observations are continuous, so this is a log-*density* (it can be positive)."""
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.forward(s)

    def filter(self, observations, actions=None, gds=None, lengths=None, *, smoothing=1e-6,
               prune=True) -> np.ndarray:
        """Belief over the states at every step given only the past (forward filtering).

        Row ``t`` is ``P(x_t | o_1..o_t, u_1..u_{t-1})``: the step's own observation counts, its
        action (chosen after it) does not; every row sums to 1 and each episode of ``lengths``
        starts afresh from the map's state frequencies.  :meth:`predict` decodes the whole
        sequence at once (Viterbi) instead.  Returns a (T, S) float array.
        """
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.filtered(s)

    def predict_proba(self, observations, actions=None, gds=None, lengths=None, *, smoothing=1e-6,
                      prune=True) -> np.ndarray:
        """Posterior probability of every state at every step given the whole episode
        (forward-backward, also called smoothing), as hmmlearn's ``predict_proba``.

        Row ``t`` is ``P(x_t | o_1..o_n, u_1..u_n)`` over the ``n`` steps of ``t``'s episode:
        unlike :meth:`filter`, later steps count too.  Returns a (T, S) float array whose rows
        sum to 1; arguments as :meth:`predict`.  Memory beyond the output does not grow with T.
        """
        return self.score_samples(observations, actions, gds, lengths, smoothing=smoothing,
                                  prune=prune)[1]

    def score_samples(self, observations, actions=None, gds=None, lengths=None, *, smoothing=1e-6,
                      prune=True) -> tuple[float, np.ndarray]:
        """``(log_prob, posteriors)`` in one forward-backward pass, as hmmlearn's
        ``score_samples``: ``log_prob`` is the log-likelihood ``log P(o, u)`` of the whole
        sequence (natural log, summed over the episodes: T times :meth:`score`, which is per
        step), ``posteriors`` what :meth:`predict_proba` returns."""
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.posteriors(s)

    def decode(self, observations, actions=None, gds=None, lengths=None, *, algorithm="viterbi",
               smoothing=1e-6, prune=True) -> tuple[float, np.ndarray]:
        """``(log_prob, states)``: the states of every step and a log-probability, as
        hmmlearn's ``decode``.

        ``algorithm="viterbi"``: the most probable state path (:meth:`predict`) and its joint
        log-probability with the data, ``log P(o, u, x)``, summed over the episodes.
        ``algorithm="map"``: every step's most probable state on its own (the argmax of a row of
        :meth:`predict_proba`; the sequence may hold a move the map makes improbable) and the
        log-likelihood ``log P(o, u)`` of :meth:`score_samples`.  Arguments as :meth:`predict`.
        """
        if algorithm not in ("viterbi", "map"):
            raise ValueError(f"algorithm must be 'viterbi' or 'map', got {algorithm!r}")
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        if algorithm == "map":
            log_prob, post = inference.posteriors(s)
            return log_prob, post.argmax(axis=1)
        path = inference.viterbi(s)
        return inference.path_log_prob(s, path), path

    def sample(self, n_samples: int = 1, actions=None, random_state=None, *,
               currstate: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A walk drawn from the map: ``(X, actions, states)``, (n_samples, D) observations and
        the (n_samples,) actions and states; see :func:`topomap.core.map.sampling.sample`.

        ``actions``: None draws each step's action from ``P(u|x)``; an array of n_samples action
        ids is followed; a callable ``policy(state, executable)`` is asked for every action.
        ``random_state``: an int, None or a ``numpy.random.Generator``.  ``currstate``: the
        first state (default: drawn from the map's state frequencies), as in hmmlearn.
        """
        return sampling.sample(self, n_samples, actions, random_state, currstate)

    def step_belief(self, belief, action: int, observation, gds: int | None = None, *,
                    smoothing: float = 1e-6) -> np.ndarray:
        """One step of :meth:`filter`: the belief after taking ``action`` from ``belief`` and then
        seeing ``observation``; ``gds`` is the GDS recognised there (-1: none, so no GDS state;
        None: no GDS information).  ``belief=None`` gives the belief at an episode's first step
        (``action`` is then ignored)."""
        X = np.asarray(observation, dtype=np.float64).reshape(1, -1)
        g = None if gds is None else [int(gds)]
        s = inference.setup(self, X, [0], g, None, smoothing, prune=False)
        emit = inference.emission_row(s)
        if belief is None:
            return _normalised(s.tables.log_init + emit)
        belief = np.asarray(belief, dtype=np.float64)
        if belief.shape != (self.n_states,) or not np.isclose(belief.sum(), 1.0):
            raise ValueError(f"belief must be a probability vector over the {self.n_states} states")
        if not (isinstance(action, (int, np.integer)) and 0 <= action < self.n_actions):
            raise ValueError(f"action must be an action id in [0, {self.n_actions}), got {action!r}")
        return _normalised(np.log(inference.predicted(s, belief, int(action))) + emit)

    def plan(self, start: int, goal, *, min_prob: float = 0.0,
             names: bool = False) -> list[int] | list[str]:
        """Actions of the most probable path from state ``start`` to ``goal`` (a state or an
        iterable of states), as action ids; with ``names=True`` as the map's action names, or
        the ids written as strings (``"0"``) where the map has none, the labels of
        :meth:`to_networkx`.  See :func:`topomap.core.map.planning.plan`."""
        actions = planning.plan(self, start, goal, min_prob)
        return [self.action_label(a) for a in actions] if names else actions

    # ------------------------------------------------------------------ files and graphs
    def action_label(self, a: int) -> str:
        """The name of action ``a``: its entry of :attr:`action_names`, or ``str(a)``."""
        return self.action_names[a] if self.action_names else str(a)

    def state_label(self, s: int) -> str:
        if self.state_gds[s] >= 0:
            g = int(self.state_gds[s])
            return self.gds_names[g] if self.gds_names else f"GDS{g}"
        return f"s{s}"

    def to_networkx(self, min_prob: float = 0.0):
        """A ``networkx.DiGraph``, one arc per ``(x, x')`` with an action whose
        ``P(x'|x,u) > min_prob``; see :func:`topomap.core.map.files.to_networkx`."""
        return files.to_networkx(self, min_prob)

    def to_graphml(self, path, min_prob: float = 0.0) -> Path:
        """Write :meth:`to_networkx` as GraphML (list attributes joined with ``;``)."""
        return files.to_graphml(self, path, min_prob)

    def to_dict(self) -> dict:
        """The map as a JSON object (:func:`topomap.core.map.files.to_dict`)."""
        return files.to_dict(self)

    def save(self, path) -> Path:
        """Write the map as JSON (atomically: the file appears only when complete)."""
        return files.save(self, path)

    @classmethod
    def from_dict(cls, d: dict) -> "TopologicalMap":
        """The map described by ``d`` (what :meth:`to_dict` returns), every field checked: a
        problem is a one-line ValueError naming the field, e.g. ``states[3].covariance``."""
        return files.from_dict(cls, d)

    @classmethod
    def load(cls, path) -> "TopologicalMap":
        """Read a map written by :meth:`save`; any problem is a one-line ValueError naming the
        file and the field."""
        return files.load(cls, path)

    # ------------------------------------------------------------------ names the README used
    @property
    def state_gds_(self) -> np.ndarray:
        """:attr:`state_gds` (read only)."""
        return self.state_gds

    @property
    def action_probs_(self) -> np.ndarray:
        """:attr:`action_probs`."""
        return self.action_probs

    @property
    def transition_probs_(self) -> np.ndarray:
        """:attr:`transition_probs`."""
        return self.transition_probs

    def __repr__(self) -> str:
        return (f"TopologicalMap(n_states={self.n_states}, n_actions={self.n_actions}, "
                f"n_features={self.n_features})")


def _normalised(log_belief: np.ndarray) -> np.ndarray:
    """``exp(log_belief)`` scaled to sum to 1 (a belief that lost all mass is an error)."""
    m = np.max(log_belief)
    if not np.isfinite(m):
        raise ValueError("no state of the map can explain this observation (every state has "
                         "probability 0; check the GDS labels)")
    b = np.exp(log_belief - m)
    return b / b.sum()
