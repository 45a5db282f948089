"""Property-based tests (hypothesis): the learner's invariants on random small worlds, and the
loaders' behaviour on random, truncated and ill-typed input.

Every example is tiny (a few places, at most 60 steps) and the examples are derandomized, so the
file runs the same in CI every time.
"""

import functools
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from topomap import MapLearner, TopologicalMap, Trajectory, load_trajectory, save_trajectory
from topomap.core import check_sequences

# fixed examples (derandomize) and no example database: CI sees the same inputs on every run
LEARN = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
FUZZ = settings(max_examples=300, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])


# ---------------------------------------------------------------- random small worlds
@dataclass
class World:
    """A walk through a random deterministic world, ready for the learner."""

    X: np.ndarray
    u: np.ndarray
    gds: np.ndarray | None
    lengths: list[int]
    places: np.ndarray
    n_actions: int


@st.composite
def worlds(draw) -> World:
    """A random successor table over 2-6 places and 1-3 actions, few observation symbols (so
    places are aliased), a random walk of 12-60 steps in 1-3 episodes, one-hot or 2-D noisy
    observations and, sometimes, one place that is a GDS."""
    n_places = draw(st.integers(2, 6))
    n_actions = draw(st.integers(1, 3))
    cells = n_places * n_actions
    succ = np.array(draw(st.lists(st.integers(0, n_places - 1), min_size=cells, max_size=cells)))
    symbol = np.array(draw(st.lists(st.integers(0, max(1, n_places - 2)), min_size=n_places,
                                    max_size=n_places)))
    T = draw(st.integers(12, 60))
    cuts = sorted(draw(st.sets(st.integers(1, T - 1), max_size=2)))
    lengths = np.diff([0, *cuts, T]).tolist()
    gds_place = draw(st.none() | st.integers(0, n_places - 1))
    one_hot = draw(st.booleans())
    noise = draw(st.sampled_from([0.01, 0.2]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    u = rng.integers(0, n_actions, T)
    places = np.empty(T, dtype=np.int64)
    t = 0
    for n in lengths:
        places[t] = rng.integers(n_places)
        for s in range(t + 1, t + n):
            places[s] = succ[places[s - 1] * n_actions + u[s - 1]]
        t += n
    emit = np.eye(symbol.max() + 1) if one_hot else rng.normal(0, 1, (symbol.max() + 1, 2))
    X = emit[symbol[places]] + rng.normal(0, noise, (T, emit.shape[1]))
    gds = None if gds_place is None else np.where(places == gds_place, 0, -1)
    return World(X, u, gds, lengths, places, n_actions)


@st.composite
def fitted(draw):
    """``(world, learner)``: a learner with random small settings fitted on a random world."""
    w = draw(worlds())
    n_plain = len(w.X) if w.gds is None else int(np.sum(w.gds < 0))
    assume(n_plain >= 1)
    ns = draw(st.integers(1, min(5, n_plain)))
    n_gds = 0 if w.gds is None else int(np.any(w.gds >= 0))
    learner = MapLearner(n_clusters=ns, n_states=ns + n_gds + draw(st.integers(0, 6)), n_init=1,
                         covariance_type=draw(st.sampled_from(["diag", "full"])),
                         random_state=draw(st.integers(0, 1000)))
    return w, learner.fit(w.X, w.u, gds=w.gds, lengths=w.lengths, n_actions=w.n_actions)


# ---------------------------------------------------------------- the learner's invariants
@LEARN
@given(fitted())
def test_a_split_never_raises_action_and_transition_entropy(case):
    _, learner = case
    e = learner.entropies_
    assert len(e) == len(learner.split_history_) + 1
    for before, after in zip(e, e[1:]):
        assert after["H_u"] + after["H_x"] <= before["H_u"] + before["H_x"] + 1e-9
        assert after["H_o"] == pytest.approx(before["H_o"], abs=1e-9)  # splits keep P(o|x)
    final = learner.map_.entropies()
    for key in ("H_o", "H_u", "H_x"):
        assert final[key] == pytest.approx(e[-1][key], abs=1e-9)


@LEARN
@given(fitted())
def test_splitting_refines_phase_one_along_the_parent_links(case):
    w, learner = case
    m, m1 = learner.map_, learner.map_phase1_
    x, x1 = learner.labels_, learner.labels_phase1_
    assert m.n_states == learner.n_states or learner.stop_reason_ == "no state can be split"
    for s in range(m.n_states):
        root = s
        while m.state_parent[root] >= 0:
            assert m.state_parent[root] < root  # a state is split from an older one
            root = int(m.state_parent[root])
        assert root < m1.n_states
        # every step of a final state had the same phase-1 state: the root of its parent links
        assert set(x1[x == s].tolist()) <= {root}
        assert m.state_symbol[s] == m1.state_symbol[root]
        assert m.state_gds[s] == m1.state_gds[root]
    # the phase-1 state of a step is its K-means symbol, or its GDS state
    plain = x1 < learner.n_clusters_
    assert np.array_equal(m1.state_symbol[x1[plain]], x1[plain])
    if w.gds is not None:
        assert np.array_equal(plain, w.gds < 0)
        assert np.all(m.state_parent[m.state_gds >= 0] == -1)  # GDS states are never split


@LEARN
@given(fitted())
def test_a_saved_map_loads_and_scores_identically(case):
    w, learner = case
    m = learner.map_
    with tempfile.TemporaryDirectory() as tmp:
        m2 = TopologicalMap.load(m.save(Path(tmp) / "map.json"))
    data = (w.X, w.u, w.gds, w.lengths)
    assert m2.to_dict() == m.to_dict()
    assert m2.score(*data) == m.score(*data)
    assert np.array_equal(m2.predict(*data), m.predict(*data))


@LEARN
@given(fitted())
def test_the_same_seed_gives_the_same_map(case):
    w, learner = case
    from sklearn.base import clone

    twin = clone(learner).fit(w.X, w.u, gds=w.gds, lengths=w.lengths, n_actions=w.n_actions)
    with tempfile.TemporaryDirectory() as tmp:
        a = learner.map_.save(Path(tmp) / "a.json").read_bytes()
        b = twin.map_.save(Path(tmp) / "b.json").read_bytes()
    assert a == b


# ---------------------------------------------------------------- random and ill-typed values
def any_array(max_dims=3):
    """Arrays of any scalar dtype (numbers, strings, bytes, dates) and small shapes."""
    return hnp.arrays(hnp.scalar_dtypes(), hnp.array_shapes(min_dims=0, max_dims=max_dims,
                                                              max_side=7))


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-2, 8) | st.integers(-10**20, 10**20)
    | st.text(max_size=5)
    | st.floats(allow_nan=True, allow_infinity=True),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner,
                                                                max_size=3),
    max_leaves=8)
any_value = any_array() | json_values


def base_sequences():
    """A valid ``(observations, actions, gds, lengths)`` of 6 steps in two episodes."""
    rng = np.random.default_rng(0)
    return {"observations": rng.normal(size=(6, 2)), "actions": np.array([0, 1, 1, 0, 2, 1]),
            "gds": np.array([-1, 0, -1, -1, 1, -1]), "lengths": np.array([3, 3])}


@FUZZ
@given(field=st.sampled_from(["observations", "actions", "gds", "lengths"]), value=any_value)
def test_check_sequences_names_the_bad_field(field, value):
    args = dict(base_sequences(), **{field: value})
    try:
        X, u, g, L = check_sequences(**args)
    except ValueError as exc:
        assert field in str(exc) and "\n" not in str(exc), str(exc)
        return
    assert X.dtype == np.float64 and X.ndim == 2 and np.isfinite(X).all()
    assert u.shape == g.shape == (X.shape[0],) and u.min() >= 0 and g.min() >= -1
    assert L.sum() == X.shape[0] and L.min() > 0


# ---------------------------------------------------------------- files: random, truncated, ill-typed
def folder_listing(folder: Path) -> list[str]:
    """The names in ``folder`` (hidden temporary files included)."""
    return sorted(p.name for p in folder.iterdir())


def expect_value_error(load, path: Path, *names):
    """``load(path)`` succeeds or raises a one-line ValueError naming the file and one of
    ``names``; it writes nothing into the file's folder."""
    before = folder_listing(path.parent)
    try:
        result = load(path)
    except ValueError as exc:
        msg = str(exc)
        assert str(path) in msg and "\n" not in msg, msg
        assert not names or any(n in msg for n in names), (names, msg)
        result = None
    assert folder_listing(path.parent) == before
    return result


def valid_trajectory() -> Trajectory:
    """Eight steps in two episodes with every optional field set."""
    rng = np.random.default_rng(1)
    T = 8
    return Trajectory(rng.normal(size=(T, 2)), rng.integers(0, 3, T),
                      gds=np.where(np.arange(T) % 4 == 0, 0, -1), places=rng.integers(0, 4, T),
                      positions=rng.uniform(size=(T, 2)), lengths=[5, 3],
                      action_names=["a", "b", "c"], gds_names=["door"])


@functools.cache
def valid_map_json() -> str:
    """The JSON text of a map learned (once) on :func:`valid_trajectory`."""
    t = valid_trajectory()
    m = MapLearner(n_clusters=3, n_states=5, n_init=1).fit_trajectory(t).map_
    return json.dumps(m.to_dict())


def valid_map_dict() -> dict:
    """A fresh copy of a map learned on :func:`valid_trajectory`, as the JSON object it saves."""
    return json.loads(valid_map_json())


def valid_file(folder: Path, suffix: str) -> bytes:
    """The bytes of a valid file written by the package (a trajectory or a map)."""
    if suffix == ".json":
        path = folder / "valid.json"
        path.write_text(json.dumps(valid_map_dict()))
    else:
        path = save_trajectory(valid_trajectory(), folder / f"valid{suffix}")
    data = path.read_bytes()
    path.unlink()
    return data


LOADERS = {".npz": load_trajectory, ".csv": load_trajectory, ".json": TopologicalMap.load}


@functools.cache
def valid_bytes(suffix: str) -> bytes:
    """The bytes of a valid ``suffix`` file, made once."""
    with tempfile.TemporaryDirectory() as tmp:
        return valid_file(Path(tmp), suffix)


@FUZZ
@given(suffix=st.sampled_from(sorted(LOADERS)), junk=st.binary(max_size=300))
def test_random_bytes_raise_a_value_error_naming_the_file(suffix, junk):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"junk{suffix}"
        path.write_bytes(junk)
        expect_value_error(LOADERS[suffix], path)


@FUZZ
@given(suffix=st.sampled_from(sorted(LOADERS)), cut=st.floats(0, 1, exclude_max=True),
       flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(0, 255)),
                      max_size=3))
def test_truncated_or_corrupted_files_raise_a_value_error_naming_the_file(suffix, cut, flips):
    data = bytearray(valid_bytes(suffix))
    for where, byte in flips:  # a few bytes overwritten, then the file cut short
        data[int(where * len(data))] = byte
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"cut{suffix}"
        path.write_bytes(bytes(data[:int(cut * len(data))]))
        expect_value_error(LOADERS[suffix], path)


NPZ_FIELDS = ["observations", "actions", "gds", "places", "positions", "lengths",
              "action_names", "gds_names"]


@FUZZ
@given(field=st.sampled_from(NPZ_FIELDS), value=any_array(), drop=st.booleans())
def test_an_ill_typed_npz_array_is_named(field, value, drop):
    t = valid_trajectory()
    arrays = {k: getattr(t, k) for k in NPZ_FIELDS}
    if drop:
        del arrays[field]
    else:
        arrays[field] = value
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.npz"
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)
        loaded = expect_value_error(load_trajectory, path, field)
    if loaded is not None:
        assert len(loaded) > 0 and loaded.observations.dtype == np.float64


@FUZZ
@given(row=st.integers(0, 8), col=st.integers(0, 8), text=st.text(max_size=6))
def test_an_ill_typed_csv_cell_is_named(row, col, text):
    lines = valid_bytes(".csv").decode().splitlines()
    cells = lines[row].split(",")
    cells[min(col, len(cells) - 1)] = text
    lines[row] = ",".join(cells)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.csv"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        expect_value_error(load_trajectory, path)


def json_paths(d, prefix=()):
    """Every path (tuple of keys and indices) into a JSON value."""
    yield prefix
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        yield from json_paths(v, (*prefix, k))


MAP_PATHS = [p for p in json_paths(valid_map_dict()) if p]


@FUZZ
@given(where=st.sampled_from(MAP_PATHS), value=json_values, delete=st.booleans())
def test_an_ill_typed_map_field_is_named(where, value, delete):
    d = valid_map_dict()
    *parents, last = where
    node = d
    for k in parents:
        node = node[k]
    if delete and isinstance(node, dict):
        del node[last]
    else:
        node[last] = value
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "map.json"
        path.write_text(json.dumps(d))
        keys = [k for k in where if isinstance(k, str)]
        m = expect_value_error(TopologicalMap.load, path, *keys)
    if m is not None:  # a change the format allows: the map still works on data
        t = valid_trajectory()
        assert np.isfinite(m.score(t.observations, t.actions))
        assert m.predict(t.observations, t.actions).shape == (len(t),)


def test_deeply_nested_json_is_a_value_error(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    expect_value_error(TopologicalMap.load, path)


# ---------------------------------------------------------------- saving
@FUZZ
@given(suffix=st.sampled_from([".npz", ".csv"]), field=st.sampled_from(NPZ_FIELDS[:6]),
       value=any_array())
def test_save_trajectory_writes_a_loadable_file_or_nothing(suffix, field, value):
    t = valid_trajectory()
    setattr(t, field, value)  # a field changed after validation
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"t{suffix}"
        try:
            save_trajectory(t, path)
        except ValueError as exc:
            assert field in str(exc) and str(path) in str(exc), str(exc)
            assert os.listdir(tmp) == []
            return
        assert os.listdir(tmp) == [path.name]
        assert len(load_trajectory(path)) == len(t)  # what was written reads back


def test_save_trajectory_interrupted_while_writing_leaves_no_file(tmp_path, monkeypatch):
    def broken(fh, **arrays):
        """Half a file, then the disk is full."""
        fh.write(b"PK\x03\x04 half a zip")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", broken)
    with pytest.raises(OSError, match="disk full"):
        save_trajectory(valid_trajectory(), tmp_path / "t.npz")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="must end in .npz or .csv"):
        save_trajectory(valid_trajectory(), tmp_path / "t.txt")
    assert list(tmp_path.iterdir()) == []
