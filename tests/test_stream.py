"""The streamed fit (MapLearner.fit_stream): logs read in chunks give the in-memory fit's states."""

import gzip
import math

import numpy as np
import pytest

from topomap import MapLearner, Trajectory, save_trajectory
from topomap.core.checks import ParameterError
from topomap.core.data.logs import Logs
from topomap.metrics import adjusted_rand
from topomap.core.split.engine import Splitter
from topomap.core.split.criteria import EntropyCriterion
from topomap.core.stats import episode_masks
from topomap.core.stream.moments import chunk_moments, combine

import reference_splitting as ref
from worlds import ring


def _save(folder, parts, suffix=".npz"):
    """Write every (X, u, gds) of ``parts`` as ``log-<i><suffix>``; returns the folder."""
    folder.mkdir(exist_ok=True)
    for i, (X, u, g) in enumerate(parts):
        save_trajectory(Trajectory(X, u, gds=g), folder / f"log-{i}{suffix}")
    return folder


def _cut(X, u, g, sizes):
    bounds = np.cumsum([0, *sizes])
    return [(X[a:b], u[a:b], None if g is None else g[a:b]) for a, b in zip(bounds, bounds[1:])]


def _aliased_walk(T, ns, n_places, D=15, A=17, seed=0):
    """A random walk on a random graph of ``n_places`` places showing ``ns`` views (places
    past the first ``ns`` repeat one of them), read with Gaussian noise 0.02."""
    rng = np.random.default_rng(seed)
    succ = rng.integers(0, n_places, size=(n_places, A))
    view = np.concatenate([np.arange(ns), rng.integers(0, ns, n_places - ns)])
    centres = rng.uniform(0, 1, size=(ns, D))
    u = rng.integers(0, A, size=T)
    places = np.empty(T, dtype=np.int64)
    p = 0
    for t in range(T):
        places[t], p = p, succ[p, u[t]]
    return centres[view[places]] + rng.normal(0, 0.02, size=(T, D)), u


def test_ring_logs_split_by_hand(tmp_path):
    # The one-way ring A -> B -> C -> D -> A with B and D alike (test_learner's case), cut into
    # four logs, one episode each: the split gains exactly 1 bit (each half of the merged state
    # has one successor), and no transition is counted across two logs: T - 4 of them.
    X, u, places = ring(n_steps=400, n_places=4, aliased=[(1, 3)], two_way=False)
    folder = _save(tmp_path / "logs", _cut(X, u, None, [100, 120, 80, 100]))
    learner = MapLearner(n_clusters=3, n_states=4).fit_stream(folder)
    (rec,) = learner.split_history_
    assert rec["gain"] == pytest.approx(1.0, abs=0.02)
    assert adjusted_rand(places, learner.labels_) == 1.0
    assert learner.map_.transition_counts.sum() == 400 - 4
    assert learner.stream_info_["logs"] == 4 and learner.stream_info_["steps"] == 400
    assert learner.labels_.dtype == np.int16
    # in memory the split keeps 2 bytes a step too, and gives the user int64 labels: the same
    fitted = MapLearner(n_clusters=3, n_states=4).fit(X, u, lengths=[100, 120, 80, 100])
    assert fitted.labels_.dtype == np.int64 and np.array_equal(fitted.labels_, learner.labels_)


def _same_fit(a, b):
    """The streamed fit ``b`` has the in-memory fit ``a``'s states, step for step, and its
    counts; the observation models agree up to rounding."""
    assert a.phase1_method_ == b.phase1_method_
    assert np.array_equal(a.labels_phase1_, b.labels_phase1_)
    assert np.array_equal(a.labels_, b.labels_)
    for name in ("state_counts", "action_counts", "transition_counts", "state_symbol",
                 "state_gds", "state_parent"):
        assert np.array_equal(getattr(a.map_, name), getattr(b.map_, name)), name
    assert np.allclose(a.map_.means, b.map_.means, rtol=0, atol=1e-12)
    assert np.allclose(a.map_.covariances, b.map_.covariances, rtol=1e-12, atol=0)
    assert [r["gain"] for r in a.split_history_] == pytest.approx(
        [r["gain"] for r in b.split_history_], abs=1e-12)


@pytest.mark.parametrize("covariance_type", ["diag", "full"])
def test_streamed_equals_in_memory_with_gds_and_csv_gz(tmp_path, covariance_type):
    # every non-GDS row clustered ("full"): a .csv.gz log beside .npz logs, GDS steps in two
    X, u, _ = ring(n_steps=900, n_places=6, aliased=[(1, 4)], seed=3)
    g = np.full(900, -1)
    g[[5, 300, 301, 700]] = [2, 0, 0, 2]
    parts = _cut(X, u, g, [250, 350, 300])
    folder = _save(tmp_path / "logs", parts[:2])
    save_trajectory(Trajectory(*parts[2][:2], gds=parts[2][2]), tmp_path / "last.csv")
    (folder / "log-2.csv.gz").write_bytes(gzip.compress((tmp_path / "last.csv").read_bytes()))
    kw = dict(n_clusters=5, n_states=8, covariance_type=covariance_type)
    # the csv holds the shortest repr of each float: read back, the same values
    a = MapLearner(**kw).fit(X, u, gds=g, lengths=[250, 350, 300])
    b = MapLearner(**kw).fit_stream(folder)
    _same_fit(a, b)
    assert b.map_.state_gds.tolist().count(-1) == b.map_.n_states - 2


def test_streamed_equals_in_memory_on_a_sample(tmp_path):
    # T * ns * D above 1e7: K-means on 20,000 sampled rows, every row given its nearest centre;
    # the streamed fit draws the same rows and assigns them in chunks of 7,000 steps
    X, u = _aliased_walk(40_000, ns=20, n_places=40)
    folder = _save(tmp_path / "logs", _cut(X, u, None, [15_000, 25_000]))
    kw = dict(n_clusters=20, n_states=40, random_state=1)
    a = MapLearner(**kw).fit(X, u, lengths=[15_000, 25_000])
    b = MapLearner(**kw).fit_stream(folder, chunk_steps=7_000)
    assert b.phase1_method_ == "sample"
    _same_fit(a, b)


def test_moments_of_chunks_combine_to_those_of_all_rows():
    rng = np.random.default_rng(0)
    X, group = rng.normal(size=(1000, 3)), rng.integers(0, 4, 1000)
    for full in (False, True):
        whole = chunk_moments(X, group, 4, full)
        parts = combine(chunk_moments(X[:300], group[:300], 4, full),
                        chunk_moments(X[300:], group[300:], 4, full))
        for k in range(4):
            rows = X[group == k]
            r = rows - rows.mean(axis=0)
            m2 = r.T @ r if full else (r * r).sum(axis=0)
            assert parts.n[k] == whole.n[k] == rows.shape[0]
            assert np.allclose(parts.mean[k], rows.mean(axis=0), atol=1e-14)
            assert np.allclose(parts.m2[k], m2, rtol=1e-12)


def test_compact_labels_split_as_the_numpy_code():
    # int64 labels and actions, or int16 and int8: the engine keeps 2 and 1 bytes a step and
    # makes the plain numpy phase 2's splits
    X, u, _ = ring(n_steps=600, n_places=8, aliased=[(1, 4), (2, 6)], seed=2)
    labels = MapLearner(n_clusters=6, n_states=6).fit(X, u).labels_phase1_
    expected = ref.splits(labels, u, 6, 2, [600], 4)
    for lab, act in ((labels, u), (labels.astype(np.int16), u.astype(np.int8))):
        s = Splitter(lab, act, 2, *episode_masks(600, [600]), symbol=list(range(6)),
                     gds=[-1] * 6, obs_entropy=np.zeros(6), criterion=EntropyCriterion())
        assert s.labels.dtype == np.int16 and s.engine.u.dtype == np.int8
        for state, _, x in expected:
            assert s.best().state == state
            s.apply(s.best())
            assert np.array_equal(s.labels, x)
    assert len(expected) == 4


def test_action_names_made_consistent(tmp_path):
    # two logs naming the same actions in another order: ids renumbered by name
    X, u, _ = ring(n_steps=400, seed=1)
    names = np.array(["forward", "back"])
    first = Trajectory(X[:200], u[:200], action_names=names)
    second = Trajectory(X[200:], 1 - u[200:], action_names=names[::-1])
    b = MapLearner(n_clusters=5, n_states=6).fit_stream([first, second])
    a = MapLearner(n_clusters=5, n_states=6).fit(X, u, lengths=[200, 200],
                                                 action_names=list(names))
    _same_fit(a, b)
    assert b.map_.action_names == ["forward", "back"]


def test_bad_logs_name_the_file(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match=r"log folder .*empty holds no logs"):
        MapLearner().fit_stream(tmp_path / "empty")
    X, u, _ = ring(n_steps=100)
    folder = _save(tmp_path / "logs", [(X, u, None), (X[:, :4], u, None)])
    with pytest.raises(ValueError, match=r"log .*log-1\.npz has observations of 4 features, "
                                         r"log .*log-0\.npz of 5"):
        MapLearner(n_clusters=5, n_states=6).fit_stream(folder)
    (folder / "log-1.npz").write_bytes(b"PK\x03\x04 half a zip")
    with pytest.raises(ValueError, match=r"log-1\.npz is not a valid \.npz file") as err:
        MapLearner(n_clusters=5, n_states=6).fit_stream(folder)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match=r"log .*nope\.npz does not exist"):
        MapLearner().fit_stream([folder / "log-0.npz", folder / "nope.npz"])


@pytest.mark.parametrize("params, name", [({"refine": "em"}, "refine"),
                                          ({"n_states": "auto"}, "n_states"),
                                          ({"metric": "standardized"}, "metric"),
                                          ({"phase1": "distinct"}, "phase1")])
def test_settings_a_stream_cannot_run(tmp_path, params, name):
    X, u, _ = ring(n_steps=100)
    with pytest.raises(ParameterError) as err:
        MapLearner(n_clusters=5, **params).fit_stream([Trajectory(X, u)])
    assert err.value.param == name


def test_chunks_of_a_log(tmp_path):
    # an uncompressed .npz log is read in chunks from the file: rows as stored, as float64
    X = np.arange(60, dtype=np.float32).reshape(20, 3)
    u = np.arange(20) % 3
    path = tmp_path / "big.npz"
    np.savez(path, observations=X, actions=u)
    logs = Logs([path], chunk_steps=8)
    assert logs.survey(0).steps == 20 and logs.chunks(0, 20) == [(0, 8), (8, 16), (16, 20)]
    rows, acts, gds = logs.rows(0, 8, 16)
    assert rows.dtype == np.float64 and np.array_equal(rows, X[8:16])
    assert np.array_equal(acts, u[8:16]) and np.all(gds == -1)
    assert np.array_equal(logs.plain_rows(0, np.array([1, 19])), X[[1, 19]])
    assert math.isclose(float(rows.sum()), float(X[8:16].sum()))


def test_data_file_reads_a_folder_as_episodes(tmp_path):
    # `data=file data.path=<folder>`: every log in name order, each an episode, places kept
    from topomap.app.components.data import FromFile

    X, u, places = ring(n_steps=300, seed=4)
    folder = tmp_path / "logs"
    folder.mkdir()
    for name, (a, b) in (("b.npz", (100, 300)), ("a.npz", (0, 100))):
        save_trajectory(Trajectory(X[a:b], u[a:b], places=places[a:b]), folder / name)
    traj = FromFile(str(folder)).train(None, 0)
    assert traj.lengths.tolist() == [100, 200]
    assert np.array_equal(traj.observations, X) and np.array_equal(traj.places, places)
    (folder / "c.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"c\.npz is not a valid \.npz file"):
        FromFile(str(folder)).train(None, 0)


def test_a_generator_of_trajectories_and_mixed_logs(tmp_path):
    X, u, _ = ring(n_steps=300, seed=6)
    parts = [Trajectory(X[a:b], u[a:b]) for a, b in ((0, 120), (120, 300))]
    b = MapLearner(n_clusters=5, n_states=6).fit_stream(t for t in parts)
    a = MapLearner(n_clusters=5, n_states=6).fit(X, u, lengths=[120, 300 - 120])
    _same_fit(a, b)
    save_trajectory(parts[0], tmp_path / "a.npz")
    with pytest.raises(ValueError, match="logs must be paths or Trajectory objects"):
        MapLearner().fit_stream([tmp_path / "a.npz", parts[1]])


def test_compact_labels_widen_past_int16():
    # 32,767 states (all but 6 empty): the second split makes state 32,768, past int16; the
    # labels become int32 and the splits stay those of the plain numpy phase 2
    X, u, _ = ring(n_steps=600, n_places=8, aliased=[(1, 4), (2, 6)], seed=2)
    labels = MapLearner(n_clusters=6, n_states=6).fit(X, u).labels_phase1_
    S = 2**15 - 1
    expected = ref.splits(labels, u, S, 2, [600], 3)
    s = Splitter(labels, u, 2, *episode_masks(600, [600]), symbol=list(range(S)),
                 gds=[-1] * S, obs_entropy=np.zeros(S), criterion=EntropyCriterion())
    assert s.labels.dtype == np.int16
    for _, _, x in expected:
        s.apply(s.best())
        assert np.array_equal(s.labels, x)
    assert s.labels.dtype == np.int32 and s.labels.max() == S + 2
