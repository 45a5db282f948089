"""The learned topological map: a POMDP-style model over discrete states.

A :class:`TopologicalMap` holds, for every state, where it came from (its K-means symbol or its
GDS id, and the state it was split from), the Gaussian observation model ``P(o|x)``, the counts
behind ``P(u|x)`` and ``P(x'|x,u)``, and the learning record (split history and the three entropies
after phase 1 and after every split).  It decodes new sequences (:meth:`predict`, Viterbi), scores
them (:meth:`score`, forward algorithm), exports a graph (:meth:`to_networkx`, :meth:`to_graphml`)
and round-trips through JSON (:meth:`save`, :meth:`load`).

Observation models are *tied*: states split from the same symbol share that symbol's Gaussian, as
in the paper, where splitting refines the state set without touching ``P(o|x)``.  Hence
``H(o|x)`` is left unchanged by every split.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from . import inference
from ..data.files import atomic_write
from ..stats import conditional_entropy, count_tables, episode_masks, normalise
from .observations import observation_models
from ..data.trajectory import as_float_observations

__all__ = ["TopologicalMap", "FORMAT_VERSION"]

FORMAT_VERSION = 1


# ------------------------------------------------------------------ checking a map's fields
#: the largest magnitude a count or id may have (it must fit an int64 exactly)
_INT_LIMIT = 2**53


def _short(value) -> str:
    """A one-line repr of ``value``, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _is_int(value) -> bool:
    """Whether ``value`` is an integer (a JSON integer; booleans are not)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _array(values, name: str, integer: bool) -> np.ndarray:
    """``values`` as an int64 or float64 array, or a ValueError naming ``name``."""
    what = "integers" if integer else "numbers"
    try:
        arr = np.asarray(values)
    except (ValueError, TypeError):
        raise ValueError(f"{name} must be a rectangular array of {what}, "
                         f"got {_short(values)}") from None
    if arr.dtype.kind not in ("iu" if integer else "iuf"):
        raise ValueError(f"{name} must hold {what}, got {_short(values)}")
    if integer and arr.size and (arr.max() > _INT_LIMIT or arr.min() < -_INT_LIMIT):
        raise ValueError(f"{name} holds an integer beyond +-2**53: {_short(values)}")
    return arr.astype(np.int64 if integer else np.float64)


def _first_bad(ok) -> int | None:
    """The first state (row of ``ok``) with a False entry, or None."""
    ok = np.asarray(ok).reshape(len(ok), -1).all(axis=1)
    return None if ok.all() else int(np.flatnonzero(~ok)[0])


def _require(ok, message: str) -> None:
    """Raise ``states[i].<message>`` for the first state ``i`` where ``ok`` is False."""
    i = _first_bad(ok)
    if i is not None:
        raise ValueError(f"states[{i}].{message}")


def _is_covariance(c: np.ndarray) -> bool:
    """Whether ``c`` is a symmetric positive definite matrix of finite numbers."""
    if not (np.all(np.isfinite(c)) and np.allclose(c, c.T)):
        return False
    try:
        np.linalg.cholesky(c)
    except np.linalg.LinAlgError:
        return False
    return True


def _names(values, name: str) -> list:
    """``values`` as a list (of names), or a ValueError naming ``name``."""
    if isinstance(values, (str, bytes, dict)):
        raise ValueError(f"{name} must be a list of names, got {_short(values)}")
    try:
        return list(values)
    except TypeError:
        raise ValueError(f"{name} must be a list of names, got {_short(values)}") from None


def _records(values, name: str) -> list[dict]:
    """``values`` as a list of dicts (copied), or a ValueError naming ``name``."""
    if isinstance(values, (str, bytes, dict)) or not hasattr(values, "__iter__"):
        raise ValueError(f"{name} must be a list of records, got {_short(values)}")
    out = []
    for k, record in enumerate(values):
        if not isinstance(record, dict):
            raise ValueError(f"{name}[{k}] must be a record (a JSON object), got {_short(record)}")
        out.append(dict(record))
    return out


def _field(d: dict, key: str, where: str = ""):
    """``d[key]``, or a ValueError naming the missing field ``<where>.<key>``."""
    if key not in d:
        raise ValueError(f"field {where}{'.' if where else ''}{key} is missing")
    return d[key]


def _positive_int(d: dict, key: str) -> int:
    """Field ``key`` of ``d``, which must be an integer >= 1."""
    value = _field(d, key)
    if not _is_int(value) or not 1 <= value <= _INT_LIMIT:
        raise ValueError(f"field {key} must be a positive integer, got {_short(value)}")
    return int(value)


def _state_column(states: list, key: str, integer: bool) -> np.ndarray:
    """Field ``key`` of every state, stacked; a ValueError names ``states[i].<key>``."""
    rows = [_array(_field(st, key, f"states[{i}]"), f"states[{i}].{key}", integer)
            for i, st in enumerate(states)]
    for i, row in enumerate(rows):
        if row.shape != rows[0].shape:
            raise ValueError(f"states[{i}].{key} has shape {row.shape} but states[0].{key} "
                             f"has shape {rows[0].shape}")
    return np.stack(rows)


def _json_states(d: dict) -> list[dict]:
    """The ``states`` list of a map's JSON object, checked to be states 0..n_states-1."""
    S = _positive_int(d, "n_states")
    states = _field(d, "states")
    if not isinstance(states, list):
        raise ValueError(f"field states must be a list, got {_short(states)}")
    if len(states) != S:
        raise ValueError(f"field states has {len(states)} entries but n_states is {S}")
    for i, st in enumerate(states):
        if not isinstance(st, dict):
            raise ValueError(f"states[{i}] must be a JSON object, got {_short(st)}")
        if not (_is_int(_field(st, "id", f"states[{i}]")) and st["id"] == i):
            raise ValueError(f"states[{i}].id is {_short(st['id'])}; states must be listed in "
                             "order 0..n_states-1")
    return states


def _json_transitions(rows, S: int, A: int) -> np.ndarray:
    """The (S, A, S) transition counts from the JSON rows ``[state, action, next_state, count]``."""
    if not isinstance(rows, list):
        raise ValueError(f"field transitions must be a list of rows, got {_short(rows)}")
    trans = np.zeros((S, A, S), dtype=np.int64)
    for k, row in enumerate(rows):
        if not (isinstance(row, list) and len(row) == 4 and all(_is_int(v) for v in row)):
            raise ValueError(f"transitions[{k}] must be [state, action, next_state, count] "
                             f"(integers), got {_short(row)}")
        x, a, y, n = row
        if not (0 <= x < S and 0 <= a < A and 0 <= y < S and 0 <= n <= _INT_LIMIT):
            raise ValueError(f"transitions[{k}] = {row} is out of range (states 0..{S - 1}, "
                             f"actions 0..{A - 1}, a count >= 0)")
        trans[x, a, y] = n
    return trans


def _json_names(d: dict, key: str):
    """Optional field ``key``: null or a list of strings."""
    names = d.get(key)
    if names is not None and not (isinstance(names, list)
                                  and all(isinstance(n, str) for n in names)):
        raise ValueError(f"field {key} must be a list of strings or null, got {_short(names)}")
    return names


class TopologicalMap:
    """A learned map.  Usually made by :class:`topomap.MapLearner`; see the module docstring.

    Parameters
    ----------
    state_symbol : (S,) int -- K-means symbol of each state, -1 for GDS states
    state_gds : (S,) int -- GDS id of each state, -1 for ordinary states
    state_parent : (S,) int -- the state each state was split from, -1 for phase-1 states
    means : (S, D) float -- observation mean of each state's symbol (or GDS)
    covariances : (S, D, D) or (S, D) float -- covariance ("full") or variances ("diag")
    state_counts : (S,) int -- steps in each state
    action_counts : (S, A) int -- steps in each state taking each action
    transition_counts : (S, A, S) int -- transitions ``(x, u) -> x'`` inside episodes
    """

    def __init__(self, state_symbol, state_gds, state_parent, means, covariances, state_counts,
                 action_counts, transition_counts, *, action_names=None, gds_names=None,
                 split_history=(), entropies=(), info=None):
        self.state_symbol_ = _array(state_symbol, "states[*].symbol", integer=True)
        self.state_gds_ = _array(state_gds, "states[*].gds", integer=True)
        self.state_parent_ = _array(state_parent, "states[*].parent", integer=True)
        self.means_ = _array(means, "states[*].mean", integer=False)
        self.covariances_ = _array(covariances, "states[*].covariance", integer=False)
        self.state_counts_ = _array(state_counts, "states[*].count", integer=True)
        self.action_counts_ = _array(action_counts, "states[*].action_counts", integer=True)
        self.transition_counts_ = _array(transition_counts, "transitions", integer=True)
        self.action_names = None if action_names is None else _names(action_names, "action_names")
        self.gds_names = None if gds_names is None else _names(gds_names, "gds_names")
        self.split_history_ = _records(split_history, "split_history")
        self.entropies_ = _records(entropies, "entropies")
        if info is not None and not isinstance(info, dict):
            raise ValueError(f"info must be a dict (a JSON object), got {_short(info)}")
        self.info = dict(info or {})
        self._check_shapes()
        self._check_values()

    def _check_shapes(self) -> None:
        """Every table has the shape the state, action and feature counts give it."""
        if self.action_counts_.ndim != 2 or 0 in self.action_counts_.shape:
            raise ValueError("states[*].action_counts must form a non-empty (n_states, n_actions) "
                             f"table, got shape {self.action_counts_.shape}")
        S, A = self.action_counts_.shape
        for key, arr in (("symbol", self.state_symbol_), ("gds", self.state_gds_),
                         ("parent", self.state_parent_), ("count", self.state_counts_)):
            if arr.shape != (S,):
                raise ValueError(f"states[*].{key} must be one integer for each of the {S} "
                                 f"states, got shape {arr.shape}")
        if self.means_.ndim != 2 or self.means_.shape[0] != S or self.means_.shape[1] == 0:
            raise ValueError(f"states[*].mean must form a ({S}, n_features) array, got shape "
                             f"{self.means_.shape}")
        D = self.means_.shape[1]
        if self.covariances_.shape not in ((S, D), (S, D, D)):
            raise ValueError(f"states[*].covariance must form a ({S}, {D}) or ({S}, {D}, {D}) "
                             f"array, got shape {self.covariances_.shape}")
        if self.transition_counts_.shape != (S, A, S):
            raise ValueError(f"transitions must form a ({S}, {A}, {S}) table, got shape "
                             f"{self.transition_counts_.shape}")

    def _check_values(self) -> None:
        """Counts are >= 0, observation models are proper Gaussians, ids refer to what exists."""
        S, A = self.action_counts_.shape
        _require(self.state_counts_ >= 0, "count must be >= 0")
        _require(self.action_counts_ >= 0, "action_counts must be >= 0")
        _require(self.transition_counts_ >= 0, "transitions: counts must be >= 0")
        _require(np.isfinite(self.means_), "mean must hold finite numbers")
        if self.covariances_.ndim == 2:
            _require(np.isfinite(self.covariances_) & (self.covariances_ > 0),
                     "covariance must hold finite variances > 0")
        else:
            _require([_is_covariance(c) for c in self.covariances_],
                     "covariance must be a symmetric positive definite matrix")
        symbol, gds, parent = self.state_symbol_, self.state_gds_, self.state_parent_
        _require((symbol >= -1) & (gds >= -1) & ((symbol >= 0) != (gds >= 0)),
                 "symbol and .gds: one must be >= 0 and the other -1")
        _require((parent >= -1) & (parent < np.arange(S)), "parent must be -1 or an earlier state")
        if self.action_names is not None and len(self.action_names) < A:
            raise ValueError(f"action_names has {len(self.action_names)} names but the map has "
                             f"{A} actions")
        if self.gds_names is not None and len(self.gds_names) <= gds.max():
            raise ValueError(f"gds_names has {len(self.gds_names)} names but states use GDS id "
                             f"{int(gds.max())}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_labels(cls, observations, actions, labels, *, lengths=None, state_symbol, state_gds,
                    state_parent, n_actions, covariance_type="diag", reg_covar=1e-3, **kwargs):
        """Estimate every table from a labelled sequence (labels in ``[0, S)``).

        The observation model of a state is the Gaussian of all steps sharing its symbol (or its
        GDS id); ``reg_covar`` times the mean feature variance of the data is added to every
        variance so that a constant feature does not make the density degenerate.
        """
        X = as_float_observations(observations)
        u = np.asarray(actions, dtype=np.int64)
        x = np.asarray(labels, dtype=np.int64)
        T = X.shape[0]
        S = len(state_symbol)
        A = int(n_actions)
        L = np.array([T]) if lengths is None else np.asarray(lengths)
        _, has_next = episode_masks(T, L)
        symbol = np.asarray(state_symbol)
        gds = np.asarray(state_gds)
        # a "model id" per state: symbols, then GDS ids after them
        n_sym = int(symbol.max()) + 1 if (symbol >= 0).any() else 0
        model_of_state = np.where(symbol >= 0, symbol, n_sym + gds)
        M = int(model_of_state.max()) + 1
        mean_m, cov_m, _ = observation_models(X, model_of_state[x], M, covariance_type, reg_covar)
        state_counts, action_counts, trans = count_tables(x, u, S, A, has_next)
        info = dict(kwargs.pop("info", None) or {})
        info.setdefault("covariance_type", covariance_type)
        return cls(state_symbol, state_gds, state_parent, mean_m[model_of_state],
                   cov_m[model_of_state], state_counts, action_counts, trans, info=info, **kwargs)

    # ------------------------------------------------------------------ sizes and tables
    @property
    def n_states(self) -> int:
        return int(self.state_counts_.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.action_counts_.shape[1])

    @property
    def n_features(self) -> int:
        return int(self.means_.shape[1])

    @property
    def covariance_type(self) -> str:
        return "full" if self.covariances_.ndim == 3 else "diag"

    @property
    def state_probs_(self) -> np.ndarray:
        """(S,) share of steps in each state."""
        return self.state_counts_ / max(self.state_counts_.sum(), 1)

    @property
    def action_probs_(self) -> np.ndarray:
        """(S, A) ``P(u|x)``; a state never seen gets a uniform row."""
        return normalise(self.action_counts_)

    @property
    def transition_probs_(self) -> np.ndarray:
        """(S, A, S) ``P(x'|x,u)``; an ``(x, u)`` never seen gets a uniform row."""
        return normalise(self.transition_counts_)

    # ------------------------------------------------------------------ entropies
    def state_entropies(self) -> np.ndarray:
        """(S,) differential entropy in bits of each state's Gaussian observation model."""
        if self.covariance_type == "diag":
            logdet = np.log2(self.covariances_).sum(axis=1)
        else:
            logdet = np.linalg.slogdet(self.covariances_)[1] / np.log(2)
        return 0.5 * (self.n_features * np.log2(2 * np.pi * np.e) + logdet)

    def entropies(self) -> dict:
        """``H(o|x)``, ``H(u|x)``, ``H(x'|x,u)`` in bits (``H(o|x)`` is a differential entropy)."""
        return {
            "H_o": float(self.state_probs_ @ self.state_entropies()),
            "H_u": conditional_entropy(self.action_counts_),
            "H_x": conditional_entropy(self.transition_counts_),
        }

    # ------------------------------------------------------------------ inference
    def _log_obs(self, X: np.ndarray) -> np.ndarray:
        """(T, S) Gaussian log-densities (:func:`topomap.core.map.inference.log_densities`)."""
        return inference.log_densities(self, np.asarray(X, dtype=np.float64))

    def predict(self, observations, actions, gds=None, lengths=None, *, smoothing=1e-6,
                prune=True) -> np.ndarray:
        """Most likely state of every step of a new sequence (Viterbi).

        Uses the Gaussian observation likelihoods, ``P(u|x)`` and ``P(x'|x,u)``; ``smoothing`` mixes
        a small uniform share into every table so unseen transitions are unlikely, not impossible.
        With ``gds`` given, GDS steps are clamped to their GDS state and other steps never take
        one.  ``prune`` skips states far below a step's best (exact; see
        :mod:`topomap.core.map.inference`).  Memory does not grow with T beyond the path.
        """
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.viterbi(s)

    def score(self, observations, actions, gds=None, lengths=None, *, smoothing=1e-6,
              prune=True) -> float:
        """Mean log-likelihood per step (natural log, forward algorithm) of a new sequence.

        Observations are continuous, so this is a log-*density* (it can be positive)."""
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.forward(s)

    def filter(self, observations, actions, gds=None, lengths=None, *, smoothing=1e-6,
               prune=True) -> np.ndarray:
        """Belief over the states at every step given only the past (forward filtering).

        Row ``t`` is ``P(x_t | o_1..o_t, u_1..u_{t-1})``: the step's own observation counts, its
        action (chosen after it) does not; every row sums to 1 and each episode of ``lengths``
        starts afresh from the map's state frequencies.  :meth:`predict` decodes the whole
        sequence at once (Viterbi) instead.  Returns a (T, S) float array.
        """
        s = inference.setup(self, observations, actions, gds, lengths, smoothing, prune)
        return inference.filtered(s)

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
            return _normalised(s["log_init"] + emit)
        belief = np.asarray(belief, dtype=np.float64)
        if belief.shape != (self.n_states,) or not np.isclose(belief.sum(), 1.0):
            raise ValueError(f"belief must be a probability vector over the {self.n_states} states")
        if not (isinstance(action, (int, np.integer)) and 0 <= action < self.n_actions):
            raise ValueError(f"action must be an action id in [0, {self.n_actions}), got {action!r}")
        return _normalised(np.log(inference.predicted(s, belief, int(action))) + emit)

    def plan(self, start: int, goal, *, min_prob: float = 0.0) -> list[int]:
        """Actions of the most probable path from state ``start`` to ``goal`` (a state or an
        iterable of states, e.g. the GDS states; the nearest one is taken).

        The path maximises the product of ``max_u P(x'|x,u)`` over its arcs (networkx's Dijkstra
        on ``-log P``); each step's action is the one that makes its arc most probable.  Arcs are
        those observed at least once with a probability above ``min_prob``.  Returns ``[]`` when
        ``start`` is a goal; raises ValueError when no goal can be reached.
        """
        import networkx as nx

        goals = {int(goal)} if isinstance(goal, (int, np.integer)) else {int(x) for x in goal}
        for s in goals | {int(start)}:
            if not 0 <= s < self.n_states:
                raise ValueError(f"state {s} is not a state of this map (0..{self.n_states - 1})")
        if not goals:
            raise ValueError("goal must name at least one state")
        if int(start) in goals:
            return []
        graph = self._planning_graph(min_prob)
        try:
            _, path = nx.multi_source_dijkstra(graph.reverse(copy=False), goals, int(start))
        except nx.NetworkXNoPath:
            raise ValueError(f"no goal state of {sorted(goals)} can be reached from state {start} "
                             f"through arcs with P(x'|x,u) > {min_prob}") from None
        path = path[::-1]
        return [graph.edges[x, y]["action"] for x, y in zip(path[:-1], path[1:])]

    def _planning_graph(self, min_prob: float):
        """The arcs :meth:`plan` may use, weighted by ``-log max_u P(x'|x,u)`` (cached)."""
        import networkx as nx

        cache = self.__dict__.setdefault("_plan_graphs", {})
        if min_prob not in cache:
            P = np.where(self.transition_counts_ > 0, self.transition_probs_, 0.0)
            best = P.argmax(axis=1)  # (S, S'): the action of each arc
            prob = np.take_along_axis(P, best[:, None, :], axis=1)[:, 0, :]
            graph = nx.DiGraph()
            graph.add_nodes_from(range(self.n_states))
            for x, y in zip(*np.nonzero(prob > min_prob)):
                graph.add_edge(int(x), int(y), weight=float(-np.log(prob[x, y])),
                               action=int(best[x, y]))
            cache[min_prob] = graph
        return cache[min_prob]

    # ------------------------------------------------------------------ graphs
    def state_label(self, s: int) -> str:
        if self.state_gds_[s] >= 0:
            g = int(self.state_gds_[s])
            return self.gds_names[g] if self.gds_names else f"GDS{g}"
        return f"s{s}"

    def to_networkx(self, min_prob: float = 0.0):
        """A ``networkx.DiGraph``: one node per state, one arc per ``(x, x')`` with an action whose
        ``P(x'|x,u) > min_prob`` (and at least one observed transition).

        Arc attributes: ``actions`` (list of action ids), ``action_names``, ``probs`` (the
        probabilities), ``prob`` (the largest) and ``count`` (transitions observed).
        """
        import networkx as nx

        P = self.transition_probs_
        C = self.transition_counts_
        G = nx.DiGraph()
        for s in range(self.n_states):
            G.add_node(s, label=self.state_label(s), symbol=int(self.state_symbol_[s]),
                       gds=int(self.state_gds_[s]), parent=int(self.state_parent_[s]),
                       count=int(self.state_counts_[s]))
        xs, us, ys = np.nonzero((C > 0) & (P > min_prob))
        for x, a, y in zip(xs.tolist(), us.tolist(), ys.tolist()):
            name = self.action_names[a] if self.action_names else str(a)
            if G.has_edge(x, y):
                d = G.edges[x, y]
                d["actions"].append(a)
                d["action_names"].append(name)
                d["probs"].append(float(P[x, a, y]))
                d["prob"] = max(d["probs"])
                d["count"] += int(C[x, a, y])
            else:
                G.add_edge(x, y, actions=[a], action_names=[name], probs=[float(P[x, a, y])],
                           prob=float(P[x, a, y]), count=int(C[x, a, y]))
        return G

    def to_graphml(self, path, min_prob: float = 0.0) -> Path:
        """Write :meth:`to_networkx` as GraphML (list attributes joined with ``;``)."""
        import networkx as nx

        G = self.to_networkx(min_prob)
        for _, _, d in G.edges(data=True):
            d["actions"] = ";".join(str(a) for a in d["actions"])
            d["action_names"] = ";".join(d["action_names"])
            d["probs"] = ";".join(f"{p:.6g}" for p in d["probs"])
        path = Path(path)
        atomic_write(path, lambda tmp: nx.write_graphml(G, tmp))
        return path

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        xs, us, ys = np.nonzero(self.transition_counts_)
        return {
            "format": "topomap.map",
            "version": FORMAT_VERSION,
            "n_states": self.n_states,
            "n_actions": self.n_actions,
            "n_features": self.n_features,
            "covariance_type": self.covariance_type,
            "action_names": self.action_names,
            "gds_names": self.gds_names,
            "states": [
                {
                    "id": s,
                    "symbol": int(self.state_symbol_[s]),
                    "gds": int(self.state_gds_[s]),
                    "parent": int(self.state_parent_[s]),
                    "count": int(self.state_counts_[s]),
                    "mean": self.means_[s].tolist(),
                    "covariance": self.covariances_[s].tolist(),
                    "action_counts": self.action_counts_[s].tolist(),
                }
                for s in range(self.n_states)
            ],
            "transitions": [[int(a), int(b), int(c), int(self.transition_counts_[a, b, c])]
                            for a, b, c in zip(xs, us, ys)],
            "split_history": self.split_history_,
            "entropies": self.entropies_,
            "info": self.info,
        }

    def save(self, path) -> Path:
        """Write the map as JSON (atomically: the file appears only when complete)."""
        path = Path(path)
        text = json.dumps(self.to_dict(), indent=1, sort_keys=True)

        def write(tmp):
            Path(tmp).write_text(text + "\n")

        atomic_write(path, write)
        return path

    @classmethod
    def from_dict(cls, d: dict) -> "TopologicalMap":
        """The map described by ``d`` (what :meth:`to_dict` returns), every field checked: a
        problem is a one-line ValueError naming the field, e.g. ``states[3].covariance``."""
        if not isinstance(d, dict):
            raise ValueError(f"a map must be a JSON object, got {_short(d)}")
        if d.get("format") != "topomap.map":
            raise ValueError(f"field format must be 'topomap.map', got {_short(d.get('format'))}")
        if not _is_int(d.get("version")) or d["version"] != FORMAT_VERSION:
            raise ValueError(f"field version is {_short(d.get('version'))}; this topomap reads "
                             f"version {FORMAT_VERSION}")
        states = _json_states(d)
        S, A, D = len(states), _positive_int(d, "n_actions"), _positive_int(d, "n_features")
        col = {key: _state_column(states, key, integer=key not in ("mean", "covariance"))
               for key in ("symbol", "gds", "parent", "mean", "covariance", "count",
                           "action_counts")}
        kind = _field(d, "covariance_type")
        if kind not in ("diag", "full"):
            raise ValueError(f"field covariance_type must be 'diag' or 'full', got {_short(kind)}")
        shapes = {"action_counts": (A,), "mean": (D,),
                  "covariance": (D,) if kind == "diag" else (D, D)}
        for key, shape in shapes.items():
            if col[key].shape[1:] != shape:
                raise ValueError(f"states[*].{key} must each have shape {shape} (n_actions={A}, "
                                 f"n_features={D}, covariance_type={kind}), got "
                                 f"{col[key].shape[1:]}")
        return cls(col["symbol"], col["gds"], col["parent"], col["mean"], col["covariance"],
                   col["count"], col["action_counts"],
                   _json_transitions(_field(d, "transitions"), S, A),
                   action_names=_json_names(d, "action_names"),
                   gds_names=_json_names(d, "gds_names"),
                   split_history=d.get("split_history", ()), entropies=d.get("entropies", ()),
                   info=d.get("info"))

    @classmethod
    def load(cls, path) -> "TopologicalMap":
        """Read a map written by :meth:`save`; any problem is a one-line ValueError naming the
        file and the field."""
        path = Path(path)
        try:
            d = json.loads(Path(path).read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            reason = "it is nested too deeply" if isinstance(exc, RecursionError) else exc
            raise ValueError(f"map file {path} could not be read as JSON: {reason}") from None
        try:
            return cls.from_dict(d)
        except ValueError as exc:
            raise ValueError(f"map file {path}: {exc}") from None

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
