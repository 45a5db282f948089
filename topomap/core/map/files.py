"""A map's files and the checks of its fields.

* JSON (version :data:`FORMAT_VERSION`): :func:`to_dict` / :func:`from_dict` and :func:`save` /
  :func:`load`, which :class:`~topomap.core.map.model.TopologicalMap`'s methods of the same names
  call.  Every field read is checked: a problem is a one-line ValueError naming the field, e.g.
  ``states[3].covariance``; a file's counts must also be those of one walk
  (:func:`check_counts`), which :func:`save` checks too, so it never writes what :func:`load`
  refuses.
* A graph: :func:`to_networkx` and :func:`to_graphml`.
* The checks every map passes when it is made (:func:`checked_fields`, :func:`check_tables`),
  whether it comes from a file or from the learner; their messages name the JSON fields.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..data.atomic import atomic_write

__all__ = ["FORMAT_VERSION", "checked_fields", "check_tables", "check_counts", "to_dict",
           "from_dict", "save", "load", "to_networkx", "to_graphml"]

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
    first = {}
    for k, row in enumerate(rows):
        if not (isinstance(row, list) and len(row) == 4 and all(_is_int(v) for v in row)):
            raise ValueError(f"transitions[{k}] must be [state, action, next_state, count] "
                             f"(integers), got {_short(row)}")
        x, a, y, n = row
        if not (0 <= x < S and 0 <= a < A and 0 <= y < S and 0 <= n <= _INT_LIMIT):
            raise ValueError(f"transitions[{k}] = {row} is out of range (states 0..{S - 1}, "
                             f"actions 0..{A - 1}, a count >= 0)")
        if (x, a, y) in first:
            raise ValueError(f"transitions[{k}] repeats (state, action, next_state) = "
                             f"({x}, {a}, {y}) of transitions[{first[x, a, y]}]; each is "
                             "listed once, with its count")
        first[x, a, y] = k
        trans[x, a, y] = n
    return trans


def _json_names(d: dict, key: str):
    """Optional field ``key``: null or a list of strings."""
    names = d.get(key)
    if names is not None and not (isinstance(names, list)
                                  and all(isinstance(n, str) for n in names)):
        raise ValueError(f"field {key} must be a list of strings or null, got {_short(names)}")
    return names


#: the map's array fields: (attribute, the JSON field an error names, integer or float)
ARRAY_FIELDS = (("state_symbol", "states[*].symbol", True), ("state_gds", "states[*].gds", True),
                ("state_parent", "states[*].parent", True), ("means", "states[*].mean", False),
                ("covariances", "states[*].covariance", False),
                ("state_counts", "states[*].count", True),
                ("action_counts", "states[*].action_counts", True),
                ("transition_counts", "transitions", True))


def checked_fields(m) -> dict:
    """The fields of the map ``m`` as it keeps them: int64 / float64 arrays, lists of names,
    lists of (copied) records and an info dict; a ValueError names the first bad field."""
    out = {name: _array(getattr(m, name), where, integer) for name, where, integer in ARRAY_FIELDS}
    for name in ("action_names", "gds_names"):
        value = getattr(m, name)
        out[name] = None if value is None else _names(value, name)
    out["split_history"] = _records(m.split_history, "split_history")
    out["entropy_history"] = _records(m.entropy_history, "entropies")
    if m.info is not None and not isinstance(m.info, dict):
        raise ValueError(f"info must be a dict (a JSON object), got {_short(m.info)}")
    out["info"] = dict(m.info or {})
    return out


def check_tables(m) -> None:
    """The tables of ``m`` (checked by :func:`checked_fields`) fit together; see
    :func:`_check_shapes` and :func:`_check_values`."""
    _check_shapes(m)
    _check_values(m)


def _check_shapes(m) -> None:
    """Every table has the shape the state, action and feature counts give it."""
    if m.action_counts.ndim != 2 or 0 in m.action_counts.shape:
        raise ValueError("states[*].action_counts must form a non-empty (n_states, n_actions) "
                         f"table, got shape {m.action_counts.shape}")
    S, A = m.action_counts.shape
    for key, arr in (("symbol", m.state_symbol), ("gds", m.state_gds),
                     ("parent", m.state_parent), ("count", m.state_counts)):
        if arr.shape != (S,):
            raise ValueError(f"states[*].{key} must be one integer for each of the {S} "
                             f"states, got shape {arr.shape}")
    if m.means.ndim != 2 or m.means.shape[0] != S or m.means.shape[1] == 0:
        raise ValueError(f"states[*].mean must form a ({S}, n_features) array, got shape "
                         f"{m.means.shape}")
    D = m.means.shape[1]
    if m.covariances.shape not in ((S, D), (S, D, D)):
        raise ValueError(f"states[*].covariance must form a ({S}, {D}) or ({S}, {D}, {D}) "
                         f"array, got shape {m.covariances.shape}")
    if m.transition_counts.shape != (S, A, S):
        raise ValueError(f"transitions must form a ({S}, {A}, {S}) table, got shape "
                         f"{m.transition_counts.shape}")


def _check_values(m) -> None:
    """Counts are >= 0, observation models are proper Gaussians, ids refer to what exists."""
    S, A = m.action_counts.shape
    _require(m.state_counts >= 0, "count must be >= 0")
    _require(m.action_counts >= 0, "action_counts must be >= 0")
    _require(m.transition_counts >= 0, "transitions: counts must be >= 0")
    _require(np.isfinite(m.means), "mean must hold finite numbers")
    if m.covariances.ndim == 2:
        _require(np.isfinite(m.covariances) & (m.covariances > 0),
                 "covariance must hold finite variances > 0")
    else:
        _require([_is_covariance(c) for c in m.covariances],
                 "covariance must be a symmetric positive definite matrix")
    symbol, gds, parent = m.state_symbol, m.state_gds, m.state_parent
    _require((symbol >= -1) & (gds >= -1) & ((symbol >= 0) != (gds >= 0)),
             "symbol and .gds: one must be >= 0 and the other -1")
    _require((parent >= -1) & (parent < np.arange(S)), "parent must be -1 or an earlier state")
    if m.action_names is not None and len(m.action_names) < A:
        raise ValueError(f"action_names has {len(m.action_names)} names but the map has "
                         f"{A} actions")
    if m.gds_names is not None and len(m.gds_names) <= gds.max():
        raise ValueError(f"gds_names has {len(m.gds_names)} names but states use GDS id "
                         f"{int(gds.max())}")


def check_counts(m) -> None:
    """The counts of the map ``m`` are those of one labelled walk, as in every map topomap
    learns (``count_tables``; ``partial_fit`` adds each new step once and each transition
    between its steps once): for every state ``s``

    * ``states[s].action_counts`` sum to ``states[s].count``: every step takes one action;
    * the transitions leaving ``s`` by action ``a`` number at most ``action_counts[a]``: each
      leaves from one step of ``s`` that took ``a`` (an episode's last step leaves by none);
    * the transitions arriving in ``s`` number at most ``states[s].count``: each arrives at one
      step of ``s`` (an episode's first step is reached by none).

    A map made in Python may hold any counts; a map file may not (:func:`load`, :func:`save`).
    Sums are taken in floats, which no hostile count can wrap around."""
    steps = m.action_counts.sum(axis=1, dtype=np.float64)
    s = _first_bad(steps == m.state_counts)
    if s is not None:
        raise ValueError(f"states[{s}].action_counts sum to {steps[s]:.0f} but states[{s}].count "
                         f"is {m.state_counts[s]}: every step takes one action")
    leaving = m.transition_counts.sum(axis=2, dtype=np.float64)
    s = _first_bad(leaving <= m.action_counts)
    if s is not None:
        a = int(np.flatnonzero(leaving[s] > m.action_counts[s])[0])
        raise ValueError(f"transitions leave state {s} by action {a} {leaving[s, a]:.0f} times "
                         f"but states[{s}].action_counts[{a}] is {m.action_counts[s, a]}: each "
                         "leaves from a step counted there")
    arriving = m.transition_counts.sum(axis=(0, 1), dtype=np.float64)
    s = _first_bad(arriving <= m.state_counts)
    if s is not None:
        raise ValueError(f"transitions arrive in state {s} {arriving[s]:.0f} times but "
                         f"states[{s}].count is {m.state_counts[s]}: each arrives at a step "
                         "counted there")


# ------------------------------------------------------------------ JSON
def to_dict(m) -> dict:
    """The JSON object of the map ``m`` (what :func:`save` writes, keys sorted)."""
    xs, us, ys = np.nonzero(m.transition_counts)
    return {
        "format": "topomap.map",
        "version": FORMAT_VERSION,
        "n_states": m.n_states,
        "n_actions": m.n_actions,
        "n_features": m.n_features,
        "covariance_type": m.covariance_type,
        "action_names": m.action_names,
        "gds_names": m.gds_names,
        "states": [
            {
                "id": s,
                "symbol": int(m.state_symbol[s]),
                "gds": int(m.state_gds[s]),
                "parent": int(m.state_parent[s]),
                "count": int(m.state_counts[s]),
                "mean": m.means[s].tolist(),
                "covariance": m.covariances[s].tolist(),
                "action_counts": m.action_counts[s].tolist(),
            }
            for s in range(m.n_states)
        ],
        "transitions": [[int(a), int(b), int(c), int(m.transition_counts[a, b, c])]
                        for a, b, c in zip(xs, us, ys)],
        "split_history": m.split_history,
        "entropies": m.entropy_history,
        "info": m.info,
    }


def finite_json(obj):
    """``obj`` (dicts, lists, numbers) with non-finite floats as None (strict JSON's null)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    return obj


def save(m, path) -> Path:
    """Write the map ``m`` as JSON (atomically: the file appears only when complete)."""
    path = Path(path)
    try:
        check_counts(m)
    except ValueError as exc:
        raise ValueError(f"map file {path} not written: {exc}") from None
    d = {**to_dict(m), "info": finite_json(m.info)}  # strict JSON: no Infinity / NaN literals
    text = json.dumps(d, indent=1, sort_keys=True, allow_nan=False)

    def write(tmp):
        Path(tmp).write_text(text + "\n")

    atomic_write(path, write)
    return path


def from_dict(cls, d: dict):
    """The map (of class ``cls``) described by ``d``, what :func:`to_dict` returns; every field
    is checked, and the counts with :func:`check_counts`."""
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
    m = cls(col["symbol"], col["gds"], col["parent"], col["mean"], col["covariance"],
            col["count"], col["action_counts"],
            _json_transitions(_field(d, "transitions"), S, A),
            action_names=_json_names(d, "action_names"), gds_names=_json_names(d, "gds_names"),
            split_history=d.get("split_history", ()),
            entropy_history=d.get("entropies", ()), info=d.get("info"))
    check_counts(m)
    return m


def load(cls, path):
    """Read a map (of class ``cls``) written by :func:`save`; any problem is a one-line
    ValueError naming the file and the field."""
    path = Path(path)
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        reason = "it is nested too deeply" if isinstance(exc, RecursionError) else exc
        raise ValueError(f"map file {path} could not be read as JSON: {reason}") from None
    try:
        return from_dict(cls, d)
    except ValueError as exc:
        raise ValueError(f"map file {path}: {exc}") from None


# ------------------------------------------------------------------ graphs
def to_networkx(m, min_prob: float = 0.0):
    """A ``networkx.DiGraph`` of the map ``m``: one node per state, one arc per ``(x, x')`` with
    an action whose ``P(x'|x,u) > min_prob`` (and at least one observed transition).

    Arc attributes: ``actions`` (list of action ids), ``action_names``, ``probs`` (the
    probabilities), ``prob`` (the largest) and ``count`` (transitions observed).
    """
    import networkx as nx

    P = m.transition_probs
    C = m.transition_counts
    G = nx.DiGraph()
    for s in range(m.n_states):
        G.add_node(s, label=m.state_label(s), symbol=int(m.state_symbol[s]),
                   gds=int(m.state_gds[s]), parent=int(m.state_parent[s]),
                   count=int(m.state_counts[s]))
    xs, us, ys = np.nonzero((C > 0) & (P > min_prob))
    for x, a, y in zip(xs.tolist(), us.tolist(), ys.tolist()):
        name = m.action_label(a)
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


def to_graphml(m, path, min_prob: float = 0.0) -> Path:
    """Write :func:`to_networkx` of ``m`` as GraphML (list attributes joined with ``;``)."""
    import networkx as nx

    G = to_networkx(m, min_prob)
    for _, _, d in G.edges(data=True):
        d["actions"] = ";".join(str(a) for a in d["actions"])
        d["action_names"] = ";".join(d["action_names"])
        d["probs"] = ";".join(f"{p:.6g}" for p in d["probs"])
    path = Path(path)
    atomic_write(path, lambda tmp: nx.write_graphml(G, tmp))
    return path
