"""The robot's odometry as input: the checks that name the field and the step, and the moves in
the robot's frame -- on small walks whose answer follows by hand."""

import numpy as np
import pytest

from topomap import MapLearner
from topomap.core.checks import ParameterError
from topomap.core.motion.inputs import MAX_ODOMETRY_STEP, check_odometry, odometry_moves


def _square(n=4, side=1.0):
    """Drive ``side`` east, turn left, ``side`` north, ... : the poses of a square."""
    x = [0.0, side, side, 0.0][:n]
    y = [0.0, 0.0, side, side][:n]
    th = [0.0, np.pi / 2, np.pi, -np.pi / 2][:n]
    return np.column_stack([x, y, th])


def test_check_odometry_keeps_good_odometry_as_float64():
    O = check_odometry(_square().tolist(), 4)
    assert O.dtype == np.float64 and O.shape == (4, 3)
    assert check_odometry(None, 4) is None


@pytest.mark.parametrize("bad, words", [
    (np.zeros((4, 2)), "shape (4, 3)"),
    (np.zeros((5, 3)), "5 rows but observations has 4 rows"),
    (np.zeros(12), "shape (4, 3)"),
    ("odometry.csv", "must be numbers"),
])
def test_check_odometry_names_the_field_and_the_shape(bad, words):
    with pytest.raises(ParameterError, match="odometry") as err:
        check_odometry(bad, 4)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_check_odometry_names_the_first_step_that_is_not_finite():
    O = _square()
    O[2, 2] = np.nan
    O[3, 0] = np.inf
    with pytest.raises(ParameterError, match="odometry contains NaN or inf in 2 row.s., first at step 2"):
        check_odometry(O, 4)


def test_check_odometry_names_a_jump_and_its_step():
    O = _square(side=0.5)
    O[3:, 0] += MAX_ODOMETRY_STEP + 1  # the fourth pose: 0.5 m west and 3 m east of the third
    with pytest.raises(ParameterError, match=r"odometry moves 2.5 m from step 2 to step 3"):
        check_odometry(O, 4)


def test_a_jump_between_episodes_is_a_new_start_not_an_error():
    O = _square(side=0.5)
    O[2:, 0] += 10.0  # the second episode starts 10 m off
    assert check_odometry(O, 4, lengths=[2, 2]).shape == (4, 3)
    with pytest.raises(ParameterError, match="step 2"):
        check_odometry(O, 4, lengths=[4])


def test_odometry_moves_are_in_the_frame_of_the_step_before():
    # a square driven anticlockwise: every move is 1 m forward, 0 left, then a quarter turn
    d = odometry_moves(_square(), [4])
    np.testing.assert_allclose(d[0], [0, 0, 0])
    np.testing.assert_allclose(d[1], [1, 0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(d[2], [1, 0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(d[3], [1, 0, np.pi / 2], atol=1e-12)


def test_odometry_moves_do_not_depend_on_the_frame_the_odometry_started_in():
    O = _square()
    c, s = np.cos(0.7), np.sin(0.7)
    moved = np.column_stack([3 + c * O[:, 0] - s * O[:, 1], -2 + s * O[:, 0] + c * O[:, 1],
                             O[:, 2] + 0.7])
    np.testing.assert_allclose(odometry_moves(moved, [4]), odometry_moves(O, [4]), atol=1e-12)
    assert not odometry_moves(O, [2, 2])[2].any()  # an episode's first step has no move


def test_the_learner_checks_odometry_in_fit_partial_fit_predict_and_score():
    rng = np.random.default_rng(0)
    X, u = rng.normal(size=(60, 2)), rng.integers(0, 2, 60)
    learner = MapLearner(n_clusters=3, n_states=4, random_state=0)
    with pytest.raises(ParameterError, match=r"odometry must have shape \(60, 3\)"):
        learner.fit(X, u, odometry=np.zeros((60, 2)))
    learner.fit(X, u, odometry=np.zeros((60, 3)))
    with pytest.raises(ParameterError, match="odometry contains NaN or inf .* first at step 5"):
        learner.predict(X, u, odometry=np.where(np.arange(60)[:, None] == 5, np.nan, 0.0)
                        * np.ones((60, 3)))
    with pytest.raises(ParameterError, match="odometry has 59 rows but observations has 60"):
        learner.score(X, u, odometry=np.zeros((59, 3)))
    with pytest.raises(ParameterError, match="odometry has 9 rows but observations has 10"):
        learner.partial_fit(X[:10], u[:10], odometry=np.zeros((9, 3)))
    # odometry that passes the checks does not change a map of a discrete walk
    plain = MapLearner(n_clusters=3, n_states=4, random_state=0).fit(X, u)
    np.testing.assert_array_equal(learner.labels_, plain.labels_)
    np.testing.assert_array_equal(learner.predict(X, u, odometry=np.zeros((60, 3))),
                                  plain.predict(X, u))
