import numpy as np
import pytest

from topomap import Trajectory, load_trajectory, save_trajectory


def make(T=20, seed=0):
    rng = np.random.default_rng(seed)
    return Trajectory(
        observations=rng.normal(size=(T, 3)), actions=rng.integers(0, 4, T),
        gds=np.where(np.arange(T) % 7 == 0, 1, -1), places=rng.integers(0, 5, T),
        positions=rng.uniform(size=(T, 2)), lengths=[T - 5, 5],
        action_names=["a", "b", "c", "d"], gds_names=["g0", "g1"],
    )


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_roundtrip(tmp_path, suffix):
    t = make()
    path = save_trajectory(t, tmp_path / f"run{suffix}")
    r = load_trajectory(path)
    assert np.array_equal(r.observations, t.observations)  # repr() keeps floats exact in CSV
    for key in ("actions", "gds", "places", "positions", "lengths"):
        assert np.array_equal(getattr(r, key), getattr(t, key)), key
    if suffix == ".npz":
        assert r.action_names == t.action_names and r.gds_names == t.gds_names


def test_minimal_csv_by_hand(tmp_path):
    p = tmp_path / "log.csv"
    p.write_text("o0,o1,action\n0.5,1,0\n0.25,2,1\n1,3,1\n")
    t = load_trajectory(p)
    assert t.observations.tolist() == [[0.5, 1], [0.25, 2], [1, 3]]
    assert t.actions.tolist() == [0, 1, 1] and t.gds is None and t.lengths is None


def test_a_spreadsheet_export_with_a_byte_order_mark_reads_as_without(tmp_path):
    p = tmp_path / "excel.csv"
    p.write_bytes(b"\xef\xbb\xbfo0,o1,action\r\n0.5,1,0\r\n0.25,2,1\r\n")
    t = load_trajectory(p)
    assert t.observations.tolist() == [[0.5, 1], [0.25, 2]] and t.actions.tolist() == [0, 1]


def test_actions_by_name_get_ids_in_order_of_first_appearance(tmp_path):
    p = tmp_path / "named.csv"
    p.write_text("o0,action\n1,north\n2,east\n3,north\n4,west\n")
    t = load_trajectory(p)
    assert t.actions.tolist() == [0, 1, 0, 2] and t.action_names == ["north", "east", "west"]


def test_a_misspelt_column_names_the_nearest(tmp_path):
    p = tmp_path / "typo.csv"
    p.write_text("o0,acton\n1,0\n")
    with pytest.raises(ValueError, match=r"unknown column\(s\) 'acton'; did you mean 'action'\?"):
        load_trajectory(p)


@pytest.mark.parametrize("text, match", [
    ("o0,action\n1,0\nx,1\n", "line 3, column 'o0': 'x' is not a number"),
    ("o0,action\n1,0\n2\n", "line 3: 1 fields"),
    ("o0,speed\n1,0\n", "unknown column"),
    ("o0,o1\n1,0\n", "no 'action' column"),
    ("o0,action\n1,0.5\n", "actions must hold integers"),
    ("o0,action\n", "no data rows"),
    ("", "is empty"),
    ("o0,action,x\n1,0,1\n", "position column.*x; positions need the columns x and y"),
    ("o0,action,x,z\n1,0,1,2\n", "position column.*x, z; positions need"),
])
def test_malformed_csv(tmp_path, text, match):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_trajectory(p)


def test_malformed_npz(tmp_path):
    p = tmp_path / "bad.npz"
    p.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="bad.npz"):
        load_trajectory(p)
    np.savez(tmp_path / "noact.npz", observations=np.zeros((4, 2)))
    with pytest.raises(ValueError, match="lacks the array.*actions"):
        load_trajectory(tmp_path / "noact.npz")
    np.savez(tmp_path / "obj.npz", observations=np.array([{"a": 1}], dtype=object),
             actions=np.zeros(1))
    with pytest.raises(ValueError, match="obj.npz"):
        load_trajectory(tmp_path / "obj.npz")
    np.savez(tmp_path / "len.npz", observations=np.zeros((4, 2)), actions=np.zeros(3, int))
    with pytest.raises(ValueError, match="actions has 3 entries"):
        load_trajectory(tmp_path / "len.npz")


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        load_trajectory(tmp_path / "nope.npz")
    (tmp_path / "x.txt").write_text("1")
    with pytest.raises(ValueError, match="must end in .npz, .csv or .csv.gz"):
        load_trajectory(tmp_path / "x.txt")


def test_failed_save_leaves_no_file(tmp_path):
    t = make()
    t.observations = np.array(["not", "numbers"], dtype=object)  # breaks while writing
    with pytest.raises(Exception):
        save_trajectory(t, tmp_path / "out.csv")
    assert list(tmp_path.iterdir()) == []


def test_names_must_cover_ids():
    with pytest.raises(ValueError, match="only 2 action_names"):
        Trajectory(np.zeros((3, 1)), [0, 1, 2], action_names=["a", "b"])
    with pytest.raises(ValueError, match="positions must have shape"):
        Trajectory(np.zeros((3, 1)), [0, 1, 1], positions=np.zeros((3, 4)))


@pytest.mark.filterwarnings("ignore:Number of distinct clusters")  # one step dwarfs the rest
def test_observations_too_large_to_square_name_the_file_the_field_and_the_overflow(tmp_path):
    """1e300 squared is beyond float64 (1.8e308): the file is refused, naming it, the field,
    the step and the column, where the learner once failed later on an infinite variance of
    ``states[0].covariance``.  1e100 is far below the bound (about 2e152 for 300 x 3 values)."""
    from topomap import MapLearner

    rng = np.random.default_rng(0)
    X, u = rng.normal(size=(300, 3)), rng.integers(0, 3, 300)
    X[5, 1] = 1e300
    path = tmp_path / "big.npz"
    np.savez(path, observations=X, actions=u)
    with pytest.raises(ValueError, match=rf"^trajectory file {path}: observations hold 1e\+300 "
                       r"\(step 5, column 1\), too large: the variances and distances the "
                       r"learner sums over these 300 x 3 values would overflow float64 \(\|x\| "
                       r"must stay below 2.2e\+152\); rescale the observations"):
        load_trajectory(path)
    with pytest.raises(ValueError, match=r"^observations hold 1e\+300 \(step 5, column 1\)"):
        MapLearner(n_clusters=3, n_states=5).fit(X, u)
    X[5, 1] = -1e100
    assert MapLearner(n_clusters=3, n_states=5).fit(X, u).map_.n_states == 5


def test_nan_rows_across_blocks_are_counted_before_any_value_too_large(monkeypatch):
    # blocks of 4 rows: a value too large at step 1, NaN at steps 6 and 9 and inf at step 13
    # (three blocks): the rows that are not finite are named, all three, from step 6
    from topomap.core.data import trajectory

    monkeypatch.setattr(trajectory, "_BLOCK_ROWS", 4)
    X, u = np.zeros((16, 2)), np.zeros(16, dtype=int)
    X[1, 0], X[6, 1], X[9, 0], X[13, 1] = 1e300, np.nan, np.nan, np.inf
    with pytest.raises(ValueError, match=r"^observations contain NaN or inf in 3 row\(s\), "
                       r"first at step 6$"):
        trajectory.check_sequences(X, u)
    X[[6, 9, 13]] = 0.0  # then the value too large, in the block where it lies
    X[14, 0] = -2e300
    with pytest.raises(ValueError, match=r"^observations hold 1e\+300 \(step 1, column 0\)"):
        trajectory.check_sequences(X, u)

